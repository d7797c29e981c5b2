"""The evaluation's inner loops, compiled (numba): a prediction sampled only at the valid
ground-truth pixels, and the metrics of a map in one pass, with no full-size temporaries;
a block of a variant's maps judged in one call (:func:`_judge_sparse`, :func:`_judge_dense`).

Every per-pixel step is done in the dtype numpy's expression of the reference code would
use (float32 for float32 inputs: the prediction's dtype, promoted with the ground truth's
and the scale's as numpy promotes), so the depths compared are the same numbers to the
last bit; only the sums differ: each metric accumulates in float64, in columns (pixel
``j`` of every block of 256, or column ``j`` of every row, added one by one), the columns
then summed in order (numpy sums float32 pairwise in float32), and the logarithms are
float64 (:func:`_log`, within a few units in the last place of the C library's). The same
code runs on every CPU: no fast-math, multiply-adds only where written (``fma``), sums in
the order written, whatever width the loops are vectorised to.

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
from numba.np.numpy_support import carray
from numba.core import cgutils, types
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
    lo, hi = (np.clip(j, 0, n_in - 1).astype(np.uint32) for j in (i, i + 1))
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
def _bilinear(p0, p1, index, start, x0, x1, wx, w, k, end, sigmoid, lo, span, out):
    """``out[k:end]``: the pixels ``index[k:end]`` of one output row (flat indices from
    ``start``) interpolated between the input rows ``p0`` and ``p1`` (weight ``w``).
    Unsigned column numbers: numba checks a signed index for a negative value."""
    for j in range(k, end):
        c = np.uint32(index[j] - start)
        c0, c1 = x0[c], x1[c]
        a, b, e, f = p0[c0], p0[c1], p1[c0], p1[c1]
        if sigmoid:
            a, b, e, f = lo + span * a, lo + span * b, lo + span * e, lo + span * f
        h0 = fma(b - a, wx[c], a)
        h1 = fma(f - e, wx[c], e)
        out[j] = fma(h1 - h0, w, h0)


@njit
def _sample(pred, index, bounds, width, x0, x1, wx, y0, y1, wy, resize, sigmoid, lo, span, invert, one,
            out):
    """``out[k]`` = the prediction at flat ground-truth pixel ``index[k]`` (``width`` per
    row; sorted): interpolated from its four inputs (``resize``) or read; each input first
    through ``lo + span * v`` (``sigmoid``); then ``one / v`` (``invert``). Row ``r``'s
    pixels are ``index[bounds[r]:bounds[r + 1]]`` (:func:`row_bounds`), taken a row at a time."""
    for row in range(bounds.size - 1):
        k, end = bounds[row], bounds[row + 1]
        if k == end:
            continue
        start = row * width
        if resize:
            p0, p1 = pred[y0[row]], pred[y1[row]]
            if sigmoid:  # two loops: the test out of the inner one
                _bilinear(p0, p1, index, start, x0, x1, wx, wy[row], k, end, True, lo, span, out)
            else:
                _bilinear(p0, p1, index, start, x0, x1, wx, wy[row], k, end, False, lo, span, out)
        else:
            p0 = pred[row]
            for j in range(k, end):
                v = p0[np.uint32(index[j] - start)]
                out[j] = lo + span * v if sigmoid else v
    if invert:  # apart: the divisions vectorise, the gathers above do not
        for j in range(index.size):
            out[j] = div(one, out[j])
    return out


def row_bounds(index: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Where each row's pixels begin in the sorted flat indices ``index`` of a map of
    ``shape``, and where the last one's end (``H + 1`` values, int64)."""
    height, width = shape
    return np.searchsorted(index, np.arange(height + 1, dtype=np.int64) * width).astype(np.int64)


def sample_linear(pred: np.ndarray, gt_shape: tuple[int, int], index: np.ndarray, *,
                  sigmoid: tuple[float, float] | None = None, invert: bool = False) -> np.ndarray:
    """``cv2.resize(pred, (W, H), interpolation=cv2.INTER_LINEAR).reshape(-1)[index]`` for a
    float32 or float64 map and ground truth of shape ``gt_shape = (H, W)``, computing only
    the pixels ``index`` (flat, row-major; in any order), bit for bit (the module's rules).

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
    order = None
    if index.size > 1 and (np.diff(index) < 0).any():
        order = np.argsort(index, kind="stable")
        index = index[order]
    out = np.empty(index.size, pred.dtype)
    _sample(pred, index, row_bounds(index, gt_shape), width, x0, x1, wx, y0, y1, wy, resize,
            sigmoid is not None, dt(lo), dt(span), invert, dt(1), out)
    if order is None:
        return out
    back = np.empty_like(out)
    back[order] = out
    return back


_NONE = {d: (np.zeros(1, np.uint32), np.zeros(1, np.uint32), np.zeros(1, t))
         for d, t in ((False, np.float32), (True, np.float64))}


@njit
def _select(a, b, k):
    """The ``k``-th smallest value (0-based) of ``a`` and the ``k - 1``-th (meaningless
    for ``k = 0``); ``a`` and ``b`` (as large) are scratch. Each step splits the values
    around a pivot (the median of three) into ``b``, those below from the front and
    those above from the back, in a loop with no branch (a branch per value would be
    mispredicted half the time), and goes on in the part that holds rank ``k``, the two
    arrays trading places. Rank ``k - 1``: the largest value left below, or the last
    pivot passed over on the way up."""
    n = a.size
    lower = a[0]
    while n > 16:
        x, y, z = a[0], a[n // 2], a[n - 1]
        pivot = max(min(x, y), min(max(x, y), z))
        below = 0
        above = 0
        for j in range(n):
            x = a[j]
            b[below] = x
            below += x < pivot
            b[n - 1 - above] = x
            above += x > pivot
        if k < below:
            a, b, n = b[:below], a, below
        elif k >= n - above:
            k -= n - above
            a, b, n, lower = b[n - above:n], a, above, pivot  # the pivot's copies: below
        else:
            if k > below:
                lower = pivot
            elif below:
                lower = b[0]
                for j in range(1, below):
                    lower = max(lower, b[j])
            return pivot, lower
    for i in range(1, n):  # a few values: insertion sort
        x = a[i]
        j = i - 1
        while j >= 0 and a[j] > x:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = x
    return a[k], (a[k - 1] if k else lower)


@njit
def _middle(a, spare, r, even, two):
    """The order statistic ``r`` of ``a`` (scratch, as ``spare``), or with ``even`` its
    mean with statistic ``r - 1``, added and halved in the dtype, as numpy's mean of
    the two."""
    upper, lower = _select(a, spare, r)
    return (lower + upper) / two if even else upper


@intrinsic
def _keep_between(typingctx, src, dst, lo, hi):
    """Of the 64 bytes of values at address ``src`` (16 float32 or 8 float64), those in
    ``[lo, hi]`` stored one after another at address ``dst``, in order (LLVM's
    ``masked.compressstore``: one instruction with AVX-512, lane by lane elsewhere); returns
    their count plus ``2^32`` times the count of those below ``lo``."""
    if not isinstance(lo, types.Float) or lo != hi:
        return None
    bits = lo.bitwidth
    width = 512 // bits

    def codegen(context, builder, signature, args):
        address, out, low, high = args
        ft = low.type
        vt, mt, it = ir.VectorType(ft, width), ir.VectorType(ir.IntType(1), width), ir.IntType(width)
        v = builder.load(builder.inttoptr(address, vt.as_pointer()), align=bits // 8)
        undef, zeros = ir.Constant(vt, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), width), [0] * width)

        def splat(x):
            return builder.shuffle_vector(builder.insert_element(undef, x, ir.Constant(ir.IntType(32), 0)), undef,
                                          zeros)

        keep = builder.and_(builder.fcmp_ordered(">=", v, splat(low)), builder.fcmp_ordered("<=", v, splat(high)))
        below = builder.fcmp_ordered("<", v, splat(low))
        store = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [vt, ft.as_pointer(), mt]),
                                               f"llvm.masked.compressstore.v{width}f{bits}")
        builder.call(store, [v, builder.inttoptr(out, ft.as_pointer()), keep])
        count = cgutils.get_or_insert_function(builder.module, ir.FunctionType(it, [it]), f"llvm.ctpop.i{width}")
        i64 = ir.IntType(64)
        kept, under = (builder.zext(builder.call(count, [builder.bitcast(m, it)]), i64) for m in (keep, below))
        return builder.or_(kept, builder.shl(under, ir.Constant(i64, 32)))

    return types.int64(types.int64, types.int64, lo, hi), codegen


@njit
def _between(v, work, lo, hi):
    """``(kept, below)``: the values of ``v`` (contiguous) in ``[lo, hi]`` copied to the
    front of ``work`` in order, their count, and the count of those below ``lo``; 64 bytes
    at a time (:func:`_keep_between`: a branch-free store at a moving index otherwise
    costs a loop of several cycles a value), the last few one by one."""
    n = v.size
    size = v.itemsize
    step = 64 // size
    src, dst = np.int64(v.ctypes.data), np.int64(work.ctypes.data)
    kept = below = 0
    j = 0
    while j + step <= n:
        r = _keep_between(src + j * size, dst + kept * size, lo, hi)
        kept += r & 0xFFFFFFFF
        below += r >> 32
        j += step
    for i in range(j, n):
        x = v[i]
        below += x < lo
        work[kept] = x
        kept += (x >= lo) & (x <= hi)
    return kept, below


_SAMPLE = 512  # values whose order statistics bound the median's neighbourhood
_SPREAD = 40  # sample ranks either side of the median's: 3.5 standard deviations


@njit
def _median(v, work, spare, two):
    """``np.median(v)`` (``v`` unchanged; ``work`` and ``spare``: as large, scratch). A
    large ``v`` is first cut to the values between two order statistics of a strided
    sample, which hold its middle unless the data are unlucky (then all of it is
    selected): one pass with no branch, then the selection on a tenth of the values."""
    n = v.size
    k = n // 2
    even = n % 2 == 0
    if n >= 8 * _SAMPLE:
        step = n // _SAMPLE
        q = (k * _SAMPLE) // n
        for j in range(_SAMPLE):
            work[j] = v[j * step]
        lo = _select(work[:_SAMPLE], spare[:_SAMPLE], max(q - _SPREAD, 0))[0]
        for j in range(_SAMPLE):
            work[j] = v[j * step]
        hi = _select(work[:_SAMPLE], spare[:_SAMPLE], min(q + _SPREAD, _SAMPLE - 1))[0]
        kept, below = _between(v, work, lo, hi)
        if below <= k - even and k < below + kept:
            return _middle(work[:kept], spare, k - below, even, two)
    work[:n] = v
    return _middle(work[:n], spare, k, even, two)


def median(values: np.ndarray):
    """``np.median(values)`` of a 1-D float array without NaN, the same number in the same
    dtype: the middle value, or for an even count the two middle ones added and halved in
    the array's dtype, as numpy's mean of them."""
    values = np.ascontiguousarray(values)  # _between reads it 64 bytes at a time
    return values.dtype.type(_median(values, np.empty_like(values), np.empty_like(values),
                                     values.dtype.type(2)))


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
    # the exponent as a float64 by its bits (2^52 + e, less 2^52 + 1023): AVX2 has no
    # vector conversion of int64 to float64, and a scalar one per value costs the loop
    k = _from_bits(((i >> 52) & 0x7FF) | 0x4330000000000000) - (4503599627370496.0 + 1023.0)
    m = _from_bits((i & 0xFFFFFFFFFFFFF) | 0x3FF0000000000000)
    big = m > _SQRT2
    m = m * 0.5 if big else m
    k = k + 1.0 if big else k
    s = div(m - 1.0, m + 1.0)
    z = s * s
    c = _C
    # Horner's steps as multiply-adds: half the operations of a product and a sum each
    q = fma(fma(fma(fma(fma(fma(fma(fma(fma(c[9], z, c[8]), z, c[7]), z, c[6]), z, c[5]), z, c[4]), z, c[3]),
                    z, c[2]), z, c[1]), z, c[0])
    return fma(k, _LN2, 2.0 * s * fma(q, z, 1.0))


_BLOCK = 256  # pixels a vectorised loop takes together; pixel j of each goes to column j


@njit
def _pixel(g, d):
    """One pixel's terms: ``|g - d| / g``, ``(g - d)^2 / g``, ``(g - d)^2``, ``max(g / d,
    d / g)`` in the dtype of ``g`` and ``d``, and ``log(d / g)`` in float64."""
    diff = g - d
    sq = diff * diff
    return (div(abs(diff), g), div(sq, g), sq, max(div(g, d), div(d, g)),
            _log(div(np.float64(d), np.float64(g))))


@njit
def _terms(gt, p, scale, lo, hi, zero, acc, nyu):
    """:func:`_scaled_errors`' terms of the pixels of ``gt`` and ``p`` (a block), pixel
    ``j``'s added to column ``j`` of ``acc``'s rows (:func:`_sum_columns`), in a loop that
    vectorises; returns the count of NaN ``d`` and those of ``t`` under the thresholds
    (integers: in any order)."""
    a0, a1, a2, a3, a4, a5 = acc[0], acc[1], acc[2], acc[3], acc[4], acc[5]
    nan = n1 = n2 = n3 = 0
    for j in range(p.size):
        d = p[j] * scale
        nan += d != d
        d = lo if d < lo else d
        d = hi if d > hi else d
        x, y, z, t, e = _pixel(gt[j] + zero, d + zero)
        a0[j] += x
        a1[j] += y
        a2[j] += z
        a4[j] += e * e
        if nyu:  # the means of e and |e| are nyu's only
            a3[j] += e
            a5[j] += abs(e)
        n1 += t < 1.25
        n2 += t < 1.25 ** 2
        n3 += t < 1.25 ** 3
    return nan, n1, n2, n3


@njit
def _sum_columns(acc):
    """Each row of ``acc`` summed, column after column: the sums' last step. A column holds
    its pixels' terms added one by one as they came (pixel ``j`` of every block, or column
    ``j`` of every row): the same order on any CPU, whatever width a loop is vectorised to,
    and the adds of different columns need not wait for each other."""
    s = np.zeros(acc.shape[0])
    for k in range(acc.shape[0]):
        t = 0.0
        for j in range(acc.shape[1]):
            t += acc[k, j]
        s[k] = t
    return s[0], s[1], s[2], s[3], s[4], s[5]


@njit
def _scaled_errors(gt, p, scale, lo, hi, zero, nyu):
    """The sums over the pixels of ``g = gt`` and ``d = clamp(p * scale, lo, hi)``, both in
    the dtype of ``zero`` (numpy's arithmetic): ``|g - d| / g``, ``(g - d)^2 / g``, ``(g -
    d)^2``, the counts of ``max(g / d, d / g)`` under the three thresholds, then of ``e =
    log(d / g)`` in float64 (``log d - log g``; ``log10 d - log10 g`` is ``e / ln 10``),
    ``e`` and ``|e|`` (``nyu`` only: 0 otherwise) and ``e^2``; and whether a ``d`` is NaN.

    A block of pixels at a time (:func:`_terms`): pixel ``j`` of each block is added to
    column ``j`` of float64 accumulators, which are summed at the end (:func:`_sum_columns`)."""
    acc = np.zeros((6, min(_BLOCK, max(p.size, 1))))
    n1 = n2 = n3 = nan = 0
    for start in range(0, p.size, _BLOCK):
        m = min(_BLOCK, p.size - start)
        nan, c1, c2, c3 = _terms(gt[start:start + m], p[start:start + m], scale, lo, hi, zero, acc, nyu)
        n1, n2, n3 = n1 + c1, n2 + c2, n3 + c3
        if nan:
            break
    s0, s1, s2, s6, s7, s8 = _sum_columns(acc)
    return (s0, s1, s2, float(n1), float(n2), float(n3), s6, s7, s8), nan > 0


@njit
def _dense_terms(raw, pred, divisor, vlo, vhi, lo, hi, one, zero, acc, nyu):
    """:func:`_terms` of a row of a whole map (its pixel ``j`` into column ``j``): the
    ground truth ``raw / divisor`` (float32), valid where ``vlo < g < vhi``; an invalid
    pixel's terms are 0 (``g = d = 1``, ``one`` in the prediction's dtype: a sum is the same
    number with them added), so that the loop has no branch. Returns the counts of NaN,
    valid pixels and ``t`` under the thresholds."""
    a0, a1, a2, a3, a4, a5 = acc[0], acc[1], acc[2], acc[3], acc[4], acc[5]
    nan = n = n1 = n2 = n3 = 0
    for j in range(pred.size):
        g = div(np.float32(raw[j]), divisor)
        valid = (g > vlo) & (g < vhi)
        d = pred[j]
        nan += valid & (d != d)
        d = lo if d < lo else d
        d = hi if d > hi else d
        g, d = (g if valid else np.float32(1)) + zero, (d if valid else one) + zero
        x, y, z, t, e = _pixel(g, d)
        # as in _terms, written out: a function of both took the loops' vectorising away
        # (3.9 ms a NYU map against 0.44)
        a0[j] += x
        a1[j] += y
        a2[j] += z
        a4[j] += e * e
        if nyu:
            a3[j] += e
            a5[j] += abs(e)
        n += valid
        n1 += valid & (t < 1.25)
        n2 += valid & (t < 1.25 ** 2)
        n3 += valid & (t < 1.25 ** 3)
    return nan, n, n1, n2, n3


@njit
def _dense_errors(pred, raw, divisor, box, vlo, vhi, lo, hi, one, zero, nyu):
    """:func:`_scaled_errors` of a whole map in one pass, with no per-pixel array: the
    ground truth ``raw[r, c] / divisor`` (float32), valid where ``vlo < g < vhi`` inside
    the slice bounds ``box`` (top, bottom, left, right), and the prediction ``pred[r, c]``
    clamped to ``[lo, hi]`` (:func:`_dense_terms`), a row at a time: column ``c`` of the
    accumulators takes column ``c`` of each row, and they are summed at the end. Returns
    the sums, the count of valid pixels and whether a prediction is NaN."""
    total = np.zeros(9)
    left, right = box[2], box[3]
    acc = np.zeros((6, max(right - left, 1)))
    n = n1 = n2 = n3 = 0
    for r in range(box[0], box[1]):
        nan, v, c1, c2, c3 = _dense_terms(raw[r, left:right], pred[r, left:right], divisor, vlo, vhi, lo, hi,
                                          one, zero, acc, nyu)
        if nan:
            return total, n, True
        n, n1, n2, n3 = n + v, n1 + c1, n2 + c2, n3 + c3
    s0, s1, s2, s6, s7, s8 = _sum_columns(acc)
    for i, x in enumerate((s0, s1, s2, float(n1), float(n2), float(n3), s6, s7, s8)):
        total[i] = x
    return total, n, False


_LN10 = math.log(10)


@njit
def _metrics(sums, n, nyu, out):
    """The metrics from :func:`_scaled_errors`' sums over ``n`` pixels into ``out`` (7, or
    ``nyu`` 9); whether they are all finite."""
    m = np.float64(n)
    e, e2 = div(sums[6], m), div(sums[7], m)
    out[0], out[1], out[2] = div(sums[0], m), div(sums[1], m), math.sqrt(div(sums[2], m))
    out[3], out[4], out[5], out[6] = math.sqrt(e2), div(sums[3], m), div(sums[4], m), div(sums[5], m)
    k = 7
    if nyu:
        var = e2 - e * e
        out[7] = div(div(sums[8], m), _LN10)
        out[8] = math.sqrt(var) * 100 if var >= 0 else np.nan
        k = 9
    finite = True
    for i in range(k):
        finite &= abs(out[i]) < np.inf
    return finite


def _means(sums, n: int, nyu: bool) -> tuple:
    """The metrics from :func:`_scaled_errors`' sums over ``n`` pixels (:func:`_metrics`)."""
    out = np.empty(9)
    _metrics(sums, n, nyu, out)
    return tuple(float(v) for v in out[:9 if nyu else 7])


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
    sums, bad = _scaled_errors(gt, p, scale, dt(low), dt(high), t.type(0), nyu)
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
    sums, n, bad = _dense_errors(pred, raw, f32(divisor), np.asarray(box, np.int64), f32(valid[0]),
                                 f32(valid[1]), dt(low), dt(high), dt(1), t.type(0), nyu)
    if bad:
        return None
    return (_means(sums, n, nyu) if n else None), n


# --------------------------------------------------------------------------- a variant's maps

@intrinsic
def _pointer(typingctx, address, like):
    """``address`` (an int64) as a pointer to values of ``like``'s type. The ground truth's
    per-image arrays reach a batch call as addresses: numba's typed lists compile anew in
    every process (seconds, uncached), and one concatenated copy would hold it twice."""
    ptr = types.CPointer(like)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(ptr))

    return ptr(types.int64, like), codegen


@njit
def _usable(m, cap, positive):
    """Whether :func:`~.image.check_values` passes the map ``m``: every value in ``[0,
    cap]`` (NaN never is) and, with ``positive``, one above 0. Flags, not the minimum and
    maximum: the flags' reductions vectorise, and a refused map is checked again for its
    message."""
    bad = False
    some = False
    for r in range(m.shape[0]):
        for c in range(m.shape[1]):
            v = m[r, c]
            bad |= not (v >= 0 and v <= cap)
            some |= v > 0
    return not bad and (some or not positive)


@njit
def _judge_sparse(pred, first, last, index_at, gt_at, bounds_at, rows, counts, gmed, zi, zg, width, x0, x1, wx, y0, y1,
                  wy, resize, sigmoid, lo, span, invert, one, two, by_median, factor, zs, low, high, zt,
                  cap, positive, nyu, vbuf, sbuf, spare, out, ratios, ok):
    """Maps ``first..last-1`` of ``pred`` (N x h x w) against ground truth kept as valid
    pixels (image ``i``: ``counts[i]`` flat indices at address ``index_at[i]``, their
    depths at ``gt_at[i]``, its ``rows + 1`` :func:`row_bounds` at ``bounds_at[i]``; 0
    pixels: not here): the value check, the sampling (:func:`_sample`), the scale (``by_median``: ``gmed[i] / median``, in the dtype of
    ``zs``; else ``factor``), the clamp to ``[low, high]`` and the metrics into ``out[i]``,
    the scale into ``ratios[i]`` (these three indexed from ``first``). ``ok[i]``: done;
    where not, the map is judged again one at a time, which says why it is refused."""
    for i in range(first, last):
        n = counts[i]
        if n == 0 or not _usable(pred[i], cap, positive):
            continue
        index = carray(_pointer(index_at[i], zi), n)
        gt = carray(_pointer(gt_at[i], zg), n)
        bounds = carray(_pointer(bounds_at[i], np.int64(0)), rows + 1)
        v = _sample(pred[i], index, bounds, width, x0, x1, wx, y0, y1, wy, resize, sigmoid, lo, span,
                    invert, one, vbuf[:n])
        s = factor
        if by_median:
            s = div(gmed[i] + zs, _median(v, sbuf, spare, two) + zs)
            if not (s > 0 and s < np.inf):
                continue
        sums, bad = _scaled_errors(gt, v, s, low, high, zt, nyu)
        if not bad and _metrics(sums, n, nyu, out[i - first]):
            ratios[i - first] = s
            ok[i - first] = True


@njit
def _judge_dense(pred, first, last, raw_at, zr, divisors, box, vlo, vhi, lo, hi, one, zero, cap,
                 positive, nyu, out, ok):
    """Maps ``first..last-1`` of ``pred`` against ground truth kept whole (image ``i``: a
    map of ``pred``'s size at address ``raw_at[i]``, depth ``raw / divisors[i]``; address
    0: not here): the value check and :func:`_dense_errors`, the metrics into ``out[i]``;
    ``ok[i]`` as :func:`_judge_sparse`'s."""
    shape = (pred.shape[1], pred.shape[2])
    for i in range(first, last):
        if raw_at[i] == 0 or not _usable(pred[i], cap, positive):
            continue
        raw = carray(_pointer(raw_at[i], zr), shape)
        sums, n, bad = _dense_errors(pred[i], raw, divisors[i], box, vlo, vhi, lo, hi, one, zero, nyu)
        ok[i - first] = not bad and n > 0 and _metrics(sums, n, nyu, out[i - first])
