"""Zoom blur and the clipped zoom it shares with snow.

Every zoom layer is a bilinear resample of a centred crop onto a corner-aligned grid
(SciPy ``ndimage.zoom(order=1)``). The sampling positions depend only on the image shape
and the factor, so they are tabulated once per shape (:func:`zoom_table`) and one numba
kernel resamples and accumulates all the layers of a level in a single pass over the rows.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ._jit import njit
from ._ops import truncate_to_uint8
from .registry import register
from .severity import BLEND, Blend, interpolate

# (start, stop, step) of numpy.arange with float steps, exactly as the benchmark writes
# them: the float steps decide the last factor (arange(1, 1.11, .01) ends at 1.11).
LEVELS = (
    (1, 1.11, 0.01),
    (1, 1.16, 0.01),
    (1, 1.21, 0.02),
    (1, 1.26, 0.02),
    (1, 1.31, 0.03),
)


def level_factors(level: int) -> tuple[float, ...]:
    """The zoom factors of integer ``level``: 12, 16, 11, 13 and 11 of them for levels 1..5."""
    return tuple(float(z) for z in np.arange(*LEVELS[level - 1]))


def zoom_axis(n: int, z: float) -> tuple[int, int, int]:
    """Crop and zoom of one axis of length ``n`` by ``z``: ``(start, crop, zoomed)`` with
    ``crop = ceil(n / z)``, ``start = (n - crop) // 2`` and ``zoomed = round(crop * z)``
    (Python's round, half to even, as ``scipy.ndimage.zoom`` sizes its output)."""
    crop = int(math.ceil(n / float(z)))
    return (n - crop) // 2, crop, int(round(crop * z))


def linear_taps(n_in: int, n_out: int, start: int, count: int):
    """Bilinear taps of the first ``count`` outputs of a corner-aligned resample of
    ``n_in`` samples (beginning at index ``start``) onto ``n_out``: output ``i`` samples
    ``y = i * (n_in - 1) / (n_out - 1)``, i.e. ``(1 - w) * a[i0] + w * a[i1]``.

    Returns ``(i0, i1, w)``; indices are absolute (``start`` added), ``w`` is float32.
    """
    i = np.arange(count, dtype=np.float64)
    scale = (n_in - 1) / (n_out - 1) if n_out > 1 else 0.0
    y = i * scale
    lo = np.minimum(np.floor(y).astype(np.int64), n_in - 1)
    w = y - lo
    hi = np.minimum(lo + 1, n_in - 1)
    return lo + start, hi + start, w.astype(np.float32)


def column_runs(c0: np.ndarray) -> np.ndarray:
    """Split outputs ``0..len(c0)-1`` into runs where ``c0[j] - j`` is constant.

    Within a run the left taps of consecutive outputs are consecutive source columns, so the
    column pass reads contiguous memory and vectorises. Returns int64 ``(runs, 3)`` rows
    ``(first, end, c0[first] - first)``.
    """
    n = c0.size
    if n == 0:
        return np.zeros((0, 3), np.int64)
    off = c0 - np.arange(n)
    cuts = np.flatnonzero(np.diff(off)) + 1
    first = np.concatenate(([0], cuts))
    end = np.concatenate((cuts, [n]))
    return np.stack([first, end, off[first]], axis=1).astype(np.int64)


def _tables(h: int, w: int, factors, keep_h: int, keep_w: int, *, crop: bool = True) -> tuple:
    k = len(factors)
    nrows = np.zeros(k, np.int64)
    r0 = np.zeros((k, keep_h), np.int64); r1 = np.zeros((k, keep_h), np.int64)
    wy = np.zeros((k, keep_h), np.float32)
    wx = np.zeros((k, keep_w), np.float32)
    runs = []
    for j, z in enumerate(factors):
        if crop:
            (top, ch, oh), (left, cw, ow) = zoom_axis(h, z), zoom_axis(w, z)
        else:
            (top, ch, oh), (left, cw, ow) = (0, h, int(round(h * z))), (0, w, int(round(w * z)))
        nr, nc = min(oh, keep_h), min(ow, keep_w)
        nrows[j] = nr
        r0[j, :nr], r1[j, :nr], wy[j, :nr] = linear_taps(ch, oh, top, nr)
        c0, _, wx[j, :nc] = linear_taps(cw, ow, left, nc)
        runs.append(column_runs(c0))
    width = max(len(r) for r in runs)
    run_tab = np.zeros((k, width, 3), np.int64)
    nruns = np.zeros(k, np.int64)
    for j, r in enumerate(runs):
        run_tab[j, :len(r)] = r
        nruns[j] = len(r)
    out = (nrows, r0, r1, wy, nruns, run_tab, wx)
    for a in out:
        a.flags.writeable = False
    return out


@lru_cache(maxsize=16)
def zoom_table(h: int, w: int, factors: tuple) -> tuple:
    """Resampling tables of the clipped zoom (the centre crop of :func:`zoom_axis` zoomed as
    :func:`linear_zoom` does) by every factor in ``factors`` for an ``h`` x ``w`` image,
    keeping only the outputs inside the top-left ``h`` x ``w``.

    Returns ``(nrows, r0, r1, wy, nruns, runs, wx)``: per factor the number of rows kept and
    their taps, the column taps as runs (:func:`column_runs`) and the column weights.
    """
    return _tables(h, w, factors, h, w)


@njit
def _accumulate(img, nrows, r0, r1, wy, nruns, runs, wx, acc):
    """``acc[:nrows[k], :W'] += bilinear layer k`` for every factor ``k``, ``W'`` the width of
    ``acc`` (the layer's columns beyond it are not computed).

    ``img`` is float32 H x W x C. Rows are blended first into a one-row buffer (contiguous),
    then columns run by run (contiguous within a run); the right tap of an output is the
    column after its left tap. The clamp at the crop's last column is not needed: there the
    weight is zero (up to rounding) and the buffer is padded.
    """
    h, w, nch = img.shape
    wo = acc.shape[1]
    row = np.zeros((w + 1) * nch, np.float32)
    flat = img.reshape(h, w * nch)
    out = acc.reshape(acc.shape[0], wo * nch)
    u = np.empty(wo * nch, np.float32)
    for k in range(nrows.shape[0]):
        for j in range(wo):
            for c in range(nch):
                u[j * nch + c] = wx[k, j]
        for i in range(nrows[k]):
            a = flat[r0[k, i]]
            b = flat[r1[k, i]]
            t = wy[k, i]
            for q in range(w * nch):
                row[q] = a[q] + t * (b[q] - a[q])
            o = out[i]
            for m in range(nruns[k]):
                # Unsigned indices: numba then skips its negative-index wraparound, which
                # would otherwise keep LLVM from vectorising the loop.
                d0 = np.uint64(runs[k, m, 0] * nch)
                s0 = np.uint64((runs[k, m, 0] + runs[k, m, 2]) * nch)
                s1 = s0 + np.uint64(nch)
                for q in range(np.uint64((runs[k, m, 1] - runs[k, m, 0]) * nch)):
                    v = row[s0 + q]
                    o[d0 + q] += v + u[d0 + q] * (row[s1 + q] - v)
    return acc


def linear_zoom(img: np.ndarray, z: float) -> np.ndarray:
    """``scipy.ndimage.zoom(img, (z, z[, 1]), order=1)`` in float32: the whole ``h`` x ``w``
    array resampled to ``round(h * z)`` x ``round(w * z)`` on the corner-aligned grid.
    ``img`` is H x W or H x W x C."""
    src = np.ascontiguousarray(img, dtype=np.float32)
    flat = src.ndim == 2
    if flat:
        src = src[..., None]
    h, w = src.shape[:2]
    oh, ow = int(round(h * z)), int(round(w * z))
    tables = _tables(h, w, (z,), oh, ow, crop=False)
    out = _accumulate(src, *tables, np.zeros((oh, ow, src.shape[2]), np.float32))
    return out[..., 0] if flat else out


@register(("start", "stop", "step"), LEVELS, rules=(BLEND,) * 3, deterministic=True)
def zoom_blur(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Average of the image and its clipped zooms by every factor of the level
    (:func:`level_factors`):
    ``clip01((f + sum_z clipped_zoom(f, z)[:H, :W]) / (n + 1))`` on ``f = x / 255`` in
    float32, ``n`` the number of factors; a layer smaller than H x W adds only to its
    top-left part. Truncated to uint8.

    Size rule (as imagecorruptions-imaug 1.1.5): the factors are relative, so the blur's
    streaks grow with the image; each layer is the centre crop of ``ceil(H / z)`` x
    ``ceil(W / z)`` zoomed to ``round(ch * z)`` x ``round(cw * z)``, which can differ from
    H x W by a pixel either way: extra rows and columns are dropped, missing ones add
    nothing.

    Between integer levels (a factor set has no value in between): the blend
    ``(1 - t) * A_i + t * A_{i+1}`` of the two neighbouring levels' averages (float32,
    before the clip and truncation), ``t`` the fractional part of the level."""
    f = x.astype(np.float32) * np.float32(1 / 255)
    entry = interpolate(LEVELS, level, (BLEND,))
    if not isinstance(entry, Blend):
        return truncate_to_uint8(_average(f, level))
    i = int(level)
    t = np.float32(entry.t)
    mixed = _average(f, i)
    mixed *= np.float32(1) - t
    mixed += t * _average(f, i + 1)
    return truncate_to_uint8(mixed)


def _average(f: np.ndarray, level: int) -> np.ndarray:
    """``(f + sum_z clipped_zoom(f, z)[:H, :W]) / (n + 1)`` over the factors of integer
    ``level``, float32, unclipped."""
    h, w = f.shape[:2]
    factors = level_factors(level)
    acc = _accumulate(f, *zoom_table(h, w, factors), f.copy())
    acc /= np.float32(len(factors) + 1)
    return acc
