"""A variant's maps judged a block at a time, each block in one compiled call
(:func:`.kernels._judge_sparse`, :func:`.kernels._judge_dense`), with no Python between
one map and the next: the numbers :func:`.image.image_errors` gives each map, computed by
the same kernels. What a block call does not judge (a map refused by the value check, a
scale that is not a positive number, a ground-truth map of another form or dtype) is
judged by :func:`.image.image_errors`, which says why a map is refused.

Everything that depends on the ground truth only (its pixels' addresses, dtypes, each
image's median) is made once per evaluation (:func:`plan`) and shared by its variants.
"""

from __future__ import annotations

import numpy as np

from ..groundtruth.read import GroundTruth
from .protocols import _SIGMOID, STEREO_SCALE, Setup, crop_box
from . import kernels

BLOCK = 32  # maps a call: the pages of a block are released after it (predictions.py)


class Plan:
    """How the maps of ``shape`` and ``dtype`` are judged against ``truth`` under
    ``setup``; :meth:`judge` judges a block of them."""

    def __init__(self, truth: GroundTruth, setup: Setup, shape: tuple[int, int], dtype: np.dtype):
        n = len(truth)
        self.setup, self.shape, self.dtype = setup, shape, dtype
        p = dtype.type
        sigmoid = setup.kind == "sigmoid"
        # check_values's rule: values in [0, 1] (sigmoid) or [0, inf), a positive one (else)
        self.check = (p(1) if sigmoid else p(np.finfo(dtype).max), not sigmoid)
        self.nyu = setup.protocol == "nyu"
        self._keep = []  # the arrays whose addresses the calls read
        self.sparse = self._sparse(truth, n) if self._sparse_applies() else None
        self.dense = self._dense(truth, n) if self._dense_applies() else None

    # ----------------------------------------------------------------- which maps

    def _sparse_applies(self) -> bool:
        """kitti_image's direct path (no alignment but median scaling, in depth space), or
        nyu_image's (a depth, not aligned; its size checked per image)."""
        s = self.setup
        if s.protocol == "kitti":
            return s.align_space == "depth" and s.alignment in ("none", "median")
        return s.kind == "depth" and s.alignment == "none"

    def _dense_applies(self) -> bool:
        """:func:`.protocols.whole_map_image`'s setups."""
        s = self.setup
        return s.kind == "depth" and not s.stereo and s.alignment == "none"

    def _sparse(self, truth: GroundTruth, n: int) -> dict | None:
        counts = np.zeros(n, np.int64)
        index_at, gt_at, bounds_at = np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64)
        shape_of = np.full(n, -1)
        shapes: list[tuple[int, int]] = []
        gdtype = idtype = None
        by_median = self.setup.alignment == "median"
        gmed = np.zeros(n)
        for i in range(n):
            if truth.dense(i) is not None:
                continue
            shape, index, values = truth.get(i)
            shape = tuple(shape)
            if self.nyu and shape != self.shape:
                continue  # upsampled or refused: image_errors
            gdtype = gdtype or values.dtype
            idtype = idtype or index.dtype
            if (values.dtype != gdtype or index.dtype != idtype or not index.flags.c_contiguous
                    or not values.flags.c_contiguous or values.dtype.kind != "f"
                    or index.size > 1 and (np.diff(index) <= 0).any()):
                continue  # the valid pixels' indices are sorted (flatnonzero): else one by one
            bounds = kernels.row_bounds(index, shape)
            if shape not in shapes:
                shapes.append(shape)
            shape_of[i] = shapes.index(shape)
            counts[i], index_at[i], gt_at[i] = index.size, index.ctypes.data, values.ctypes.data
            bounds_at[i] = bounds.ctypes.data
            if by_median:
                gmed[i] = kernels.median(values)
            self._keep += [index, values, bounds]
        if not shapes:
            return None
        p, s = self.dtype.type, self.setup
        scale = np.result_type(gdtype, self.dtype) if by_median else self.dtype
        d = np.result_type(self.dtype, scale)
        t = np.result_type(gdtype, d)
        kinds = dict(sigmoid=s.kind == "sigmoid", lo=p(_SIGMOID[0]), span=p(_SIGMOID[1]),
                     invert=s.kind != "depth", one=p(1), two=p(2), by_median=by_median,
                     factor=scale.type(STEREO_SCALE if s.stereo else 1), zs=scale.type(0),
                     low=d.type(s.min_depth), high=d.type(s.depth_cap), zt=t.type(0))
        size = int(counts.max())
        # one call per ground-truth size: the counts of the others' images are 0 in it
        counts = [np.where(shape_of == j, counts, 0) for j in range(len(shapes))]
        return dict(counts=counts, index_at=index_at, gt_at=gt_at, bounds_at=bounds_at, shape_of=shape_of,
                    shapes=shapes,
                    gmed=gmed.astype(gdtype), zi=idtype.type(0), zg=gdtype.type(0), kinds=kinds,
                    buffers=(np.empty(size, self.dtype), np.empty(size, self.dtype),
                             np.empty(size, self.dtype)))

    def _dense(self, truth: GroundTruth, n: int) -> dict | None:
        raw_at, divisors = np.zeros(n, np.int64), np.ones(n, np.float32)
        rdtype = None
        for i in range(n):
            whole = truth.dense(i)
            if whole is None:
                continue
            kept, divisor = whole
            if kept.shape != self.shape or not (kept.dtype.kind in "iu" or kept.dtype == np.float32):
                continue
            rdtype = rdtype or kept.dtype
            if kept.dtype != rdtype or not kept.flags.c_contiguous:
                continue
            raw_at[i] = kept.ctypes.data
            divisors[i] = 1.0 if divisor is None else divisor
            self._keep.append(kept)
        if rdtype is None:
            return None
        s, p = self.setup, self.dtype.type
        t = np.result_type(self.dtype, np.float32)
        box = np.asarray(crop_box(s.crop_name, s.protocol, *self.shape), np.int64)
        f32 = np.float32
        return dict(raw_at=raw_at, zr=rdtype.type(0), divisors=divisors, box=box,
                    valid=(f32(s.min_depth), f32(s.depth_cap)), clamp=(p(s.min_depth), p(s.depth_cap)),
                    one=p(1), zero=t.type(0))

    # ----------------------------------------------------------------- judging

    def judge(self, maps: np.ndarray, first: int, last: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Maps ``first..last-1`` of the variant's ``maps`` (N x h x w): ``(ok, metrics,
        ratios)``, a row each; where ``ok`` is False, :func:`.image.image_errors` judges."""
        k = last - first
        ok, out, ratios = np.zeros(k, bool), np.zeros((k, 9)), np.zeros(k)
        cap, positive = self.check
        sp, dn = self.sparse, self.dense
        if sp is not None:
            kk = sp["kinds"]
            for j in np.unique(sp["shape_of"][first:last]):
                if j < 0:
                    continue
                height, width = sp["shapes"][j]
                resize = tuple(maps.shape[1:]) != (height, width)
                double = self.dtype == np.float64
                x0, x1, wx = kernels.linear_axis(maps.shape[2], width, double) if resize else kernels._NONE[double]
                y0, y1, wy = kernels.linear_axis(maps.shape[1], height, double) if resize else kernels._NONE[double]
                kernels._judge_sparse(maps, first, last, sp["index_at"], sp["gt_at"], sp["bounds_at"], height,
                                sp["counts"][j], sp["gmed"],
                                sp["zi"], sp["zg"], width, x0, x1, wx, y0, y1, wy, resize, kk["sigmoid"],
                                kk["lo"], kk["span"], kk["invert"], kk["one"], kk["two"], kk["by_median"],
                                kk["factor"], kk["zs"], kk["low"], kk["high"], kk["zt"], cap, positive,
                                self.nyu, *sp["buffers"], out, ratios, ok)
        if dn is not None and dn["raw_at"][first:last].any():
            kernels._judge_dense(maps, first, last, dn["raw_at"], dn["zr"], dn["divisors"], dn["box"],
                           *dn["valid"], *dn["clamp"], dn["one"], dn["zero"], cap, positive, self.nyu,
                           out, ok)
        return ok, out, ratios


def plan(preds, truth, setup: Setup, cache: dict) -> Plan | None:
    """The :class:`Plan` for a variant's predictions (made once per evaluation for each
    size and dtype of map, kept in ``cache``), or None when no map of them is judged in
    blocks: per-image files, maps neither float32 nor float64, ground truth read per image."""
    header = getattr(preds, "header", None)
    if header is None or not isinstance(truth, GroundTruth):
        return None
    shape, dtype = header
    if dtype not in (np.float32, np.float64) or len(shape) != 3:
        return None
    key = ("plan", tuple(shape[1:]), dtype.str)
    if key not in cache:
        cache[key] = Plan(truth, setup, tuple(shape[1:]), dtype)
    found = cache[key]
    return found if found.sparse is not None or found.dense is not None else None
