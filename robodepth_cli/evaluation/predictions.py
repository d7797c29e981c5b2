"""A model's predictions of a built dataset, read one map at a time.

Predictions (``PRED``) come in either of two forms, per variant:

1. one array per variant, N x h x w in split order: ``PRED/clean.npy``,
   ``PRED/<corruption>/<level>.npy``, KITTI-S ``PRED/<style>.npy``; a ``.npz`` holding one
   array is accepted too.
   A ``.npy`` is read one map at a time.
2. one file per image, mirroring the dataset tree with the image's name:
   ``PRED/<variant dir>/<image path>`` with the extension ``.npy`` (a 2-D float map) or
   ``.png`` (16-bit, depth = value / ``png_scale``).
"""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path, PurePosixPath

import numpy as np

from ..api import Variant
from ..errors import os_reason
from ..groundtruth.depthmaps import read_npy_header
from ..groundtruth.read import read_png16
from .protocols import EvaluationError

class Predictions:
    """The predictions of one variant: ``len(keys)`` 2-D maps, read one at a time."""

    variant: Variant
    source: Path
    is_png: bool = False  # 16-bit PNGs: depths, whatever --kind the arrays have

    def read(self, i: int) -> tuple[np.ndarray, str, bool]:
        """(map ``i``, where it came from for messages, whether it is a PNG depth)."""
        raise NotImplementedError

    def close(self) -> None:
        pass


class ArrayPredictions(Predictions):
    """Form 1: one N x h x w array per variant. A ``.npy`` (C order) is read one map at a
    time from the file; a ``.npz`` (compressed, no random access) is loaded once for its
    variant."""

    def __init__(self, variant: Variant, source: Path):
        self.variant = variant
        self.source = source
        shape, fortran, dtype, self._offset = _array_header(source)
        n = len(variant)
        if len(shape) != 3:
            hint = (" (one axis too many: squeeze it)" if len(shape) == 4 and 1 in shape[1:2]
                    else "")
            raise EvaluationError(f"{source}: shape {shape}; expected N x h x w, one 2-D map per "
                                  f"image{hint}")
        if shape[0] != n:
            raise EvaluationError(f"{source}: {shape[0]} predictions for the {n} images of "
                                  f"{variant.label} (one per image, in split order)")
        if dtype.kind not in "fiu":
            raise EvaluationError(f"{source}: dtype {dtype}; expected numbers")
        self._shape, self._dtype = shape, dtype
        self._direct = source.suffix == ".npy" and not fortran
        self._array = None
        self._fh = None

    def read(self, i):
        where = f"{self.source}: prediction {i}"
        if self._direct:
            if self._fh is None:
                self._fh = open(self.source, "rb")
            count = self._shape[1] * self._shape[2]
            self._fh.seek(self._offset + i * count * self._dtype.itemsize)
            m = np.fromfile(self._fh, dtype=self._dtype, count=count)
            if m.size != count:
                raise EvaluationError(f"{where}: the file ends early (truncated?)")
            return m.reshape(self._shape[1:]), where, False
        if self._array is None:
            try:
                if self.source.suffix == ".npz":
                    with np.load(self.source, allow_pickle=False) as z:
                        self._array = z[z.files[0]]
                else:
                    self._array = np.load(self.source, mmap_mode="r", allow_pickle=False)
            except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
                reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
                raise EvaluationError(f"{self.source}: cannot read its array, damaged? "
                                      f"({reason})") from None
        return np.array(self._array[i]), where, False

    def close(self):
        self._array = None
        if self._fh is not None:
            self._fh.close()
            self._fh = None


def _array_header(path: Path) -> tuple[tuple[int, ...], bool, np.dtype, int]:
    """Shape, Fortran order, dtype and data offset of a ``.npy`` file or of the one array of
    a ``.npz``, without reading the data."""
    try:
        if path.suffix == ".npz":
            with zipfile.ZipFile(path) as zf:
                names = [n for n in zf.namelist() if n.endswith(".npy")]
                if len(names) != 1 or len(zf.namelist()) != 1:
                    raise EvaluationError(f"{path}: holds {len(zf.namelist())} arrays; expected "
                                          "exactly one (N x h x w)")
                with zf.open(names[0]) as fh:
                    return (*read_npy_header(fh), fh.tell())
        with open(path, "rb") as fh:
            return (*read_npy_header(fh), fh.tell())
    except EvaluationError:
        raise  # already names the file
    except (ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise EvaluationError(f"{path}: not a numpy {path.suffix} file ({exc})") from None
    except OSError as exc:
        raise EvaluationError(f"{path}: cannot read ({os_reason(exc)})") from None


class FilePredictions(Predictions):
    """Form 2: one ``.npy`` or 16-bit ``.png`` per image under ``PRED/<variant dir>/``."""

    def __init__(self, variant: Variant, source: Path, png_scale: float):
        self.variant = variant
        self.source = source
        self.png_scale = png_scale
        self.files: list[Path] = []
        for i, key in enumerate(variant.keys):
            stem = source / str(PurePosixPath(key).with_suffix(""))
            npy, png = stem.with_name(stem.name + ".npy"), stem.with_name(stem.name + ".png")
            has_npy, has_png = npy.is_file(), png.is_file()
            if has_npy and has_png:
                raise EvaluationError(f"{npy}: and {png.name} beside it; keep one prediction per "
                                      f"image (image {i})")
            if not (has_npy or has_png):
                raise EvaluationError(f"{stem}.npy: no such file, nor .png (prediction of image {i} "
                                      f"of {variant.label})")
            self.files.append(npy if has_npy else png)
        pngs = [f for f in self.files if f.suffix == ".png"]
        if pngs and len(pngs) != len(self.files):
            npy = next(f for f in self.files if f.suffix == ".npy")
            png = pngs[0]
            raise EvaluationError(f"{png}: a PNG prediction (a depth) among .npy predictions (read "
                                  f"as --kind) in {source}, e.g. {npy.name}; give every image of "
                                  "a variant in one form")
        self.is_png = bool(pngs)

    def read(self, i):
        file = self.files[i]
        where = f"{file} (image {i})"
        if file.suffix == ".png":
            raw = read_png16(file, f"prediction of image {i}")
            return raw.astype(np.float32) / np.float32(self.png_scale), where, True
        try:
            m = np.load(file, allow_pickle=False)
        except (OSError, ValueError, EOFError) as exc:
            reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
            raise EvaluationError(f"{file}: not a readable .npy file ({reason}) (image {i})") from None
        if m.ndim != 2:
            raise EvaluationError(f"{file}: shape {m.shape}; expected one 2-D map (h x w) "
                                  f"(image {i})")
        if m.dtype.kind not in "fiu":
            raise EvaluationError(f"{file}: dtype {m.dtype}; expected numbers (image {i})")
        return m, where, False


def find_predictions(pred: Path, variant: Variant, png_scale: float) -> Predictions | None:
    """The predictions of ``variant`` under ``pred`` in either form, checked for count and
    shape (not yet for values); None when there are none."""
    base = pred / variant.relpath
    arrays = [p for p in (base.with_name(base.name + ".npy"), base.with_name(base.name + ".npz"))
              if p.is_file()]
    if len(arrays) == 2:
        raise EvaluationError(f"{arrays[0]}: and {arrays[1].name} beside it; keep one")
    if arrays:
        return ArrayPredictions(variant, arrays[0])
    if base.is_dir():
        return FilePredictions(variant, base, png_scale)
    return None


def check_values(m: np.ndarray, where: str, kind: str = "depth",
                 allow_negative: bool = False) -> None:
    """Refuse a map that cannot give finite metrics (the rule is :data:`ZERO_AND_INF`):
    NaN, inf, negative values (unless ``allow_negative``: a prediction aligned by a scale
    and a shift may have them), a sigmoid output outside [0, 1], or (disp, depth) no
    positive value at all, a dead map."""
    low = np.min(m)
    if np.isnan(low):
        raise EvaluationError(f"{where} contains NaN")
    if low < 0 and not allow_negative:
        raise EvaluationError(f"{where} has negative values (min {float(low):g})")
    high = np.max(m)
    if np.isinf(high):
        raise EvaluationError(f"{where} contains inf ({int(np.isinf(m).sum())} pixels); give "
                              "finite values (a far pixel as a large depth or a 0 disparity)")
    if kind == "sigmoid":
        if high > 1:
            raise EvaluationError(f"{where}: values up to {float(high):g}; --kind sigmoid is a "
                                  "network's sigmoid output, in [0, 1] (a disparity or a depth? "
                                  "give --kind disp or --kind depth)")
    elif high == 0:
        raise EvaluationError(f"{where}: no positive finite value (all 0); a dead map cannot be "
                              "evaluated")


ZERO_AND_INF = ("0 and inf: a disparity (--kind disp) of 0 is infinitely far, a depth of 0 is "
                "distance 0; either is clamped to the protocol's depth range (1e-3 to 80 m kitti, "
                "10 m nyu) as the reference evaluators clamp. inf and NaN are refused, as are "
                "negative values, sigmoid outputs outside [0, 1], a map with no positive value "
                "and (median scaling) a map that is 0 at half of the valid pixels or more.")
