"""A model's depth predictions on a built dataset, scored under the protocols the published
RoboDepth numbers use, into the results CSV that ``robodepth score`` reads.

Two protocols, each computed the way its reference evaluator computes it:

kitti
    monodepth2's ``evaluate_depth.py`` (the benchmark's KITTI-C evaluation is a copy of it):
    a disparity is resized to the ground truth's size with ``cv2.resize`` (bilinear) and
    inverted; valid pixels are ``1e-3 < gt < 80`` inside the Garg crop; each image's
    prediction is scaled by ``median(gt) / median(pred)`` (mono) or by 5.4 (stereo), then
    clamped to [1e-3, 80]. See :func:`kitti_image`.
nyu
    BTS's ``eval_with_pngs.py`` and AdaBins's ``evaluate.py``: depth in metres, upsampled
    (bilinear, corner-aligned as AdaBins's ``interpolate(align_corners=True)``) to the ground
    truth's size if smaller, clamped to [1e-3, 10]; valid pixels ``1e-3 < gt < 10`` inside
    the Eigen crop (rows 45..470, columns 41..600); no scaling; two more metrics, log10 and
    silog. See :func:`nyu_image`.

Metrics are computed per image over its valid pixels and averaged over the images
(:func:`depth_errors`, :func:`nyu_errors`). Arithmetic follows the inputs' dtype, as the
reference code's does (float32 predictions and ground truth give float32 per-image
metrics); the average over images is float64.

Predictions (``PRED``) come in either of two forms, per variant:

1. one array per variant, N x h x w in split order: ``PRED/clean.npy``,
   ``PRED/<corruption>/<level>.npy``, KITTI-S ``PRED/<style>.npy``; a ``.npz`` holding one
   array is accepted too.
   A ``.npy`` is read one map at a time.
2. one file per image, mirroring the dataset tree with the image's name:
   ``PRED/<variant dir>/<image path>`` with the extension ``.npy`` (a 2-D float map) or
   ``.png`` (16-bit, depth = value / ``png_scale``).

Ground truth: KITTI datasets, ``gt_depths.npz`` as monodepth2's ``export_gt_depth.py``
writes it (``np.load(f, allow_pickle=True)["data"]``: one float map in metres per split
image, in split order, as a pickled object array); NYU, a directory of 16-bit PNGs in
millimetres at the split lines' DEPTH paths (``<scene>/sync_depth_NNNNN.png`` for image
``<scene>/rgb_NNNNN``), as BTS's test set has them. It is read once, map by map; each map
is kept only as its valid pixels when that is smaller (KITTI's sparse lidar maps), else as
read. The pickle is read with only numpy's array reconstructors allowed (see
:func:`load_ground_truth`).
"""

from __future__ import annotations

import csv
import io
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Callable, Sequence

import numpy as np

from .api import CLEAN, BuiltDataset, Variant
from .errors import RobodepthError, os_reason

MIN_DEPTH = 1e-3
KITTI_MAX_DEPTH = 80.0
NYU_MAX_DEPTH = 10.0
STEREO_SCALE = 5.4  # monodepth2's STEREO_SCALE_FACTOR: the KITTI stereo baseline in its units
SIGMOID_MIN_DEPTH, SIGMOID_MAX_DEPTH = 0.1, 100.0  # monodepth2's defaults for disp_to_depth
GARG_CROP = (0.40810811, 0.99189189, 0.03594771, 0.96405229)  # top, bottom, left, right
NYU_EIGEN_CROP = (45, 471, 41, 601)  # rows 45..470, columns 41..600 (slice bounds)
KITTI_METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3")
NYU_METRICS = KITTI_METRICS + ("log10", "silog")
PROTOCOLS = ("kitti", "nyu")
KINDS = ("disp", "sigmoid", "depth")
PNG_SCALE = {"kitti": 256.0, "nyu": 1000.0}  # BTS's units: KITTI depth * 256, NYU millimetres


class EvaluationError(RobodepthError):
    """Predictions or ground truth that cannot be evaluated; the message names the file."""


# --------------------------------------------------------------------------- formulas

def disp_to_depth(disp: np.ndarray, min_depth: float = SIGMOID_MIN_DEPTH,
                  max_depth: float = SIGMOID_MAX_DEPTH) -> np.ndarray:
    """A network's sigmoid output as a scaled disparity (monodepth2's ``disp_to_depth``).

    ``scaled = 1 / max_depth + (1 / min_depth - 1 / max_depth) * disp``; with the defaults
    (0.1, 100) that is ``0.01 + 9.99 * disp``. Its inverse is the depth.
    """
    min_disp = 1 / max_depth
    max_disp = 1 / min_depth
    return min_disp + (max_disp - min_disp) * disp


def garg_crop(height: int, width: int) -> tuple[int, int, int, int]:
    """The Garg crop of an H x W map as slice bounds ``(top, bottom, left, right)``.

    ``top = int(0.40810811 H)``, ``bottom = int(0.99189189 H)``, ``left = int(0.03594771 W)``,
    ``right = int(0.96405229 W)``; the crop is ``rows top..bottom-1, columns left..right-1``.
    """
    t, b, left, right = GARG_CROP
    return int(t * height), int(b * height), int(left * width), int(right * width)


def depth_errors(gt: np.ndarray, pred: np.ndarray) -> tuple:
    """The seven depth metrics of one image over its valid pixels (1-D arrays, same order).

    With ``t = max(gt / pred, pred / gt)`` and means over the pixels:

    - ``abs_rel = mean(|gt - pred| / gt)``
    - ``sq_rel = mean((gt - pred)^2 / gt)``
    - ``rmse = sqrt(mean((gt - pred)^2))``
    - ``rmse_log = sqrt(mean((log gt - log pred)^2))``
    - ``a1, a2, a3 = mean(t < 1.25), mean(t < 1.25^2), mean(t < 1.25^3)``

    Returned in that order (:data:`KITTI_METRICS`).
    """
    thresh = np.maximum(gt / pred, pred / gt)
    a1 = (thresh < 1.25).mean()
    a2 = (thresh < 1.25 ** 2).mean()
    a3 = (thresh < 1.25 ** 3).mean()
    diff = gt - pred
    abs_rel = np.mean(np.abs(diff) / gt)
    sq_rel = np.mean(diff ** 2 / gt)
    rmse = np.sqrt(np.mean(diff ** 2))
    rmse_log = np.sqrt(np.mean((np.log(gt) - np.log(pred)) ** 2))
    return abs_rel, sq_rel, rmse, rmse_log, a1, a2, a3


def nyu_errors(gt: np.ndarray, pred: np.ndarray) -> tuple:
    """:func:`depth_errors` plus the two NYU metrics (:data:`NYU_METRICS` order):

    - ``log10 = mean(|log10 gt - log10 pred|)``
    - ``silog = sqrt(mean(e^2) - mean(e)^2) * 100`` with ``e = log pred - log gt``
    """
    e = np.log(pred) - np.log(gt)
    silog = np.sqrt(np.mean(e ** 2) - np.mean(e) ** 2) * 100
    log10 = np.mean(np.abs(np.log10(pred) - np.log10(gt)))
    return depth_errors(gt, pred) + (log10, silog)


def resize_bilinear(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """``cv2.resize(img, (width, height))``: bilinear, pixel centres aligned (OpenCV's
    ``INTER_LINEAR``), as monodepth2 resizes a disparity to the ground truth's size."""
    import cv2

    return cv2.resize(img, (width, height), interpolation=cv2.INTER_LINEAR)


def upsample_corners(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """Bilinear resize with the corner pixels aligned, as PyTorch's
    ``interpolate(mode="bilinear", align_corners=True)`` (AdaBins's evaluation).

    Output pixel ``(i, j)`` samples the input at ``(y, x) = (s_y i, s_x j)`` with
    ``s_y = (h - 1) / (H - 1)`` and ``s_x = (w - 1) / (W - 1)`` (0 when the output side is
    1): ``out = (1 - ly) ((1 - lx) a[y0, x0] + lx a[y0, x1]) + ly ((1 - lx) a[y1, x0] +
    lx a[y1, x1])`` with ``y0 = floor(y)``, ``y1 = min(y0 + 1, h - 1)``, ``ly = y - y0``,
    likewise for x. Like PyTorch on a float32 tensor, the positions and weights are
    float32 (their rounding moves samples by up to ~1e-5 pixel on a 480-row map, which
    float64 would not reproduce); the result is float32.
    """
    h, w = img.shape
    one = np.float32(1)

    def axis(n_in: int, n_out: int):
        scale = np.float32(n_in - 1) / np.float32(n_out - 1) if n_out > 1 else np.float32(0)
        pos = scale * np.arange(n_out, dtype=np.float32)
        lo = np.minimum(pos.astype(np.intp), n_in - 1)
        hi = np.minimum(lo + 1, n_in - 1)
        return lo, hi, pos - lo.astype(np.float32)

    y0, y1, ly = axis(h, height)
    x0, x1, lx = axis(w, width)
    src = img.astype(np.float32, copy=False)
    top, bottom = src[y0], src[y1]  # separable gathers: rows first, then columns
    lx0, ly0, ly1 = one - lx, (one - ly)[:, None], ly[:, None]
    return (ly0 * (lx0 * top[:, x0] + lx * top[:, x1])
            + ly1 * (lx0 * bottom[:, x0] + lx * bottom[:, x1]))


# --------------------------------------------------------------------------- protocols

@dataclass(frozen=True)
class Setup:
    """How the predictions are read and scored."""

    protocol: str  # "kitti" or "nyu"
    kind: str  # "disp", "sigmoid" or "depth"
    stereo: bool = False
    png_scale: float = 256.0
    kind_given: bool = True  # False: the protocol's default, and a PNG (a depth) overrides it

    @property
    def metrics(self) -> tuple[str, ...]:
        return NYU_METRICS if self.protocol == "nyu" else KITTI_METRICS

    @property
    def median_scaling(self) -> bool:
        return self.protocol == "kitti" and not self.stereo

    def describe(self) -> str:
        if self.protocol == "nyu":
            how = "metric depth, no scaling"
        elif self.stereo:
            how = f"stereo: depth x {STEREO_SCALE}, no median scaling"
        else:
            how = "mono: per-image median scaling"
        return f"protocol {self.protocol} ({how}), predictions: {self.kind}"


def make_setup(protocol: str, kind: str | None = None, stereo: bool = False,
               png_scale: float | None = None) -> Setup:
    """Check a combination of options; :class:`EvaluationError` naming the flag otherwise."""
    if protocol not in PROTOCOLS:
        raise EvaluationError(f"--protocol {protocol!r}: valid: {', '.join(PROTOCOLS)}")
    if kind is not None and kind not in KINDS:
        raise EvaluationError(f"--kind {kind!r}: valid: {', '.join(KINDS)}")
    if protocol == "nyu":
        if stereo:
            raise EvaluationError("--stereo applies to --protocol kitti only (nyu predictions are "
                                  "metric depths, never scaled)")
        if kind not in (None, "depth"):
            raise EvaluationError(f"--kind {kind}: --protocol nyu evaluates depths in metres "
                                  "(--kind depth)")
    if png_scale is not None and not (math.isfinite(png_scale) and png_scale > 0):
        raise EvaluationError(f"--png-scale {png_scale:g}: must be a positive number")
    default = "depth" if protocol == "nyu" else "disp"
    return Setup(protocol, kind or default, stereo,
                 PNG_SCALE[protocol] if png_scale is None else float(png_scale),
                 kind_given=kind is not None)


def kitti_image(pred: np.ndarray, kind: str, stereo: bool, gt_shape: tuple[int, int],
                index: np.ndarray, gt: np.ndarray) -> tuple[tuple, float | None]:
    """One image under the kitti protocol; returns (the :func:`depth_errors`, the median
    scaling ratio or None).

    ``pred`` (any size) is a disparity (``kind="disp"``, already scaled as monodepth2 saves
    it), a raw sigmoid output (``"sigmoid"``: first :func:`disp_to_depth`) or a depth
    (``"depth"``). It is resized to the ground truth's ``gt_shape`` with
    :func:`resize_bilinear`; a disparity is then inverted, ``depth = 1 / disp``. ``index``
    holds the flat indices of the valid pixels (:func:`kitti_valid`) and ``gt`` their depths.
    Mono: ``depth *= median(gt) / median(depth)`` (the ratio); stereo: ``depth *= 5.4``.
    Then ``depth`` is clamped to [1e-3, 80].
    """
    if kind == "sigmoid":
        pred = disp_to_depth(pred)
    pred = resize_bilinear(pred, *gt_shape)
    depth = pred.reshape(-1)[index]
    if kind != "depth":
        with np.errstate(divide="ignore"):
            depth = 1 / depth
    ratio = None
    if stereo:
        depth = depth * STEREO_SCALE
    else:
        ratio = np.median(gt) / np.median(depth)
        depth = depth * ratio
    depth[depth < MIN_DEPTH] = MIN_DEPTH
    depth[depth > KITTI_MAX_DEPTH] = KITTI_MAX_DEPTH
    return depth_errors(gt, depth), ratio


def kitti_valid(gt: np.ndarray) -> np.ndarray:
    """Flat indices (row-major) of the kitti protocol's valid pixels of a ground-truth map:
    ``1e-3 < gt < 80`` inside the :func:`garg_crop`."""
    mask = (gt > MIN_DEPTH) & (gt < KITTI_MAX_DEPTH)
    top, bottom, left, right = garg_crop(*gt.shape)
    crop = np.zeros(gt.shape, bool)
    crop[top:bottom, left:right] = True
    return np.flatnonzero(mask & crop)


def nyu_valid(gt: np.ndarray) -> np.ndarray:
    """Flat indices (row-major) of the nyu protocol's valid pixels: ``1e-3 < gt < 10``
    (non-finite depths count as 0) inside rows 45..470 and columns 41..600."""
    finite = np.isfinite(gt)
    mask = finite & (gt > MIN_DEPTH) & (gt < NYU_MAX_DEPTH)
    top, bottom, left, right = NYU_EIGEN_CROP
    crop = np.zeros(gt.shape, bool)
    crop[top:bottom, left:right] = True
    return np.flatnonzero(mask & crop)


def nyu_image(pred: np.ndarray, gt_shape: tuple[int, int], index: np.ndarray,
              gt: np.ndarray) -> tuple:
    """One image under the nyu protocol; returns the :func:`nyu_errors`.

    ``pred`` is a depth in metres of the ground truth's size, or smaller: then it is first
    upsampled with :func:`upsample_corners`. Clamped to [1e-3, 10] (infinity becomes 10),
    compared at the valid pixels ``index`` (:func:`nyu_valid`) with their depths ``gt``.
    No scaling.
    """
    if pred.shape != gt_shape:
        pred = upsample_corners(pred, *gt_shape)
    depth = pred.reshape(-1)[index]
    depth[depth < MIN_DEPTH] = MIN_DEPTH
    depth[depth > NYU_MAX_DEPTH] = NYU_MAX_DEPTH
    return nyu_errors(gt, depth)


VALID = {"kitti": kitti_valid, "nyu": nyu_valid}


# --------------------------------------------------------------------------- ground truth

class GroundTruth:
    """The ground-truth maps of a split, read once, in split order.

    Each map is kept as its valid pixels (flat indices and depths) when that is smaller
    than the map itself, else as read and prepared again on each use.
    """

    def __init__(self, source: str, protocol: str):
        self.source = source
        self._valid = VALID[protocol]
        self._items: list = []
        self.shapes: list[tuple[int, int]] = []

    def add(self, depth: np.ndarray, raw: np.ndarray | None = None,
            divisor: float | None = None, where: str | None = None) -> None:
        """Add the next map: ``depth`` in metres; ``raw`` and ``divisor`` (optional) a
        smaller form it can be recomputed from as ``raw.astype(float32) / divisor``."""
        self.append(self.prepare(depth, raw, divisor,
                                 where or f"{self.source}: ground-truth map {len(self._items)}"))

    def prepare(self, depth: np.ndarray, raw: np.ndarray | None, divisor: float | None,
                where: str) -> tuple:
        """The kept form of one map (see :meth:`add`), not yet added."""
        index = self._valid(depth).astype(np.int32 if depth.size < 2 ** 31 else np.int64)
        if not index.size:
            # The reference would average a NaN into every metric; say which map instead.
            raise EvaluationError(f"{where} has no valid pixel inside the protocol's crop and "
                                  "depth range")
        values = depth.reshape(-1)[index]
        kept = raw if raw is not None else depth
        if index.nbytes + values.nbytes <= kept.nbytes:
            return depth.shape, (index, values)
        return depth.shape, (kept, divisor)

    def append(self, prepared: tuple) -> None:
        shape, item = prepared
        self._items.append(item)
        self.shapes.append(shape)

    def __len__(self) -> int:
        return len(self._items)

    def get(self, i: int) -> tuple[tuple[int, int], np.ndarray, np.ndarray]:
        """(shape, flat indices of the valid pixels, their ground-truth depths) of map ``i``."""
        item = self._items[i]
        if isinstance(item[1], np.ndarray):
            return self.shapes[i], item[0], item[1]
        kept, divisor = item
        depth = kept if divisor is None else kept.astype(np.float32) / divisor
        index = self._valid(depth)
        return self.shapes[i], index, depth.reshape(-1)[index]


def load_ground_truth(path: Path, names: Sequence[str], protocol: str) -> GroundTruth:
    """Read the ground truth of a split's images from ``path``: a ``.npz``/``.npy`` file of
    depth maps in metres, one per image in split order (monodepth2's ``gt_depths.npz``), or
    a directory of 16-bit PNGs in millimetres at the relative paths ``names`` (one per
    image, in split order). Raises :class:`EvaluationError` naming the file (and map index)
    for a missing, unreadable or malformed map, and when the file holds another number of
    maps than the split has images.

    A pickled object array (monodepth2's format) is unpickled with nothing but numpy's
    array and dtype reconstructors allowed, so a crafted file cannot run code, and each map
    is reduced as soon as it is read: the ~1.3 GB of KITTI maps are never in memory
    together (peak ~125 MB for the 697 Eigen maps, against ~1.3 GB with ``np.load``).
    """
    path = Path(path)
    gt = GroundTruth(str(path), protocol)
    if path.is_dir():
        for i, name in enumerate(names):
            file = path / name
            raw = _read_png16(file, f"ground truth of image {i}")
            gt.add(raw.astype(np.float32) / 1000.0, raw, 1000.0,
                   f"{file} (ground truth of image {i})")
        return gt
    count = _read_gt_file(path, gt)
    if count != len(names):
        raise EvaluationError(f"{path}: {count} ground-truth maps, but the dataset's split has "
                              f"{len(names)} images; ground truth and split must match one to one")
    return gt


def _check_gt_map(m, path: Path, i: int) -> np.ndarray:
    if not isinstance(m, np.ndarray) or m.ndim != 2 or m.dtype.kind not in "fiu" or 0 in m.shape:
        what = (f"shape {m.shape} and dtype {m.dtype}" if isinstance(m, np.ndarray)
                else f"a {type(m).__name__}")
        raise EvaluationError(f"{path}: ground-truth map {i} has {what}; expected a 2-D depth map")
    return m


def _read_gt_file(path: Path, gt: GroundTruth) -> int:
    """Add every map of a ``.npz``/``.npy`` ground-truth file to ``gt``; return how many.

    monodepth2's file is an object array of differently sized maps, which numpy stores as
    a pickle. It is unpickled here with only numpy's array and dtype reconstructors allowed
    (anything else in the file is refused, so a crafted file cannot run code), and each map
    is reduced to its kept form as soon as it is read: the ~1.3 GB of maps are never in
    memory together. A plain N x H x W array is read as it is.
    """
    if not path.exists():
        raise EvaluationError(f"{path}: no such ground-truth file")
    try:
        with open(path, "rb") as raw:
            if zipfile.is_zipfile(raw):
                raw.seek(0)
                with zipfile.ZipFile(raw) as zf:
                    names = zf.namelist()
                    member = ("data.npy" if "data.npy" in names
                              else names[0] if len(names) == 1 else None)
                    if member is None:
                        raise EvaluationError(f"{path}: holds {', '.join(names)}; expected 'data' "
                                              "(monodepth2's gt_depths.npz) or a single array")
                    with zf.open(member) as fh:
                        return _read_gt_stream(fh, path, gt)
            raw.seek(0)
            return _read_gt_stream(raw, path, gt)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        if isinstance(exc, EvaluationError):
            raise
        raise EvaluationError(f"{path}: not a numpy .npz/.npy ground-truth file ({exc})") from None


def _read_gt_stream(fh, path: Path, gt: GroundTruth) -> int:
    fmt = np.lib.format
    version = fmt.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = fmt.read_array_header_1_0(fh)
    else:
        shape, fortran, dtype = fmt.read_array_header_2_0(fh)
    if not dtype.hasobject:
        if len(shape) != 3:
            raise EvaluationError(f"{path}: ground truth of shape {shape}; expected N depth maps "
                                  "(an object array of 2-D maps, or N x H x W)")
        nbytes = int(np.prod(shape)) * dtype.itemsize
        buf = fh.read(nbytes)
        if len(buf) != nbytes:
            raise EvaluationError(f"{path}: the array ends early (truncated?)")
        data = np.frombuffer(buf, dtype).reshape(shape, order="F" if fortran else "C")
        for i in range(len(data)):
            gt.add(_check_gt_map(data[i], path, i))
        return len(data)
    if len(shape) != 1:
        raise EvaluationError(f"{path}: ground truth of shape {shape}; expected a 1-D object "
                              "array of 2-D depth maps")
    counter = iter(range(1 << 62))

    def reduce(m: np.ndarray):
        i = next(counter)
        return _Prepared(gt.prepare(_check_gt_map(m, path, i), None, None,
                                    f"{path}: ground-truth map {i}"))

    data = _MapUnpickler(fh, path, reduce).load()
    if not isinstance(data, np.ndarray) or data.ndim != 1:
        raise EvaluationError(f"{path}: does not hold a 1-D array of depth maps")
    for i, m in enumerate(data):
        prepared = m if isinstance(m, _Prepared) else getattr(m, "prepared", None)
        if prepared is None:
            _check_gt_map(m, path, i)  # raises: not a map
        gt.append(prepared.value)
    return len(data)


class _Prepared:
    """A ground-truth map already reduced to its kept form, inside the unpickled array."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value


_NUMPY_MODULES = ("numpy", "numpy.core.multiarray", "numpy._core.multiarray",
                  "numpy.core.numeric", "numpy._core.numeric")
_ALLOWED = {"ndarray", "dtype", "_reconstruct", "_frombuffer"}


class _MapUnpickler:
    """Unpickles an object array of maps, allowing only numpy's reconstructors and handing
    each 2-D numeric map to ``reduce`` the moment it is complete (protocol 5:
    ``_frombuffer``; older protocols: ``ndarray.__setstate__``).

    The unpickler's memo would keep every map's raw bytes alive to the end (pickle
    memoizes each bytes object and state tuple); every few maps, those large entries are
    replaced by None. Nothing refers back to them: each map's bytes are its own.
    """

    PRUNE_EVERY = 8
    LARGE = 1 << 12  # bytes; the small shared constants (dtype codes, shapes) stay

    def __init__(self, fh, path: Path, reduce):
        import pickle

        outer = self
        self._done = 0

        def reduced(arr):
            result = reduce(arr)
            outer._done += 1
            if outer._done % outer.PRUNE_EVERY == 0:
                outer._prune()
            return result

        class Map(np.ndarray):
            def __setstate__(self, state):
                super().__setstate__(state)
                if self.dtype.hasobject or self.ndim != 2:
                    return
                self.prepared = reduced(np.array(self, copy=True).view(np.ndarray))
                # Release the pixels: only the reduced form is kept.
                super().__setstate__((1, (0,), self.dtype, False, b""))

        def frombuffer(*args):
            arr = outer._frombuffer(*args)
            if arr.dtype.hasobject or arr.ndim != 2:
                return arr
            return reduced(np.array(arr, copy=True))

        # The Python implementation: its memo is a plain dict that can be pruned mid-load.
        class Unpickler(pickle._Unpickler):
            def find_class(self, module, name):
                # Protocol 2 (numpy's np.save before 1.17) spells bytes as _codecs.encode.
                if (module, name) == ("_codecs", "encode"):
                    return super().find_class(module, name)
                if module not in _NUMPY_MODULES or name not in _ALLOWED:
                    raise EvaluationError(f"{path}: holds a pickled {module}.{name}; ground truth "
                                          "may hold only numpy arrays (refused, not loaded)")
                if name == "ndarray":
                    return Map
                real = super().find_class(module, name)
                if name == "_frombuffer":
                    outer._frombuffer = real
                    return frombuffer
                return real

        self._unpickler = Unpickler(fh, encoding="latin1")

    def load(self):
        return self._unpickler.load()

    def _prune(self) -> None:
        def large(v) -> bool:
            if isinstance(v, (bytes, bytearray, str)):
                return len(v) >= self.LARGE
            return isinstance(v, tuple) and any(large(x) for x in v)

        memo = self._unpickler.memo
        for k in [k for k, v in memo.items() if large(v)]:
            memo[k] = None  # not deleted: new entries are numbered by the memo's length


def _read_png16(file: Path, what: str) -> np.ndarray:
    import cv2

    if not file.is_file():
        raise EvaluationError(f"{file}: no such file ({what})")
    raw = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise EvaluationError(f"{file}: not a readable PNG ({what})")
    if raw.ndim != 2 or raw.dtype != np.uint16:
        got = f"{raw.dtype.itemsize * 8}-bit" + (f", {raw.shape[2]} channels" if raw.ndim == 3 else "")
        raise EvaluationError(f"{file}: {got}; expected a 16-bit single-channel PNG ({what})")
    return raw


# --------------------------------------------------------------------------- predictions

class Predictions:
    """The predictions of one variant: ``len(keys)`` 2-D maps, read one at a time."""

    variant: Variant
    source: Path

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
            if self.source.suffix == ".npz":
                with np.load(self.source, allow_pickle=False) as z:
                    self._array = z[z.files[0]]
            else:
                self._array = np.load(self.source, mmap_mode="r", allow_pickle=False)
        return np.array(self._array[i]), where, False

    def close(self):
        self._array = None
        if self._fh is not None:
            self._fh.close()
            self._fh = None


def _array_header(path: Path) -> tuple[tuple[int, ...], bool, np.dtype, int]:
    """Shape, Fortran order, dtype and data offset of a ``.npy`` file or of the one array of
    a ``.npz``, without reading the data."""
    fmt = np.lib.format
    try:
        if path.suffix == ".npz":
            with zipfile.ZipFile(path) as zf:
                names = [n for n in zf.namelist() if n.endswith(".npy")]
                if len(names) != 1 or len(zf.namelist()) != 1:
                    raise EvaluationError(f"{path}: holds {len(zf.namelist())} arrays; expected "
                                          "exactly one (N x h x w)")
                with zf.open(names[0]) as fh:
                    return _header(fh, fmt)
        with open(path, "rb") as fh:
            return _header(fh, fmt)
    except (ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise EvaluationError(f"{path}: not a numpy {path.suffix} file ({exc})") from None
    except OSError as exc:
        raise EvaluationError(f"{path}: cannot read ({os_reason(exc)})") from None


def _header(fh, fmt):
    version = fmt.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = fmt.read_array_header_1_0(fh)
    else:
        shape, fortran, dtype = fmt.read_array_header_2_0(fh)
    return tuple(shape), fortran, dtype, fh.tell()


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

    def read(self, i):
        file = self.files[i]
        where = f"{file} (image {i})"
        if file.suffix == ".png":
            raw = _read_png16(file, f"prediction of image {i}")
            return raw.astype(np.float32) / np.float32(self.png_scale), where, True
        try:
            m = np.load(file, allow_pickle=False)
        except (OSError, ValueError, EOFError) as exc:
            raise EvaluationError(f"{file}: not a readable .npy file ({exc}) (image {i})") from None
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


def _check_values(m: np.ndarray, where: str) -> None:
    low = np.min(m)
    if np.isnan(low):
        raise EvaluationError(f"{where} contains NaN")
    if low < 0:
        raise EvaluationError(f"{where} has negative values (min {float(low):g})")


# --------------------------------------------------------------------------- evaluation

@dataclass
class VariantResult:
    variant: Variant
    metrics: dict[str, float]  # mean over the images
    ratios: np.ndarray | None = None  # median-scaling ratio per image (mono kitti only)

    @property
    def csv_key(self) -> tuple[str, int]:
        """(corruption, level) as the results CSV names it: clean and styles have level 0."""
        return self.variant.name, self.variant.level or 0

    def ratio_summary(self) -> tuple[float, float] | None:
        """(median of the ratios, std of ratio / median), as monodepth2 prints them."""
        if self.ratios is None or not len(self.ratios):
            return None
        med = np.median(self.ratios)
        return float(med), float(np.std(self.ratios / med))


@dataclass
class Evaluation:
    dataset: str
    setup: Setup
    predictions: str
    ground_truth: str
    images: int  # per variant
    results: list[VariantResult] = field(default_factory=list)
    missing: list[Variant] = field(default_factory=list)  # no predictions (--allow-partial)

    def csv_text(self) -> str:
        """The results CSV: ``corruption,level`` then the metrics, one row per variant,
        full float precision (``repr``)."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(("corruption", "level") + self.setup.metrics)
        for r in self.results:
            name, level = r.csv_key
            w.writerow([name, level] + [repr(r.metrics[m]) for m in self.setup.metrics])
        return buf.getvalue()

    def to_json(self) -> dict:
        rows = []
        for r in self.results:
            name, level = r.csv_key
            row = {"corruption": name, "level": level, **r.metrics}
            summary = r.ratio_summary()
            if summary:
                row["scaling_ratio"] = {"median": summary[0], "std": summary[1]}
            rows.append(row)
        return {"dataset": self.dataset, "protocol": self.setup.protocol,
                "kind": self.setup.kind, "stereo": self.setup.stereo,
                "median_scaling": self.setup.median_scaling, "predictions": self.predictions,
                "ground_truth": self.ground_truth, "images": self.images, "results": rows,
                "partial": bool(self.missing),
                "missing": [{"corruption": v.name, "level": v.level or 0} for v in self.missing]}

    def summary(self) -> str:
        """A table of the metrics per variant (3 decimals) and, with median scaling, the
        ratios' median and spread per variant as monodepth2 prints them."""
        metrics = self.setup.metrics
        width = max([len("variant")] + [len(r.variant.label) for r in self.results]) + 2
        head = f"{'variant':<{width}}" + "".join(f"{m:>10}" for m in metrics)
        if self.setup.median_scaling:
            head += f"{'ratio med':>11}{'std':>7}"
        lines = [f"{self.dataset}: {len(self.results)} variants x {self.images} images, "
                 f"{self.setup.describe()}", head]
        for r in self.results:
            line = f"{r.variant.label:<{width}}" + "".join(f"{r.metrics[m]:>10.3f}" for m in metrics)
            summary = r.ratio_summary()
            if summary:
                line += f"{summary[0]:>11.3f}{summary[1]:>7.3f}"
            lines.append(line)
        if self.missing:
            lines.append(f"partial: no predictions for {len(self.missing)} variants: "
                         f"{_list(self.missing)}")
        return "\n".join(lines) + "\n"


def _list(variants: Sequence[Variant], most: int = 12) -> str:
    names = [v.relpath for v in variants]
    more = f", ... ({len(names) - most} more)" if len(names) > most else ""
    return ", ".join(names[:most]) + more


def evaluate(dataset: BuiltDataset, pred: Path, setup: Setup, *, gt: Path | None = None,
             allow_partial: bool = False, require_clean: bool = False,
             progress: Callable[[int], None] | None = None,
             on_total: Callable[[int], None] | None = None) -> Evaluation:
    """Evaluate the predictions under ``pred`` for every variant of ``dataset``.

    Everything that can be checked without reading the data is checked first: the
    predictions of every variant (presence, count, shape) and the ground truth (present,
    one map per split image). Missing variants are an error unless ``allow_partial``.
    ``progress(n)`` is called as images are done; ``on_total(n)`` once with their number.
    Raises :class:`EvaluationError` for any bad input; nothing is written here.
    """
    pred = Path(pred)
    if not pred.is_dir():
        raise EvaluationError(f"{pred}: no such predictions directory")
    variants = dataset.variants()
    found: list[tuple[Variant, Predictions]] = []
    missing: list[Variant] = []
    for v in variants:
        p = find_predictions(pred, v, setup.png_scale)
        if p is None:
            missing.append(v)
        else:
            found.append((v, p))
    if not found:
        raise EvaluationError(f"{pred}: no predictions for any of the {len(variants)} variants of "
                              f"{dataset.path} (expected e.g. {variants[0].prediction_file(pred)})")
    if missing and not allow_partial:
        raise EvaluationError(f"{pred}: no predictions for {len(missing)} of {len(variants)} "
                              f"variants: {_list(missing)} (--allow-partial evaluates the rest)")
    if require_clean and variants[0].name == CLEAN and variants[0] in missing:
        raise EvaluationError(f"{pred}: no predictions for the clean images; the scores need "
                              "them (resilience rates divide by the clean DEE)")
    gt_path = gt if gt is not None else dataset.ground_truth()
    if gt_path is None:
        raise EvaluationError(f"{dataset.path}: no ground truth (gt_depths.npz for KITTI, gt/ for "
                              "NYU); build it with ground truth, run robodepth gt, or pass --gt")
    gt_path = Path(gt_path)
    names = dataset.depth_names() if gt_path.is_dir() else dataset.keys
    truth = load_ground_truth(gt_path, names, setup.protocol)
    n = len(dataset.keys)
    if on_total:
        on_total(n * len(found))
    result = Evaluation(dataset.name, setup, str(pred), str(gt_path), n, missing=missing)
    for v, p in found:
        try:
            result.results.append(_evaluate_variant(v, p, truth, setup, dataset.size, progress))
        finally:
            p.close()
    return result


def _evaluate_variant(variant: Variant, preds: Predictions, truth: GroundTruth, setup: Setup,
                      image_size, progress) -> VariantResult:
    errors = []
    ratios = []
    for i in range(len(variant)):
        m, where, is_png = preds.read(i)
        if m.dtype not in (np.float32, np.float64):
            m = m.astype(np.float32)  # OpenCV and the reference code work in float32
        _check_values(m, where)
        shape, index, gt = truth.get(i)
        if is_png and shape != m.shape and tuple(m.shape) != tuple(image_size or ()):
            raise EvaluationError(f"{where} is {m.shape[0]} x {m.shape[1]}; a PNG prediction must "
                                  f"have the ground truth's size {shape[0]} x {shape[1]} or the "
                                  "image's")
        kind = setup.kind
        if is_png:
            if setup.kind_given and setup.kind != "depth":
                raise EvaluationError(f"{where}: a PNG prediction is a depth (value / "
                                      f"--png-scale), not --kind {setup.kind}")
            kind = "depth"
        if setup.protocol == "kitti":
            errs, ratio = kitti_image(m, kind, setup.stereo, shape, index, gt)
            if ratio is not None:
                ratios.append(ratio)
        else:
            if m.shape[0] > shape[0] or m.shape[1] > shape[1]:
                raise EvaluationError(f"{where} is {m.shape[0]} x {m.shape[1]}, larger than its "
                                      f"ground truth ({shape[0]} x {shape[1]})")
            errs = nyu_image(m, shape, index, gt)
        errors.append(errs)
        if progress:
            progress(1)
    means = np.array(errors, dtype=np.float64).mean(0)
    return VariantResult(variant, {k: float(v) for k, v in zip(setup.metrics, means)},
                         np.array(ratios, dtype=np.float64) if setup.median_scaling else None)


def write_results(path: Path, text: str) -> None:
    """Write the results CSV atomically (a temporary file, then a rename)."""
    from .files import write_atomic

    try:
        write_atomic(path, text.encode("utf-8"))
    except OSError as exc:
        raise EvaluationError(f"{path}: cannot write ({os_reason(exc)})") from None
