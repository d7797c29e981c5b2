"""The evaluation's inner loops, compiled (numba): a prediction sampled only at the valid
ground-truth pixels, and the metrics of a map in one pass, with no full-size temporaries.

Every per-pixel step is done in the dtype numpy's expression of the reference code would
use (float32 for float32 inputs: the prediction's dtype, promoted with the ground truth's
and the scale's as numpy promotes), so the depths compared are the same numbers to the
last bit; only the sums differ: each metric accumulates in float64 in pixel order
(numpy sums float32 pairwise in float32), and the logarithms are float64.

:func:`sample_linear` is ``cv2.resize(pred, (W, H), interpolation=cv2.INTER_LINEAR)`` at
the valid pixels only. The opencv-python wheel hands a float resize to IPP; its rules,
found by comparing outputs bit for bit (tests/evaluation/test_fused.py):

- output pixel ``d`` of an axis of ``n`` samples the input at ``f = (d + 0.5) n_in / n -
  0.5``, computed in float64 (float64 maps: ``fma(d, s, 0.5 s - 0.5)`` with ``s = n_in /
  n``); ``i = floor(f)``, weight ``w = f - i`` rounded to the map's dtype; the two inputs
  ``i`` and ``i + 1`` are clamped to the axis (the border is the edge pixel repeated);
- rows first: ``h = fma(b - a, wx, a)`` for the two input rows, then ``fma(h1 - h0, wy,
  h0)``, each a multiply-add rounded once in the map's dtype.

A map of the ground truth's size is not resized (OpenCV copies it): its pixels are taken
as they are.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..corruptions.jit import fma, njit


@lru_cache(maxsize=64)
def linear_axis(n_in: int, n_out: int, double: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(i0, i1, w)`` of one axis of an ``INTER_LINEAR`` resize from ``n_in`` to ``n_out``
    samples (the module's rules): the two input indices, clamped, and the weight of the
    second, float32 (``double``: float64, computed with a fused multiply-add)."""
    d = np.arange(n_out, dtype=np.float64)
    s = n_in / n_out
    f = _fma_positions(d, s, 0.5 * s - 0.5) if double else (d + 0.5) * s - 0.5
    i = np.floor(f)
    w = (f - i).astype(np.float64 if double else np.float32)
    i = i.astype(np.int64)
    lo, hi = np.clip(i, 0, n_in - 1), np.clip(i + 1, 0, n_in - 1)
    for a in (lo, hi, w):
        a.setflags(write=False)
    return lo, hi, w


@njit
def _fma_positions(d, s, t):
    out = np.empty_like(d)
    for k in range(d.size):
        out[k] = fma(d[k], s, t)
    return out


@njit
def _sample(pred, index, width, x0, x1, wx, y0, y1, wy, resize, sigmoid, lo, span, out):
    """``out[k]`` = the prediction at flat ground-truth pixel ``index[k]`` (``width`` per
    row): interpolated from its four inputs (``resize``) or read; each input first through
    ``lo + span * v`` (``sigmoid``)."""
    row = -1
    start = 0
    for k in range(index.size):
        q = index[k]
        if row < 0 or q < start or q >= start + width:  # sorted indices: once per row
            row = q // width
            start = row * width
        c = q - start
        if resize:
            r0, r1, c0, c1 = y0[row], y1[row], x0[c], x1[c]
            a, b, e, f = pred[r0, c0], pred[r0, c1], pred[r1, c0], pred[r1, c1]
            if sigmoid:
                a, b, e, f = lo + span * a, lo + span * b, lo + span * e, lo + span * f
            h0 = fma(b - a, wx[c], a)
            h1 = fma(f - e, wx[c], e)
            v = fma(h1 - h0, wy[row], h0)
        else:
            v = pred[row, c]
            if sigmoid:
                v = lo + span * v
        out[k] = v
    return out


def sample_linear(pred: np.ndarray, gt_shape: tuple[int, int], index: np.ndarray, *,
                  sigmoid: tuple[float, float] | None = None, invert: bool = False) -> np.ndarray:
    """``cv2.resize(pred, (W, H), interpolation=cv2.INTER_LINEAR).reshape(-1)[index]`` for a
    float32 or float64 map and ground truth of shape ``gt_shape = (H, W)``, computing only
    the pixels ``index`` (flat, row-major; fastest sorted), bit for bit (the module's rules).

    ``sigmoid = (lo, span)``: each input pixel is first ``lo + span * v`` (as
    :func:`~.protocols.disp_to_depth` maps the whole map before the resize); ``invert``:
    the result is ``1 / v``, in the map's dtype. The values come out in the map's dtype.
    """
    dt = pred.dtype.type
    height, width = gt_shape
    resize = pred.shape != tuple(gt_shape)
    double = pred.dtype == np.float64
    x0, x1, wx = linear_axis(pred.shape[1], width, double) if resize else _NONE[double]
    y0, y1, wy = linear_axis(pred.shape[0], height, double) if resize else _NONE[double]
    lo, span = sigmoid if sigmoid is not None else (0.0, 1.0)
    out = np.empty(index.size, pred.dtype)
    _sample(pred, index, width, x0, x1, wx, y0, y1, wy, resize, sigmoid is not None, dt(lo),
            dt(span), out)
    if invert:  # numpy's 1 / v (numba's division would raise on a 0)
        with np.errstate(divide="ignore"):
            np.divide(1, out, out=out)
    return out


_NONE = {d: (np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, t))
         for d, t in ((False, np.float32), (True, np.float64))}


@njit
def _select(a, k):
    """Reorder ``a`` so that ``a[k]`` is its ``k``-th smallest value (0-based), everything
    before it no larger; return that value (Hoare partitions, median-of-three pivots)."""
    lo, hi = 0, a.size - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if a[mid] < a[lo]:
            a[mid], a[lo] = a[lo], a[mid]
        if a[hi] < a[lo]:
            a[hi], a[lo] = a[lo], a[hi]
        if a[hi] < a[mid]:
            a[hi], a[mid] = a[mid], a[hi]
        pivot = a[mid]
        i, j = lo, hi
        while i <= j:
            while a[i] < pivot:
                i += 1
            while pivot < a[j]:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return a[k]


@njit
def _median(values, two):
    a = values.copy()
    n = a.size
    upper = _select(a, n // 2)
    if n % 2:
        return upper
    lower = a[0]
    for i in range(1, n // 2):
        if a[i] > lower:
            lower = a[i]
    return (lower + upper) / two


def median(values: np.ndarray):
    """``np.median(values)`` of a 1-D float array without NaN, the same number in the same
    dtype: the middle value, or for an even count the two middle ones added and halved in
    the array's dtype, as numpy's mean of them."""
    return values.dtype.type(_median(values, values.dtype.type(2)))


@njit
def _terms(g, a):
    """One pixel's terms of the metrics: ``|g - a| / g``, ``(g - a)^2 / g``, ``(g - a)^2``
    and ``t = max(g / a, a / g)`` in the dtype of ``g`` and ``a`` (promoted, as numpy
    computes them), and ``e = log(a / g)`` in float64 (one logarithm per pixel:
    ``log a - log g``, ``log10 a - log10 g = e / ln 10``)."""
    diff = g - a
    sq = diff * diff
    return abs(diff) / g, sq / g, sq, max(g / a, a / g), math.log(np.float64(a) / np.float64(g))


@njit
def _scaled_errors(gt, p, scale, lo, hi, zero):
    """The sums over the pixels of :func:`_terms` of ``gt`` and ``d = clamp(p * scale, lo,
    hi)``, both promoted to the dtype of ``zero``: (abs_rel, sq_rel, squares, counts below
    the three thresholds, e, e^2, |e|); the NaN flag ``bad`` when a ``d`` is NaN."""
    s0 = s1 = s2 = s4 = s5 = s6 = 0.0
    n1 = n2 = n3 = 0
    bad = False
    for k in range(p.size):
        d = p[k] * scale
        if d != d:
            bad = True
            break
        if d < lo:
            d = lo
        if d > hi:
            d = hi
        t0, t1, t2, t, e = _terms(gt[k] + zero, d + zero)
        s0 += t0
        s1 += t1
        s2 += t2
        n1 += t < 1.25
        n2 += t < 1.25 ** 2
        n3 += t < 1.25 ** 3
        s4 += e
        s5 += e * e
        s6 += abs(e)
    return (s0, s1, s2, n1, n2, n3, s4, s5, s6), p.size, bad


@njit
def _dense_errors(pred, raw, divisor, box, vlo, vhi, lo, hi, zero):
    """:func:`_scaled_errors` of a whole map in one pass: the ground truth ``raw[r, c] /
    divisor`` (float32), valid where ``vlo < g < vhi`` inside the slice bounds ``box``
    (top, bottom, left, right), the prediction ``pred[r, c]`` clamped to ``[lo, hi]``;
    with the count of valid pixels."""
    s0 = s1 = s2 = s4 = s5 = s6 = 0.0
    n1 = n2 = n3 = n = 0
    bad = False
    for r in range(box[0], box[1]):
        for c in range(box[2], box[3]):
            g = np.float32(raw[r, c]) / divisor
            if not (g > vlo and g < vhi):
                continue
            d = pred[r, c]
            if d != d:
                bad = True
            if d < lo:
                d = lo
            if d > hi:
                d = hi
            t0, t1, t2, t, e = _terms(g + zero, d + zero)
            s0 += t0
            s1 += t1
            s2 += t2
            n1 += t < 1.25
            n2 += t < 1.25 ** 2
            n3 += t < 1.25 ** 3
            s4 += e
            s5 += e * e
            s6 += abs(e)
            n += 1
    return (s0, s1, s2, n1, n2, n3, s4, s5, s6), n, bad


def _means(sums: tuple, n: int, nyu: bool) -> tuple:
    """The metrics from :func:`_scaled_errors`' sums over ``n`` pixels."""
    abs_rel, sq_rel, sq, n1, n2, n3, e, e2, abs_e = (v / n for v in sums)
    errs = (abs_rel, sq_rel, math.sqrt(sq), math.sqrt(e2), n1, n2, n3)
    if not nyu:
        return errs
    var = e2 - e * e
    return errs + (abs_e / math.log(10), math.sqrt(var) * 100 if var >= 0 else math.nan)


def errors(gt: np.ndarray, pred: np.ndarray, nyu: bool = False) -> tuple:
    """The seven metrics (``nyu``: nine) of :func:`~.protocols.depth_errors` over the
    valid pixels' depths ``gt`` and ``pred`` (1-D, same length), as float64: each pixel's
    terms in the two arrays' promoted dtype (:func:`_terms`), the sums in float64."""
    return scaled_errors(gt, pred, None, -np.inf, np.inf, nyu)


def scaled_errors(gt: np.ndarray, p: np.ndarray, scale, low: float, high: float,
                  nyu: bool = False) -> tuple | None:
    """:func:`errors` of ``d = p * scale`` clamped to ``[low, high]``, in one pass, the
    product in numpy's dtype (``scale`` a numpy scalar, or None: ``d = p``); None when a
    ``d`` is NaN."""
    scale = p.dtype.type(1) if scale is None else scale
    dt = np.result_type(p, scale).type
    sums, n, bad = _scaled_errors(gt, p, scale, dt(low), dt(high), np.result_type(gt, dt).type(0))
    return None if bad else _means(sums, n, nyu)


def dense_errors(pred: np.ndarray, raw: np.ndarray, divisor: float, box, valid: tuple,
                 low: float, high: float, nyu: bool = True) -> tuple | None:
    """The metrics of a prediction of the ground truth's size against a whole map kept as
    ``raw`` (depth ``raw / divisor`` in float32), in one pass: the pixels inside ``box``
    (slice bounds top, bottom, left, right) whose depth ``g`` has ``valid[0] < g <
    valid[1]``, the prediction clamped to ``[low, high]``. Returns ``(metrics, count)``
    (metrics None without a valid pixel), None when a prediction is NaN."""
    f32, dt = np.float32, np.result_type(pred, np.float32).type
    sums, n, bad = _dense_errors(pred, raw, f32(divisor), np.asarray(box, np.int64), f32(valid[0]),
                                 f32(valid[1]), dt(low), dt(high), dt(0))
    if bad:
        return None
    return (_means(sums, n, nyu) if n else None), n
