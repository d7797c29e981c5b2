"""Small numeric helpers shared by several corruptions."""

from __future__ import annotations

import math

import numpy as np

from ._exact import separable
from ._jit import njit


def truncate_to_uint8(v: np.ndarray, scale: float = 255.0) -> np.ndarray:
    """``uint8(floor(clip(v * scale, 0, 255)))``: the benchmark truncates, it does not round.

    A C-contiguous float array takes one numba pass instead of numpy's three, with the
    product in numpy's result type, so the same bits; an array holding NaN (whose cast
    numba leaves undefined) and anything else take the numpy passes."""
    if (isinstance(v, np.ndarray) and v.dtype in _FLOATS and v.flags.c_contiguous
            and np.result_type(v, scale) == v.dtype):
        out = np.empty(v.shape, np.uint8)
        if not _truncate(v.reshape(-1), v.dtype.type(scale), out.reshape(-1)):
            return out
    out = np.multiply(v, scale)
    np.clip(out, 0.0, 255.0, out=out)
    return out.astype(np.uint8)


_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


@njit
def _truncate(v, scale, out):
    """``out = uint8(clip(v * scale, 0, 255))`` on flat arrays; True if a product was NaN
    (``out`` is then not to be used). Branch-free, so LLVM vectorises it."""
    nan = False
    for i in range(v.size):
        p = v[i] * scale
        nan |= np.isnan(p)
        out[i] = np.uint8(min(max(p, 0.0), 255.0))
    return nan


def gaussian_kernel_1d(sigma: float, truncate: float) -> np.ndarray:
    """The 1-D kernel of ``scipy.ndimage.gaussian_filter``: radius ``int(truncate * sigma + 0.5)``.

    Each tap from the C library's ``exp`` and the sum correctly rounded (``math.fsum``):
    numpy's vectorised ``exp`` and its summation order depend on the CPU."""
    radius = int(truncate * float(sigma) + 0.5)
    k = np.array([math.exp(-0.5 * (x / sigma) ** 2) for x in range(-radius, radius + 1)])
    return k / math.fsum(k)


def gaussian(img: np.ndarray, sigma, *, truncate: float = 4.0, mode: str = "nearest") -> np.ndarray:
    """``skimage.filters.gaussian`` (= ``scipy.ndimage.gaussian_filter`` per channel) on a
    float H x W or H x W x C array, in the array's dtype with OpenCV's sepFilter2D
    arithmetic (:func:`~._exact.separable`, the same bits on any CPU).

    ``sigma`` is a scalar or a (row, column) pair; channels are never mixed.
    """
    sy, sx = (sigma, sigma) if np.isscalar(sigma) else sigma
    ky = gaussian_kernel_1d(sy, truncate)
    kx = gaussian_kernel_1d(sx, truncate)
    src = img if img.dtype in (np.float32, np.float64) else img.astype(np.float64)
    return separable(src, ky, kx, mode)

