"""Reading a challenge submission safely: a stranger's upload, so every size is bounded,
nothing is unpickled and nothing is extracted. The forms accepted and the refusals are
those of docs/challenge.md (:func:`open_submission`). A map is read from its stream one at
a time; nothing holds more than one map plus the archive's index."""

from __future__ import annotations

import os
import stat
import zipfile
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from ..errors import RobodepthError

MAX_SIDE = 8192  # a map's height or width; the largest ground truth is 1242 wide
MAX_MEMBERS = 100_000  # zip entries looked at; a keyed npz has one per image
_ARCHIVES = (".zip", ".npz", ".tar", ".tgz", ".gz", ".bz2", ".xz", ".7z", ".rar", ".zst")
_CHUNK = 1 << 20


def _ignored(name: str) -> bool:
    parts = name.replace("\\", "/").split("/")
    return parts[0] == "__MACOSX" or parts[-1] in (".DS_Store", "") or parts[-1].startswith("._")


def check_member(where: str, info: zipfile.ZipInfo) -> None:
    """Refuse a zip entry that could escape a folder or is not a plain file."""
    name = info.filename
    parts = name.replace("\\", "/").split("/")
    if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":"):
        raise RobodepthError(f"{where}: member {name!r} has an absolute path; refused")
    if ".." in parts:
        raise RobodepthError(f"{where}: member {name!r} has '..' in its path; refused")
    if stat.S_ISLNK(info.external_attr >> 16):
        raise RobodepthError(f"{where}: member {name!r} is a symlink; refused")
    if info.flag_bits & 0x1:
        raise RobodepthError(f"{where}: member {name!r} is encrypted; refused")


def zip_files(where: str, zf: zipfile.ZipFile, max_bytes: int) -> list[zipfile.ZipInfo]:
    """The file entries of an opened zip that count (not folders, not macOS's extras), each
    checked by :func:`check_member`; their declared sizes together within ``max_bytes``."""
    infos = zf.infolist()
    if len(infos) > MAX_MEMBERS:
        raise RobodepthError(f"{where}: {len(infos)} entries; at most {MAX_MEMBERS}")
    files = []
    for info in infos:
        check_member(where, info)
        if info.is_dir() or _ignored(info.filename):
            continue
        files.append(info)
    declared = sum(i.file_size for i in files)
    if declared > max_bytes:
        raise RobodepthError(f"{where}: its contents would be {_mb(declared)} uncompressed, over "
                             f"the limit of {_mb(max_bytes)} (--max-size)")
    return files


def _mb(n: int) -> str:
    return f"{n / 1e6:,.0f} MB" if n >= 1e6 else f"{n:,} bytes"


@dataclass
class ArrayHeader:
    """What an ``.npy`` stream's header claims, checked against what is allowed."""

    shape: tuple
    dtype: np.dtype
    offset: int  # bytes of the header

    @property
    def data_bytes(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) * self.dtype.itemsize


def read_header(fh, where: str) -> ArrayHeader:
    """The checked header of the ``.npy`` stream ``fh``, left at the first data byte: float
    (16, 32 or 64 bits), C order, no object fields. numpy's own reader refuses headers over
    10,000 bytes."""
    fmt = np.lib.format
    try:
        version = fmt.read_magic(fh)
        start = 8
        if version == (1, 0):
            shape, fortran, dtype = fmt.read_array_header_1_0(fh)
        elif version in ((2, 0), (3, 0)):
            shape, fortran, dtype = fmt.read_array_header_2_0(fh) if version == (2, 0) \
                else fmt._read_array_header(fh, version)
        else:
            raise ValueError(f"version {version}")
        offset = fh.tell() if hasattr(fh, "tell") else start
    except (ValueError, OSError, EOFError, SyntaxError, TypeError) as exc:
        raise RobodepthError(f"{where}: not a readable .npy array ({_first_line(exc)})") from None
    if dtype.hasobject:
        raise RobodepthError(f"{where}: an object array (Python objects, e.g. a list of per-batch "
                             "arrays, saved with pickle), never loaded; stack the maps into one "
                             "float array (np.stack) and save that")
    if dtype.kind != "f" or dtype.itemsize not in (2, 4, 8) or dtype.names or dtype.subdtype:
        raise RobodepthError(f"{where}: dtype {dtype}; expected float16, float32 or float64")
    if fortran:
        raise RobodepthError(f"{where}: saved in Fortran order; save np.ascontiguousarray(maps)")
    if any((not isinstance(s, int)) or s < 0 for s in shape):
        raise RobodepthError(f"{where}: shape {shape} is not a shape")
    return ArrayHeader(tuple(shape), dtype, offset)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0][:200] if text else type(exc).__name__


def _read_exact(fh, n: int, where: str) -> bytes:
    """``n`` bytes of ``fh``; :class:`RobodepthError` if it ends sooner."""
    parts, left = [], n
    while left:
        try:
            b = fh.read(min(left, _CHUNK))
        except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:
            raise RobodepthError(f"{where}: damaged ({_first_line(exc)})") from None
        if not b:
            raise RobodepthError(f"{where}: ends after {n - left:,} of the {n:,} bytes its "
                                 "header announces (truncated?)")
        parts.append(b)
        left -= len(b)
    return b"".join(parts)


def check_map(m: np.ndarray, where: str) -> None:
    """Refuse a map with a value no depth or disparity can have: NaN, infinity, zero or
    below (a disparity of 0 is a point infinitely far, which no evaluator can scale)."""
    if not np.isfinite(m).all():
        bad = "NaN" if np.isnan(m).any() else "infinity"
        raise RobodepthError(f"{where}: holds {bad}; every value must be finite")
    if not (m > 0).all():
        raise RobodepthError(f"{where}: holds values <= 0 (min {float(m.min()):g}); every value must "
                             "be above zero")


class Submission:
    """An opened submission: :meth:`maps` gives each image's map in list order."""

    def __init__(self, where: str, ids: Sequence[str]):
        self.where = where
        self.ids = list(ids)
        self._closers: list = []
        self.form = ""

    def close(self) -> None:
        for c in reversed(self._closers):
            c()
        self._closers.clear()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def maps(self) -> Iterator[tuple[str, np.ndarray]]:
        raise NotImplementedError


class _Dense(Submission):
    """One (N, H, W) array in a stream, read map by map."""

    def __init__(self, where, ids, opener, size: int | None):
        super().__init__(where, ids)
        self._open = opener
        with opener() as fh:
            self.header = read_header(fh, where)
        h = self.header
        if len(h.shape) != 3:
            raise RobodepthError(f"{where}: shape {h.shape}; expected 3 dimensions (N, H, W), "
                                 f"one H x W map per image{_squeeze_hint(h.shape)}")
        n, hh, ww = h.shape
        if n != len(ids):
            raise RobodepthError(f"{where}: {n} maps; the challenge has {len(ids)} images")
        _check_side(hh, ww, where)
        if size is not None and size != h.offset + h.data_bytes:
            raise RobodepthError(f"{where}: {size:,} bytes, but its header announces "
                                 f"{h.offset + h.data_bytes:,} (shape {h.shape}, {h.dtype})")
        self.form = "array"

    def maps(self):
        h = self.header
        _, hh, ww = h.shape
        per = hh * ww * h.dtype.itemsize
        with self._open() as fh:
            _read_exact(fh, h.offset, self.where)
            for i, image_id in enumerate(self.ids):
                m = np.frombuffer(_read_exact(fh, per, self.where), h.dtype).reshape(hh, ww)
                m = _native(m)
                check_map(m, f"{self.where}: map {i} (image {image_id})")
                yield image_id, m


def _native(m: np.ndarray) -> np.ndarray:
    """A map as a native-endian float32 (float64 kept: the evaluator would keep it too)."""
    return m.astype(np.float64 if m.dtype.itemsize == 8 else np.float32)


def _squeeze_hint(shape) -> str:
    if len(shape) == 4 and 1 in shape[1:2]:
        return " (drop the channel axis: maps[:, 0])"
    return ""


def _check_side(h: int, w: int, where: str) -> None:
    if not (1 <= h <= MAX_SIDE and 1 <= w <= MAX_SIDE):
        raise RobodepthError(f"{where}: maps of {h} x {w}; each side must be 1..{MAX_SIDE}")


class _Keyed(Submission):
    """An npz with one (H, W) member per image id."""

    def __init__(self, where, ids, zf: zipfile.ZipFile, members: dict):
        super().__init__(where, ids)
        self._zf, self._members = zf, members
        missing = [i for i in ids if i not in members]
        extra = sorted(set(members) - set(ids))
        if missing or extra:
            parts = []
            if missing:
                parts.append(f"no map for {len(missing)} image(s) ({', '.join(missing[:3])}"
                             f"{', ...' if len(missing) > 3 else ''})")
            if extra:
                parts.append(f"{len(extra)} member(s) that are no image id ({', '.join(extra[:3])}"
                             f"{', ...' if len(extra) > 3 else ''})")
            raise RobodepthError(f"{where}: " + "; ".join(parts))
        self.form = "keyed"

    def maps(self):
        for image_id in self.ids:
            info = self._members[image_id]
            what = f"{self.where}: {info.filename}"
            with _open_member(self._zf, info, what) as fh:
                h = read_header(fh, what)
                if len(h.shape) != 2:
                    raise RobodepthError(f"{what}: shape {h.shape}; expected one H x W map")
                _check_side(*h.shape, what)
                if info.file_size != h.offset + h.data_bytes:
                    raise RobodepthError(f"{what}: {info.file_size:,} bytes, but its header "
                                         f"announces {h.offset + h.data_bytes:,}")
                m = np.frombuffer(_read_exact(fh, h.data_bytes, what), h.dtype).reshape(h.shape)
            m = _native(m)
            check_map(m, f"{what} (image {image_id})")
            yield image_id, m


def _open_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, where: str):
    try:
        return zf.open(info)
    except (zipfile.BadZipFile, NotImplementedError, RuntimeError, OSError, ValueError) as exc:
        raise RobodepthError(f"{where}: cannot be read ({_first_line(exc)})") from None


def _open_zip(source, where: str) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(source)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise RobodepthError(f"{where}: not a readable zip ({_first_line(exc)})") from None


def _npz(where: str, ids, zf: zipfile.ZipFile, max_bytes: int, closers: list) -> Submission:
    """An npz (already open): the (N, H, W) form in one member, or the keyed form."""
    files = zip_files(where, zf, max_bytes)
    bad = [i.filename for i in files if not i.filename.endswith(".npy")]
    if bad:
        raise RobodepthError(f"{where}: member {bad[0]!r} is not a .npy array; an npz holds arrays only")
    if not files:
        raise RobodepthError(f"{where}: holds no array")
    members = {i.filename[:-len(".npy")]: i for i in files}
    if len(files) == 1 and next(iter(members)) not in set(ids):
        info = files[0]
        sub = _Dense(f"{where}: {info.filename}", ids,
                     lambda: _open_member(zf, info, f"{where}: {info.filename}"), info.file_size)
    else:
        sub = _Keyed(where, ids, zf, members)
    sub._closers = closers + [zf.close]
    return sub


def open_submission(path: str, ids: Sequence[str], max_bytes: int, scratch: str | None = None) -> Submission:
    """Open the submission at ``path`` (a file or a folder; see the module docstring) for
    the images ``ids`` in list order. ``max_bytes`` bounds the upload and everything it
    declares; ``scratch``: a folder for the one temporary file an npz inside a deflated zip
    needs (default: the system's), removed on :meth:`Submission.close`.
    Raises :class:`RobodepthError`."""
    where = str(path)
    if os.path.islink(path):
        raise RobodepthError(f"{where}: a symlink; refused")
    if os.path.isdir(path):
        return _from_folder(path, ids, max_bytes, scratch)
    try:
        size = os.path.getsize(path)
    except OSError as exc:
        raise RobodepthError(f"{where}: {exc.strerror or exc}") from None
    if size > max_bytes:
        raise RobodepthError(f"{where}: {_mb(size)}, over the limit of {_mb(max_bytes)} (--max-size)")
    with open(path, "rb") as fh:
        magic = fh.read(6)
    if magic == b"\x93NUMPY":
        return _Dense(where, ids, lambda: open(path, "rb"), size)
    if magic[:2] != b"PK":
        raise RobodepthError(f"{where}: neither a zip, an npz nor a .npy file")
    zf = _open_zip(path, where)
    try:
        files = zip_files(where, zf, max_bytes)
        if path.lower().endswith(".npz") or \
                (len(files) > 1 and all(i.filename.endswith(".npy") for i in files)):
            return _npz(where, ids, zf, max_bytes, [])  # an npz, whatever its name
        return _from_zip(where, ids, zf, files, max_bytes, scratch)
    except BaseException:
        zf.close()
        raise


def _one_array(where: str, names: list[str]) -> str:
    """The one array file among ``names``, else the refusal naming what is wrong."""
    nested = [n for n in names if n.lower().endswith(_ARCHIVES) and not n.lower().endswith(".npz")]
    if nested:
        raise RobodepthError(f"{where}: holds an archive inside it ({nested[0]}); put the .npy "
                             "(or .npz) itself at the top of the zip")
    arrays = [n for n in names if n.lower().endswith((".npy", ".npz"))]
    if not arrays:
        shown = ", ".join(names[:3]) or "nothing"
        raise RobodepthError(f"{where}: no .npy or .npz array in it (it holds {shown})")
    if len(arrays) > 1:
        raise RobodepthError(f"{where}: {len(arrays)} arrays ({', '.join(arrays[:3])}); submit "
                             "exactly one")
    others = [n for n in names if n not in arrays]
    if others:
        raise RobodepthError(f"{where}: {others[0]!r} besides the array; submit the array alone")
    return arrays[0]


def _from_zip(where, ids, zf, files, max_bytes, scratch) -> Submission:
    name = _one_array(where, [i.filename for i in files])
    info = next(i for i in files if i.filename == name)
    inner = f"{where}: {name}"
    if name.lower().endswith(".npy"):
        sub = _Dense(inner, ids, lambda: _open_member(zf, info, inner), info.file_size)
        sub._closers = [zf.close]
        return sub
    # An npz inside the zip: a zip needs random access, so a deflated member is copied out
    # (at most its declared size, which is within the limit) into a temporary file.
    if info.compress_type == zipfile.ZIP_STORED:
        member = _open_member(zf, info, inner)
        return _npz(inner, ids, _open_zip(member, inner), max_bytes, [member.close, zf.close])
    import tempfile

    fd, tmp = tempfile.mkstemp(prefix=".robodepth-submission.", suffix=".npz", dir=scratch)
    try:
        with os.fdopen(fd, "wb") as out, _open_member(zf, info, inner) as src:
            left = info.file_size
            while left:
                b = _read_exact(src, min(left, _CHUNK), inner)
                out.write(b)
                left -= len(b)
        zf.close()
        return _npz(inner, ids, _open_zip(tmp, inner), max_bytes, [lambda: os.unlink(tmp)])
    except BaseException:
        os.unlink(tmp)
        raise


def _from_folder(path: str, ids, max_bytes: int, scratch) -> Submission:
    """A folder (Codabench's ``input/res``): the one array file in it, at any depth."""
    names, total = [], 0
    for dirpath, dirnames, filenames in os.walk(path):
        for d in list(dirnames):
            full = os.path.join(dirpath, d)
            if os.path.islink(full):
                raise RobodepthError(f"{full}: a symlink; refused")
            if d == "__MACOSX":
                dirnames.remove(d)
        for f in filenames:
            full = os.path.join(dirpath, f)
            if os.path.islink(full):
                raise RobodepthError(f"{full}: a symlink; refused")
            rel = os.path.relpath(full, path)
            if _ignored(rel) or rel == "metadata":  # Codabench may add a metadata file
                continue
            names.append(rel)
            total += os.path.getsize(full)
            if total > max_bytes:
                raise RobodepthError(f"{path}: over the limit of {_mb(max_bytes)} (--max-size)")
        if len(names) > MAX_MEMBERS:
            raise RobodepthError(f"{path}: more than {MAX_MEMBERS} files")
    name = _one_array(path, sorted(names))
    return open_submission(os.path.join(path, name), ids, max_bytes, scratch)
