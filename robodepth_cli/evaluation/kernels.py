"""The evaluation's inner loops, compiled (numba): a prediction sampled only at the valid
ground-truth pixels, and the metrics of a map in one pass, with no full-size temporaries.

Every per-pixel step is done in the dtype numpy's expression of the reference code would
use (float32 for float32 inputs: the prediction's dtype, promoted with the ground truth's
and the scale's as numpy promotes), so the depths compared are the same numbers to the
last bit; only the sums differ: each metric accumulates in float64 in pixel order
(numpy sums float32 pairwise in float32), and the logarithms are float64 (:func:`_log`,
within a few units in the last place of the C library's). The same code runs on every CPU:
no fast-math, multiply-adds only where written (``fma``), sums in the order written.

:func:`sample_linear` is ``cv2.resize(pred, (W, H), interpolation=cv2.INTER_LINEAR)`` at
the valid pixels only. The opencv-python wheel hands a float resize to IPP; its rules,
found by comparing outputs bit for bit (tests/evaluation/test_evaluate_paths.py checks
them on float32 maps; float64 ones agree to ~1e-12, OpenCV rounding some small maps'
weights on a path of its own):

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

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from ..corruptions.jit import div, fma, njit


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
def _sample(pred, index, width, x0, x1, wx, y0, y1, wy, resize, sigmoid, lo, span, invert, one, out):
    """``out[k]`` = the prediction at flat ground-truth pixel ``index[k]`` (``width`` per
    row): interpolated from its four inputs (``resize``) or read; each input first through
    ``lo + span * v`` (``sigmoid``); then ``one / v`` (``invert``)."""
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
        out[k] = div(one, v) if invert else v
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
    return _sample(pred, index, width, x0, x1, wx, y0, y1, wy, resize, sigmoid is not None,
                   dt(lo), dt(span), invert, dt(1), out)


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


_SQRT2 = math.sqrt(2.0)
_LN2 = math.log(2.0)
_C = tuple(1.0 / n for n in (3, 5, 7, 9, 11, 13, 15, 17, 19, 21))


@intrinsic
def _bits(typingctx, x):
    """The bits of a float64, as an int64."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, i):
    """The float64 of the bits ``i``."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


@njit
def _log(x):
    """``log x`` of a positive normal float64 to within a few units in the last place, in
    plain arithmetic that vectorises (the C library's ``log`` is a call per value):
    ``x = m 2^k``, ``m`` in ``[sqrt(1/2), sqrt(2))``, ``log m = 2 atanh s`` with ``s = (m -
    1) / (m + 1)``, the series to ``s^21`` (``|s| < 0.172``: the next term is < 1e-17)."""
    i = _bits(x)
    k = np.float64(((i >> 52) & 0x7FF) - 1023)
    m = _from_bits((i & 0xFFFFFFFFFFFFF) | 0x3FF0000000000000)
    big = m > _SQRT2
    m = m * 0.5 if big else m
    k = k + 1.0 if big else k
    s = div(m - 1.0, m + 1.0)
    z = s * s
    c = _C
    q = ((((((((c[9] * z + c[8]) * z + c[7]) * z + c[6]) * z + c[5]) * z + c[4]) * z + c[3]) * z
          + c[2]) * z + c[1]) * z + c[0]
    return k * _LN2 + 2.0 * s * (q * z + 1.0)


_BLOCK = 256  # pixels whose logarithms are taken together, in one vectorised loop


@njit
def _scaled_errors(gt, p, scale, lo, hi, zero, work, ratio):
    """The sums over the pixels of ``g = gt`` and ``d = clamp(p * scale, lo, hi)``, both in
    the dtype of ``zero`` (numpy's arithmetic): ``|g - d| / g``, ``(g - d)^2 / g``, ``(g -
    d)^2``, the counts of ``max(g / d, d / g)`` under the three thresholds, then of ``e =
    log(d / g)`` in float64 (``log d - log g``; ``log10 d - log10 g`` is ``e / ln 10``),
    ``e``, ``e^2`` and ``|e|``, each summed in pixel order; and whether a ``d`` is NaN.

    A block of pixels at a time: their terms into the rows of ``work`` (4 x block) and
    ``ratio`` (block, float64) in loops that vectorise, then summed one by one."""
    s0 = s1 = s2 = s6 = s7 = s8 = 0.0
    n1 = n2 = n3 = 0  # integer counts: off the floating-point adders
    block = ratio.size
    for start in range(0, p.size, block):
        m = min(block, p.size - start)
        nan = 0
        for j in range(m):
            d = p[start + j] * scale
            nan += d != d
            d = lo if d < lo else d
            d = hi if d > hi else d
            g, d = gt[start + j] + zero, d + zero
            diff = g - d
            sq = diff * diff
            work[0, j] = div(abs(diff), g)
            work[1, j] = div(sq, g)
            work[2, j] = sq
            work[3, j] = max(div(g, d), div(d, g))
            ratio[j] = _log(div(np.float64(d), np.float64(g)))
        if nan:
            return (s0, s1, s2, float(n1), float(n2), float(n3), s6, s7, s8), True
        for j in range(m):
            s0 += work[0, j]
            s1 += work[1, j]
            s2 += work[2, j]
            t = work[3, j]
            n1 += t < 1.25
            n2 += t < 1.25 ** 2
            n3 += t < 1.25 ** 3
            e = ratio[j]
            s6 += e
            s7 += e * e
            s8 += abs(e)
    return (s0, s1, s2, float(n1), float(n2), float(n3), s6, s7, s8), False


@njit
def _dense_errors(pred, raw, divisor, box, vlo, vhi, lo, hi, one, zero, gbuf, pbuf, work, ratio):
    """:func:`_scaled_errors` of a whole map in one pass, with no per-pixel array: the
    ground truth ``raw[r, c] / divisor`` (float32), valid where ``vlo < g < vhi`` inside
    the slice bounds ``box`` (top, bottom, left, right), and the prediction ``pred[r, c]``
    clamped to ``[lo, hi]``, a row's valid pixels at a time (copied into the row buffers
    ``gbuf``, ``pbuf``). Returns the sums, the count of valid pixels and whether a
    prediction is NaN."""
    total = np.zeros(9)
    n = 0
    for r in range(box[0], box[1]):
        k = 0
        for c in range(box[2], box[3]):
            g = div(np.float32(raw[r, c]), divisor)
            if g > vlo and g < vhi:
                gbuf[k] = g
                pbuf[k] = pred[r, c]
                k += 1
        if not k:
            continue
        sums, bad = _scaled_errors(gbuf[:k], pbuf[:k], one, lo, hi, zero, work, ratio)
        if bad:
            return total, n, True
        for i in range(9):
            total[i] += sums[i]
        n += k
    return total, n, False


def _buffers(dtype) -> tuple[np.ndarray, np.ndarray]:
    """The work rows of :func:`_scaled_errors` for pixels of ``dtype``."""
    return np.empty((4, _BLOCK), dtype), np.empty(_BLOCK)


def _means(sums: tuple, n: int, nyu: bool) -> tuple:
    """The metrics from :func:`_scaled_errors`' sums over ``n`` pixels."""
    abs_rel, sq_rel, sq, n1, n2, n3, e, e2, abs_e = (float(v) / n for v in sums)
    errs = (abs_rel, sq_rel, math.sqrt(sq), math.sqrt(e2), n1, n2, n3)
    if not nyu:
        return errs
    var = e2 - e * e
    return errs + (abs_e / math.log(10), math.sqrt(var) * 100 if var >= 0 else math.nan)


def errors(gt: np.ndarray, pred: np.ndarray, nyu: bool = False) -> tuple:
    """The seven metrics (``nyu``: nine) of :func:`~.protocols.depth_errors` over the
    valid pixels' depths ``gt`` and ``pred`` (1-D, same length), as float64: each pixel's
    terms in the two arrays' promoted dtype (:func:`_scaled_errors`), the sums in float64."""
    return scaled_errors(gt, pred, None, -np.inf, np.inf, nyu)


def scaled_errors(gt: np.ndarray, p: np.ndarray, scale, low: float, high: float,
                  nyu: bool = False) -> tuple | None:
    """:func:`errors` of ``d = p * scale`` clamped to ``[low, high]``, in one pass, the
    product in numpy's dtype (``scale`` a numpy scalar, or None: ``d = p``); None when a
    ``d`` is NaN."""
    scale = p.dtype.type(1) if scale is None else scale
    dt = np.result_type(p, scale).type
    t = np.result_type(gt, dt)
    sums, bad = _scaled_errors(gt, p, scale, dt(low), dt(high), t.type(0), *_buffers(t))
    return None if bad else _means(sums, p.size, nyu)


def dense_errors(pred: np.ndarray, raw: np.ndarray, divisor: float, box, valid: tuple,
                 low: float, high: float, nyu: bool = True) -> tuple | None:
    """The metrics of a prediction of the ground truth's size against a whole map kept as
    ``raw`` (depth ``raw / divisor`` in float32), in one pass: the pixels inside ``box``
    (slice bounds top, bottom, left, right) whose depth ``g`` has ``valid[0] < g <
    valid[1]``, the prediction clamped to ``[low, high]``. Returns ``(metrics, count)``
    (metrics None without a valid pixel), None when a prediction is NaN."""
    f32, dt = np.float32, pred.dtype.type
    t = np.result_type(pred, f32)
    width = max(box[3] - box[2], 0)
    sums, n, bad = _dense_errors(pred, raw, f32(divisor), np.asarray(box, np.int64), f32(valid[0]),
                                 f32(valid[1]), dt(low), dt(high), dt(1), t.type(0), np.empty(width, f32),
                                 np.empty(width, pred.dtype), *_buffers(t))
    if bad:
        return None
    return (_means(sums, n, nyu) if n else None), n
