"""Filters and resamplers that give the same bits on every CPU.

OpenCV and numpy pick SIMD code at run time from the CPU (and OpenCV may hand a call to
IPP): the same call sums in another order, or fuses a multiply-add, on another machine,
and a value near an integer truncates to the other level. The kernels here are plain
sequential numba loops compiled without fast-math, so LLVM keeps every sum in the order
written and fuses only the multiply-adds written as :func:`fma`: it may only vectorise
across independent output pixels, which changes no result. Where it is known, the order
and fusing are those OpenCV's code takes on this project's AVX-512 machine, so the bytes
made there before stay. Integer arithmetic is used where it is exact.
"""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np
import scipy.fft

from ._jit import njit
from .jit import fma

# Up to this kernel side a direct correlation is cheaper than the FFT.
DIRECT_MAX = 11


def border_index(n: int, r: int, mode: str) -> np.ndarray:
    """Source index of positions ``-r .. n + r - 1`` of an axis of length ``n`` under
    ``mode`` (scipy.ndimage's names), reflected repeatedly when ``r`` exceeds ``n``;
    -1 where ``constant`` reads a zero."""
    i = np.arange(-r, n + r, dtype=np.int64)
    if mode == "constant":
        return np.where((i >= 0) & (i < n), i, -1)
    if mode == "nearest":
        return np.clip(i, 0, n - 1)
    if mode == "reflect":  # d c b a | a b c d | d c b a
        i %= 2 * n
        return np.where(i >= n, 2 * n - 1 - i, i)
    if mode == "mirror":  # d c b | a b c d | c b a
        if n == 1:
            return np.zeros_like(i)
        i %= 2 * n - 2
        return np.where(i >= n, 2 * n - 2 - i, i)
    raise ValueError(f"unknown border mode {mode!r}")


# Inner loops index a row view by the loop variable itself: numba then needs no
# negative-index wrap-around, and LLVM vectorises across output pixels (which changes no
# sum: each pixel's terms are still added one at a time, in order).


@njit
def _filter_rows(src, k, idx, ch, out):
    """Along each row of ``ch``-channel pixels: ``k[0] x[j]``, then for each later tap
    ``t`` in order ``fma(x[j + t], k[t], acc)``, ``x`` the row with its border (``idx``:
    the source pixel of each position, the identity inside the row, -1 for a zero)."""
    h, m = out.shape
    n = k.size
    r = n // 2
    w = m // ch
    buf = np.empty(idx.size * ch, src.dtype)
    for i in range(h):
        row = src[i]
        inner = buf[r * ch:r * ch + m]
        for q in range(m):
            inner[q] = row[q]
        for b in range(r):
            for j in (b, r + w + b):
                for c in range(ch):
                    buf[j * ch + c] = row[idx[j] * ch + c] if idx[j] >= 0 else 0.0
        line = out[i]
        first = k[0]
        for q in range(m):
            line[q] = buf[q] * first
        for t in range(1, n):
            wt = k[t]
            seg = buf[t * ch:t * ch + m]
            for q in range(m):
                line[q] = fma(seg[q], wt, line[q])


@njit
def _filter_columns(src, k, idx, out):
    """Down the columns with a symmetric kernel of radius ``r``: ``k[r] x[i]``, then for
    ``t = 1..r`` (nearest pair first) ``fma(x[i - t] + x[i + t], k[r + t], acc)``."""
    n, m = out.shape
    r = k.size // 2
    zero = np.zeros_like(src[0])
    for i in range(n):
        line = out[i]
        centre = src[idx[i + r]]
        w = k[r]
        for j in range(m):
            line[j] = centre[j] * w
        for t in range(1, r + 1):
            up = src[idx[i + r - t]] if idx[i + r - t] >= 0 else zero
            down = src[idx[i + r + t]] if idx[i + r + t] >= 0 else zero
            w = k[r + t]
            for j in range(m):
                line[j] = fma(up[j] + down[j], w, line[j])


@njit
def _correlate_axis0(src, k, idx, out):
    """``out[i, j] = k[r] src[idx[i + r], j] + sum_{t=r..1} k[r + t] (src[idx[i + r - t], j]
    + src[idx[i + r + t], j])`` for a symmetric kernel ``k`` of radius ``r``, in float64:
    the centre, then the pairs from the farthest in (as scipy.ndimage sums a symmetric
    kernel)."""
    n, m = out.shape
    r = k.size // 2
    acc = np.empty(m, np.float64)
    zero = np.zeros_like(src[0])
    for i in range(n):
        centre = src[idx[i + r]]
        w = k[r]
        for j in range(m):
            acc[j] = w * np.float64(centre[j])
        for t in range(r, 0, -1):
            up = src[idx[i + r - t]] if idx[i + r - t] >= 0 else zero
            down = src[idx[i + r + t]] if idx[i + r + t] >= 0 else zero
            w = k[r + t]
            for j in range(m):
                acc[j] += w * (np.float64(up[j]) + np.float64(down[j]))
        line = out[i]
        for j in range(m):
            line[j] = acc[j]


@njit
def _correlate_axis1(src, k, idx, out):
    """:func:`_correlate_axis0` along the rows: ``out[i, j, c]`` from ``src[i, idx[j + ...],
    c]`` (each row first copied with its border into a float64 buffer; ``idx`` is the
    identity inside the row)."""
    h, w, ch = out.shape
    m = w * ch
    r = k.size // 2
    acc = np.empty(m, np.float64)
    buf = np.empty((idx.size, ch), np.float64)
    flat = buf.reshape(-1)
    for i in range(h):
        row = src[i].reshape(-1)
        inner = flat[r * ch:r * ch + m]
        for q in range(m):
            inner[q] = row[q]
        for b in range(r):  # the borders, through the index map
            for j in (b, r + w + b):
                for c in range(ch):
                    buf[j, c] = src[i, idx[j], c] if idx[j] >= 0 else 0.0
        centre = flat[r * ch:r * ch + m]
        wt = k[r]
        for q in range(m):
            acc[q] = wt * centre[q]
        for t in range(r, 0, -1):
            left = flat[(r - t) * ch:(r - t) * ch + m]
            right = flat[(r + t) * ch:(r + t) * ch + m]
            wt = k[r + t]
            for q in range(m):
                acc[q] += wt * (left[q] + right[q])
        line = out[i].reshape(-1)
        for q in range(m):
            line[q] = acc[q]


def separable(img: np.ndarray, ky: np.ndarray, kx: np.ndarray, mode: str) -> np.ndarray:
    """Correlate float ``img`` (H x W or H x W x C) with the symmetric, odd-length, centred
    kernels ``kx`` along the rows and ``ky`` down the columns; ``mode`` names the border as
    scipy.ndimage does. The same bits on every CPU:

    - float64, as scipy.ndimage sums (the benchmark's scikit-image blur, whose flat areas
      land a rounding error off a whole level): columns first, each pass in float64, the
      centre tap and then the pairs from the farthest in;
    - float32 (displacement fields, kernels), in float32 with the arithmetic of OpenCV's
      sepFilter2D on a CPU with AVX-512: rows first, tap by tap in fused multiply-adds,
      then columns a pair at a time, nearest first, fused (that machine's bytes stay)."""
    src = np.ascontiguousarray(img if img.ndim == 3 else img[:, :, None])
    h, w, ch = src.shape
    ky, kx = np.asarray(ky, src.dtype), np.asarray(kx, src.dtype)
    if not (np.array_equal(ky, ky[::-1]) and np.array_equal(kx, kx[::-1])):
        raise ValueError("separable() takes symmetric kernels")
    flat = (h, w * ch)
    mid, out = np.empty_like(src), np.empty_like(src)
    if src.dtype == np.float32:
        _filter_rows(src.reshape(flat), kx, border_index(w, kx.size // 2, mode), ch, mid.reshape(flat))
        _filter_columns(mid.reshape(flat), ky, border_index(h, ky.size // 2, mode), out.reshape(flat))
    else:
        _correlate_axis0(src.reshape(flat), ky, border_index(h, ky.size // 2, mode), mid.reshape(flat))
        _correlate_axis1(mid, kx, border_index(w, kx.size // 2, mode), out)
    return out if img.ndim == 3 else out[:, :, 0]


@njit
def _correlate2d(padded, k, ch, out):
    """``out[i, q] = sum_{a, b} k[a, b] * padded[i + a, b * ch + q]`` in float32, taps in
    row-major order, zero taps skipped, each tap one fused multiply-add (as OpenCV's
    filter2D sums on a CPU with FMA, so the bytes there stay OpenCV's)."""
    h, wc = out.shape
    acc = np.empty(wc, np.float32)
    for i in range(h):
        acc[:] = 0.0
        for a in range(k.shape[0]):
            row = padded[i + a]
            for b in range(k.shape[1]):
                wt = k[a, b]
                if wt != 0.0:
                    seg = row[b * ch:b * ch + wc]
                    for q in range(wc):
                        acc[q] = fma(wt, seg[q], acc[q])
        line = out[i]
        for q in range(wc):
            line[q] = acc[q]


@njit
def _multiply_spectra(spec, kernel):
    """``spec[i, j, c] *= kernel[i, j]`` (complex64), the real and imaginary parts each from
    two rounded products and one rounded sum."""
    for i in range(spec.shape[0]):
        for j in range(spec.shape[1]):
            kr, ki = kernel[i, j].real, kernel[i, j].imag
            for c in range(spec.shape[2]):
                sr, si = spec[i, j, c].real, spec[i, j, c].imag
                re = sr * kr - si * ki
                im = sr * ki + si * kr
                spec[i, j, c] = complex(re, im)


@lru_cache(maxsize=6)  # ~9 MB each at 1024 x 2048
def _spectrum(kernel_bytes: bytes, side: int, shape: tuple[int, int]) -> np.ndarray:
    k = np.frombuffer(kernel_bytes, np.float32).reshape(side, side).astype(np.float64)
    spec = scipy.fft.rfft2(k, s=shape).astype(np.complex64)
    spec.flags.writeable = False
    return spec


def correlate2d(x: np.ndarray, k: np.ndarray, spectrum_kernel: np.ndarray | None = None) -> np.ndarray:
    """``cv2.filter2D(x, CV_32F, k)`` with a reflect-101 border: each channel of ``x`` (H x W
    x C, uint8 or float32) correlated with the square float32 kernel ``k`` into float32.

    Kernels up to :data:`DIRECT_MAX` wide are summed directly (:func:`_correlate2d`); larger
    ones through a float32 FFT (scipy's pocketfft, which takes no CPU-dependent path) of the
    padded image, with ``spectrum_kernel`` (default ``k``) as the kernel. A symmetric kernel
    is assumed: correlation and convolution then coincide."""
    h, w, ch = x.shape
    r = k.shape[0] // 2
    padded = _pad_mirror(x, r)
    if k.shape[0] <= DIRECT_MAX:
        out = np.empty((h, w * ch), np.float32)
        _correlate2d(padded.reshape(h + 2 * r, -1), np.ascontiguousarray(k, np.float32), ch, out)
        return out.reshape(h, w, ch)
    kf = np.ascontiguousarray(k if spectrum_kernel is None else spectrum_kernel, np.float32)
    shape = (scipy.fft.next_fast_len(h + 2 * r, real=True), scipy.fft.next_fast_len(w + 2 * r, real=True))
    spec = scipy.fft.rfft2(padded, s=shape, axes=(0, 1), workers=1)
    _multiply_spectra(spec, _spectrum(kf.tobytes(), kf.shape[0], shape))
    # Circular wrap-around only reaches the first 2r rows and columns, which are dropped.
    out = scipy.fft.irfft2(spec, s=shape, axes=(0, 1), workers=1)
    return out[2 * r:2 * r + h, 2 * r:2 * r + w]


def _pad_mirror(x: np.ndarray, r: int) -> np.ndarray:
    """float32 ``x`` with ``r`` reflect-101 border pixels on every side (OpenCV's copy when
    the border fits in the image: it only moves values, and faster)."""
    h, w = x.shape[:2]
    if r < min(h, w):
        padded = cv2.copyMakeBorder(np.ascontiguousarray(x, np.float32), r, r, r, r, cv2.BORDER_REFLECT_101)
        return padded.reshape(h + 2 * r, w + 2 * r, -1)  # OpenCV drops a single channel
    return np.ascontiguousarray(x[border_index(h, r, "mirror")][:, border_index(w, r, "mirror")], np.float32)


def opencv_gaussian_kernel(size: int, sigma: float) -> np.ndarray:
    """OpenCV's ``getGaussianKernel(size, sigma, CV_32F)``: ``exp(-x^2 / (2 sigma^2))``
    rounded to float32, scaled by the reciprocal of their float64 sum, rounded again."""
    scale = -0.5 / (sigma * sigma)
    taps = [float(np.float32(math.exp(scale * x * x))) for x in np.arange(size) - (size - 1) * 0.5]
    inv = 1.0 / sum(taps)
    return np.array([t * inv for t in taps], np.float64).astype(np.float32)


@njit
def _remap_reflect(src, ch, coords, out):
    """Bilinear sample of every channel of ``src`` at ``coords[i, j] = (x, y)`` in float32
    as OpenCV's remap computes it on a CPU with FMA: ``t = x - floor(x)``, two lerps
    along x, then one along y, each ``fma(b - a, t, a)``; indices folded by half-sample
    reflection; truncated to uint8 (a lerp stays between its ends: within 0..255).
    ``src`` and ``out`` hold rows of ``ch``-channel pixels."""
    h, w = src.shape[0], src.shape[1] // ch
    for i in range(coords.shape[0]):
        line = coords[i]
        dst = out[i]
        for j in range(coords.shape[1]):
            x, y = line[j, 0], line[j, 1]
            fx, fy = np.float32(math.floor(x)), np.float32(math.floor(y))
            ax, ay = x - fx, y - fy
            ix, iy = int(fx), int(fy)
            if 0 <= ix and ix + 1 < w:  # inside: no folding (most pixels)
                x0, x1 = ix * ch, (ix + 1) * ch
            else:
                x0, x1 = _fold(ix, w) * ch, _fold(ix + 1, w) * ch
            if 0 <= iy and iy + 1 < h:
                row0, row1 = src[iy], src[iy + 1]
            else:
                row0, row1 = src[_fold(iy, h)], src[_fold(iy + 1, h)]
            for c in range(ch):
                a, b = np.float32(row0[x0 + c]), np.float32(row0[x1 + c])
                d0, d1 = np.float32(row1[x0 + c]), np.float32(row1[x1 + c])
                top = fma(b - a, ax, a)
                bottom = fma(d1 - d0, ax, d0)
                dst[j * ch + c] = np.uint8(fma(bottom - top, ay, top))


@njit
def _fold(i, n):
    if 0 <= i < n:
        return i
    i %= 2 * n
    return 2 * n - 1 - i if i >= n else i


def remap_reflect(x: np.ndarray, coords: np.ndarray) -> np.ndarray:
    """uint8 ``x`` (H x W x C) sampled bilinearly at float32 ``coords`` (H' x W' x 2, column
    then row) with a half-sample symmetric border, truncated to uint8."""
    h, w, ch = x.shape
    out = np.empty(coords.shape[:2] + (ch,), np.uint8)
    _remap_reflect(np.ascontiguousarray(x).reshape(h, w * ch), ch, coords, out.reshape(out.shape[0], -1))
    return out


_COEF_BITS = 11  # OpenCV's INTER_RESIZE_COEF_BITS: coefficients in units of 1/2048


def _cubic_taps(n_src: int, n_dst: int, start: int = 0, count: int | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Per output position ``d`` along one axis (``start .. start + count``; all by
    default), the four source indices (clamped: replicated border) and OpenCV's fixed-point
    cubic weights (A = -0.75), computed as OpenCV does in float32:
    ``f = float32((d + 0.5) * scale - 0.5)``, ``s = floor(f)``, ``t = f - s``, weights
    rounded half to even after scaling by 2048, the last ``1 - w0 - w1 - w2``."""
    scale = 1.0 / (n_dst / n_src)
    d = np.arange(start, start + (n_dst - start if count is None else count), dtype=np.float64)
    f = ((d + 0.5) * scale - 0.5).astype(np.float32)
    s = np.floor(f)
    t = f - s
    one, a = np.float32(1), np.float32(-0.75)
    u = t + one
    w0 = ((a * u - np.float32(5) * a) * u + np.float32(8) * a) * u - np.float32(4) * a
    w1 = ((a + np.float32(2)) * t - (a + np.float32(3))) * t * t + one
    v = one - t
    w2 = ((a + np.float32(2)) * v - (a + np.float32(3))) * v * v + one
    w3 = one - w0 - w1 - w2
    weights = np.rint(np.stack([w0, w1, w2, w3], axis=1) * np.float32(1 << _COEF_BITS)).astype(np.int64)
    index = np.clip(s.astype(np.int64)[:, None] + np.arange(-1, 3), 0, n_src - 1)
    return index, weights


@njit
def _cubic_rows(src, xi, xw, out):
    """``out[i, j, c] = sum_k src[i, xi[j, k], c] * xw[j, k]`` in int64 (exact)."""
    for i in range(src.shape[0]):
        for j in range(xi.shape[0]):
            for c in range(src.shape[2]):
                acc = 0
                for k in range(4):
                    acc += np.int64(src[i, xi[j, k], c]) * xw[j, k]
                out[i, j, c] = acc


@njit
def _cubic_columns(rows, yi, yw, shift, out):
    """``out[i, q] = clip((sum_k rows[yi[i, k], q] * yw[i, k] + 2^(shift-1)) >> shift, 0, 255)``."""
    half = np.int64(1) << (shift - 1)
    for i in range(yi.shape[0]):
        r0, r1, r2, r3 = rows[yi[i, 0]], rows[yi[i, 1]], rows[yi[i, 2]], rows[yi[i, 3]]
        b0, b1, b2, b3 = yw[i, 0], yw[i, 1], yw[i, 2], yw[i, 3]
        line = out[i]
        for q in range(line.size):
            v = (r0[q] * b0 + r1[q] * b1 + r2[q] * b2 + r3[q] * b3 + half) >> shift
            line[q] = min(max(v, 0), 255)


def resize_cubic(img: np.ndarray, size: tuple[int, int],
                 window: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """``cv2.resize(img, size, interpolation=INTER_CUBIC)`` of uint8 ``img`` (H x W x C) to
    ``size`` = (width, height) by OpenCV's reference fixed-point formula, in exact integer
    arithmetic: rows of 4 taps weighted in 1/2048, then columns likewise, the sum rounded
    (``+ 2^21 >> 22``) and saturated to 0..255. ``window`` = (top, left, height, width):
    only that part of the resized image (the same bytes as cropping the whole one)."""
    (w_out, h_out), (h, w, ch) = size, img.shape
    top, left, rows_out, cols_out = window or (0, 0, h_out, w_out)
    xi, xw = _cubic_taps(w, w_out, left, cols_out)
    yi, yw = _cubic_taps(h, h_out, top, rows_out)
    rows = np.empty((h, cols_out, ch), np.int64)
    _cubic_rows(np.ascontiguousarray(img), xi, xw, rows)
    out = np.empty((rows_out, cols_out, ch), np.uint8)
    _cubic_columns(rows.reshape(h, -1), yi, yw, 2 * _COEF_BITS, out.reshape(rows_out, -1))
    return out
