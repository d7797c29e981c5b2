"""The predictions folder (``PRED``), one owner for its format: what ``robodepth predict``,
``robodepth run --keep-predictions`` and :meth:`robodepth_cli.api.Variant.save_predictions`
write, and what ``robodepth evaluate``, ``robodepth report`` and ``build --scene-depth`` read.

Per variant either one N x h x w array in split order (``PRED/clean.npy``,
``PRED/<corruption>/<level>.npy``, KITTI-S ``PRED/<style>.npy``; or a one-array ``.npz``),
memory-mapped and read a block of maps at a time, or one file per image mirroring the dataset
tree (``.npy``, or a 16-bit ``.png`` holding depth x ``png_scale``). ``PRED/predictions.json``
(:data:`RECORD`) says which model made the maps, what they hold and of which build's split
(:func:`split_digest`). Every refusal here is a :class:`PredictionsError` naming the file."""

from __future__ import annotations

import hashlib
import json
import mmap
import os
import zipfile
import zlib
from pathlib import Path, PurePosixPath
from typing import Sequence

import numpy as np

from .errors import RobodepthError, cannot_write, os_reason
from .formats import FormatError, check, stamp
from .files import read_npy_header
from .imageio import read_depth_png

RECORD = "predictions.json"
SCHEMA = "robodepth-predictions"


class PredictionsError(RobodepthError):
    """A predictions folder, record or file that cannot be written or used."""


def split_digest(keys: Sequence[str]) -> str:
    """The sha256 of a build's split (its keys, one a line): which images the maps are of."""
    return hashlib.sha256("\n".join(keys).encode("utf-8")).hexdigest()


def model_identity(record: dict) -> str:
    """What tells a model's maps apart, short enough for a manifest cell: the adapter and 16
    hex digits of the sha256 of its weights' identity and options. ``robodepth evaluate``
    writes the same for the predictions it reads."""
    text = json.dumps({k: record.get(k) for k in ("adapter", "identity", "options")},
                      sort_keys=True, default=str)
    return f"{record.get('adapter')}:{hashlib.sha256(text.encode('utf-8')).hexdigest()[:16]}"


def read_record(pred: Path) -> dict | None:
    """``PRED/predictions.json``, or None when there is none; :class:`PredictionsError`
    naming the file when it is unreadable or not a robodepth predictions record."""
    path = Path(pred) / RECORD
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        reason = os_reason(exc) if isinstance(exc, OSError) else "not UTF-8 text"
        raise PredictionsError(f"{path}: cannot read ({reason})") from None
    try:
        record = json.loads(text)
    except ValueError as exc:
        raise PredictionsError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(record, dict) or not isinstance(record.get("evaluate"), dict):
        raise PredictionsError(f"{path}: not a robodepth predictions record (no 'evaluate' entry)")
    try:
        check(record, SCHEMA, str(path), "run robodepth predict again")
    except FormatError as exc:
        raise PredictionsError(str(exc)) from None
    return record


def write_record(pred: Path, record: dict) -> None:
    """Write ``PRED/predictions.json`` atomically, its format version first."""
    from .files import write_atomic

    try:
        write_atomic(Path(pred) / RECORD, (json.dumps({**stamp(SCHEMA), **record}, indent=2) + "\n").encode())
    except OSError as exc:
        raise PredictionsError(cannot_write(Path(pred) / RECORD, exc)) from None


def prediction_file(pred, relpath: str) -> Path:
    """Form 1's file of the variant at ``relpath``: ``PRED/<relpath>.npy``."""
    return Path(pred) / f"{relpath}.npy"


def image_files(folder: Path, keys: Sequence[str]) -> list[Path]:
    """Form 2's files in ``folder``: each image's ``<image path>.npy``."""
    return [folder / str(PurePosixPath(k).with_suffix(".npy")) for k in keys]


def clean_source(pred: Path) -> Path | None:
    """The clean images' predictions in ``pred``: ``clean.npy``, ``clean.npz`` or the folder
    ``clean/``; None when there are none."""
    for p in (pred / "clean.npy", pred / "clean.npz", pred / "clean"):
        if p.exists():
            return p
    return None


class Predictions:
    """The predictions of one variant: ``len(keys)`` 2-D maps, read one at a time."""

    variant: object  # a robodepth_cli.api.Variant
    source: Path
    is_png: bool = False  # 16-bit PNGs: depths, whatever --kind the arrays have

    def read(self, i: int) -> tuple[np.ndarray, str, bool]:
        """(map ``i``, where it came from for messages, whether it is a PNG depth)."""
        raise NotImplementedError

    def close(self) -> None:
        pass


class ArrayPredictions(Predictions):
    """Form 1: one N x h x w array per variant. A ``.npy`` is memory-mapped (read-only) and
    each map handed out as a view of it, with no copy: the page cache holds the file once;
    a ``.npz`` (compressed, no random access) is loaded once for its variant."""

    def __init__(self, variant, source: Path):
        self.variant = variant
        self.source = source
        shape, fortran, dtype, offset = _array_header(source)
        n = len(variant)
        if len(shape) != 3:
            hint = (" (one axis too many: squeeze it)" if len(shape) == 4 and 1 in shape[1:2]
                    else "")
            raise PredictionsError(f"{source}: shape {shape}; expected N x h x w, one 2-D map per "
                                  f"image{hint}")
        if shape[0] != n:
            raise PredictionsError(f"{source}: {shape[0]} predictions for the {n} images of "
                                  f"{variant.label} (one per image, in split order)")
        if dtype.kind not in "fiu":
            raise PredictionsError(f"{source}: dtype {dtype}; expected numbers")
        if source.suffix == ".npy":
            have, need = source.stat().st_size, offset + int(np.prod(shape)) * dtype.itemsize
            if have < need:
                raise PredictionsError(f"{source}: the file ends early (truncated?): {have:,} "
                                      f"bytes, its header says {need:,}")
        self._array = None
        self._previous = None  # the maps read last (first, last), whose pages the next read releases
        # (shape, dtype) of the maps judged a block at a time (evaluation/batch.py); None
        # for Fortran order, which the block calls are not compiled for
        self.header = None if fortran else (tuple(shape), dtype)

    def read(self, i):
        return self.block(i, i + 1)[i], f"{self.source}: prediction {i}", False

    def block(self, first: int, last: int) -> np.ndarray:
        """The N x h x w array, of which maps ``first..last-1`` are read now (a mapped
        ``.npy``: the pages of the maps read before are released)."""
        if self._array is None:
            try:
                if self.source.suffix == ".npz":
                    with np.load(self.source, allow_pickle=False) as z:
                        self._array = z[z.files[0]]
                else:
                    self._array = np.load(self.source, mmap_mode="r", allow_pickle=False)
            except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
                reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
                raise PredictionsError(f"{self.source}: cannot read its array, damaged? "
                                      f"({reason})") from None
        if self._previous is not None:
            self._release(*self._previous)
        self._previous = (first, last)
        return self._array

    def _release(self, first: int, last: int) -> None:
        """Drop the pages of maps ``first..last-1`` from this process's mapping (not from
        the page cache): a variant's maps are read once each, and the pages would otherwise
        count in its RSS to the end of the variant. A later read of a map maps them again."""
        mm = getattr(self._array, "_mmap", None)
        if mm is None or not hasattr(mm, "madvise") or not hasattr(mmap, "MADV_DONTNEED"):
            return
        size = self._array[0].nbytes
        start = self._array.offset % mmap.ALLOCATIONGRANULARITY + first * size  # in the mapping
        end = start + (last - first) * size
        lo, hi = -(-start // mmap.PAGESIZE) * mmap.PAGESIZE, end // mmap.PAGESIZE * mmap.PAGESIZE
        if hi > lo:
            mm.madvise(mmap.MADV_DONTNEED, lo, hi - lo)

    def close(self):
        self._array = None
        self._previous = None


def _array_header(path: Path) -> tuple[tuple[int, ...], bool, np.dtype, int]:
    """Shape, Fortran order, dtype and data offset of a ``.npy`` file or of the one array of
    a ``.npz``, without reading the data."""
    try:
        if path.suffix == ".npz":
            with zipfile.ZipFile(path) as zf:
                names = [n for n in zf.namelist() if n.endswith(".npy")]
                if len(names) != 1 or len(zf.namelist()) != 1:
                    raise PredictionsError(f"{path}: holds {len(zf.namelist())} arrays; expected "
                                          "exactly one (N x h x w)")
                with zf.open(names[0]) as fh:
                    return (*read_npy_header(fh), fh.tell())
        with open(path, "rb") as fh:
            return (*read_npy_header(fh), fh.tell())
    except PredictionsError:
        raise  # already names the file
    except (ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise PredictionsError(f"{path}: not a numpy {path.suffix} file ({exc})") from None
    except OSError as exc:
        raise PredictionsError(f"{path}: cannot read ({os_reason(exc)})") from None


class FilePredictions(Predictions):
    """Form 2: one ``.npy`` or 16-bit ``.png`` per image under ``PRED/<variant dir>/``."""

    def __init__(self, variant, source: Path, png_scale: float):
        self.variant = variant
        self.source = source
        self.png_scale = png_scale
        self.files: list[Path] = []
        for i, key in enumerate(variant.keys):
            stem = source / str(PurePosixPath(key).with_suffix(""))
            npy, png = stem.with_name(stem.name + ".npy"), stem.with_name(stem.name + ".png")
            has_npy, has_png = npy.is_file(), png.is_file()
            if has_npy and has_png:
                raise PredictionsError(f"{npy}: and {png.name} beside it; keep one prediction per "
                                      f"image (image {i})")
            if not (has_npy or has_png):
                raise PredictionsError(f"{stem}.npy: no such file, nor .png (prediction of image {i} "
                                      f"of {variant.label})")
            self.files.append(npy if has_npy else png)
        pngs = [f for f in self.files if f.suffix == ".png"]
        if pngs and len(pngs) != len(self.files):
            npy = next(f for f in self.files if f.suffix == ".npy")
            png = pngs[0]
            raise PredictionsError(f"{png}: a PNG prediction (a depth) among .npy predictions (read "
                                  f"as --kind) in {source}, e.g. {npy.name}; give every image of "
                                  "a variant in one form")
        self.is_png = bool(pngs)

    def read(self, i):
        file = self.files[i]
        where = f"{file} (image {i})"
        if file.suffix == ".png":
            raw = read_depth_png(file, f"prediction of image {i}", PredictionsError)
            return raw.astype(np.float32) / np.float32(self.png_scale), where, True
        try:
            m = np.load(file, allow_pickle=False)
        except (OSError, ValueError, EOFError) as exc:
            reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
            raise PredictionsError(f"{file}: not a readable .npy file ({reason}) (image {i})") from None
        if m.ndim != 2:
            raise PredictionsError(f"{file}: shape {m.shape}; expected one 2-D map (h x w) "
                                  f"(image {i})")
        if m.dtype.kind not in "fiu":
            raise PredictionsError(f"{file}: dtype {m.dtype}; expected numbers (image {i})")
        return m, where, False


def find_predictions(pred: Path, variant, png_scale: float) -> Predictions | None:
    """The predictions of ``variant`` under ``pred`` in either form, checked for count and
    shape (not yet for values); None when there are none."""
    base = pred / variant.relpath
    arrays = [p for p in (base.with_name(base.name + ".npy"), base.with_name(base.name + ".npz"))
              if p.is_file()]
    if len(arrays) == 2:
        raise PredictionsError(f"{arrays[0]}: and {arrays[1].name} beside it; keep one")
    if arrays:
        return ArrayPredictions(variant, arrays[0])
    if base.is_dir():
        return FilePredictions(variant, base, png_scale)
    return None


_WRITE_BUFFER = 16 << 20


class PredictionWriter:
    """Streams ``n`` maps into one ``N x h x w`` ``.npy`` file (form 1 of ``robodepth
    evaluate``) through a temporary file and a rename: a reader sees the whole file or
    none, and a failure (or fewer than ``n`` maps) leaves nothing behind.

    The first map fixes the size and the dtype (a floating dtype is kept, others become
    float32); each later map must have that size and is converted to that dtype.

    >>> with PredictionWriter(Path("PRED/clean.npy"), 2) as out:    # doctest: +SKIP
    ...     out.write(map0); out.write(map1)
    """

    def __init__(self, target: Path, n: int):
        self.target = Path(target)
        self.n = n
        self.count = 0
        self._shape = None
        self._dtype = None
        self._cm = None
        self._fh = None

    def __enter__(self) -> "PredictionWriter":
        from .files import atomic_output

        # Written in 16 MiB pieces, not a map at a time: Linux's page cache then holds the
        # file in large folios, which evaluate's mapping takes some ten times faster than
        # the small ones that 480 KiB writes leave (4 against 37 us a 192 x 640 map).
        self._cm = atomic_output(self.target, buffering=_WRITE_BUFFER)
        try:
            self._fh = self._cm.__enter__()
        except OSError as exc:
            raise PredictionsError(cannot_write(self.target, exc)) from None
        if self.n == 0:
            self._header((0, 0), np.dtype(np.float32))
        return self

    def _header(self, shape, dtype) -> None:
        self._shape, self._dtype = shape, dtype
        np.lib.format.write_array_header_1_0(self._fh, {
            "descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False,
            "shape": (self.n, *shape)})

    def write(self, value) -> None:
        """Append the next map (anything :func:`numpy.asarray` takes, CPU tensors too; a
        leading axis of length 1 is dropped)."""
        i = self.count
        if i >= self.n:
            raise PredictionsError(f"{self.target}: more than the {self.n} predictions expected")
        m = _as_map(value, self.target, i)
        if self._shape is None:
            self._header(m.shape, m.dtype if m.dtype.kind == "f" else np.dtype(np.float32))
        elif m.shape != self._shape:
            raise PredictionsError(f"{self.target}: prediction {i} is {m.shape[0]} x {m.shape[1]}, "
                               f"prediction 0 is {self._shape[0]} x {self._shape[1]}; all must "
                               "have one size")
        try:
            self._fh.write(np.ascontiguousarray(m, dtype=self._dtype).data)
        except OSError as exc:
            raise PredictionsError(cannot_write(self.target, exc)) from None
        self.count += 1

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None and self.count != self.n:
            exc = PredictionsError(f"{self.target}: {self.count} predictions written of the "
                               f"{self.n} expected")
            self._cm.__exit__(type(exc), exc, None)
            raise exc
        try:
            return self._cm.__exit__(exc_type, exc, tb)
        except OSError as err:
            raise PredictionsError(cannot_write(self.target, err)) from None


def _as_map(value, target: Path, i: int) -> np.ndarray:
    if hasattr(value, "detach"):  # a torch tensor, perhaps on a GPU or needing grad
        value = value.detach().cpu().numpy()
    m = np.asarray(value)
    if m.ndim == 3 and m.shape[0] == 1:
        m = m[0]
    if m.ndim != 2:
        raise PredictionsError(f"{target}: prediction {i} has shape {m.shape}; expected one 2-D "
                           "map (h x w) per image")
    if m.dtype.kind not in "fiu":
        raise PredictionsError(f"{target}: prediction {i} has dtype {m.dtype}; expected numbers")
    return m


def finished(pred: Path, variant) -> bool:
    """Whether ``variant``'s predictions are there whole: its ``.npy`` (one map per image),
    or its folder of one ``.npy`` per image."""
    path = prediction_file(pred, variant.relpath)
    folder = Path(pred) / variant.relpath
    if folder.is_dir() and not path.is_file():
        return all(p.is_file() for p in image_files(folder, variant.keys))
    if not path.is_file():
        return False
    try:
        shape = np.load(path, mmap_mode="r", allow_pickle=False).shape
    except (OSError, ValueError, EOFError):
        return False
    return len(shape) == 3 and shape[0] == len(variant)


def remove_leftovers(pred: Path, variants) -> None:
    """Delete the temporary files (and folders) a killed run left beside the variants'."""
    import shutil

    from .files import is_temporary

    for folder in {prediction_file(pred, v.relpath).parent for v in variants}:
        if folder.is_dir():
            for p in folder.iterdir():
                if not is_temporary(p.name):
                    continue
                if p.is_dir():
                    shutil.rmtree(p)
                else:
                    p.unlink()


class ImageFilesWriter:
    """The per-image form for one variant: each map as ``<image path>.npy`` in a temporary
    folder beside ``PRED/<variant>``, renamed to it when all are written (removed on
    failure), so the folder is whole or absent. Same ``write`` as
    :class:`PredictionWriter`."""

    def __init__(self, pred: Path, variant):
        self.target = Path(pred) / variant.relpath
        self.variant = variant
        self.count = 0
        self._tmp = None
        self._files: list[Path] = []

    def __enter__(self) -> "ImageFilesWriter":
        import secrets

        if self.target.exists():
            raise PredictionsError(f"{self.target}: exists but is not complete predictions of "
                             f"{self.variant.label}; delete it")
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
            # os.mkdir, not mkdtemp: the folder gets the usual 0777 & ~umask once renamed
            self._tmp = self.target.parent / f".{self.target.name}.{secrets.token_hex(6)}.part"
            self._tmp.mkdir()
        except OSError as exc:
            raise PredictionsError(cannot_write(self.target, exc)) from None
        self._files = image_files(self._tmp, self.variant.keys)
        return self

    def write(self, m: np.ndarray) -> None:
        path = self._files[self.count]
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            np.save(path, m if m.dtype.kind == "f" else m.astype(np.float32))
        except OSError as exc:
            raise PredictionsError(cannot_write(path, exc)) from None
        self.count += 1

    def __exit__(self, exc_type, exc, tb):
        import shutil

        try:
            if exc_type is None:
                if self.count != len(self._files):
                    raise PredictionsError(f"{self.target}: {self.count} predictions written of the "
                                     f"{len(self._files)} expected")
                try:
                    os.replace(self._tmp, self.target)
                except OSError as err:
                    raise PredictionsError(cannot_write(self.target, err)) from None
        finally:
            if self._tmp is not None and self._tmp.exists():
                shutil.rmtree(self._tmp)
        return False
