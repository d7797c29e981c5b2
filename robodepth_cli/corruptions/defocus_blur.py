"""Defocus blur: convolution with an anti-aliased disk."""

from __future__ import annotations

from functools import lru_cache

import math

import numpy as np

from ._exact import correlate2d, opencv_gaussian_kernel, separable
from ._ops import truncate_to_uint8
from .registry import register
from .severity import interpolate

LEVELS = ((3, 0.1), (4, 0.5), (6, 0.5), (8, 0.5), (10, 0.5))

@lru_cache(maxsize=None)
def disk_kernel(radius: float, alias: float) -> np.ndarray:
    """The benchmark's defocus kernel, trimmed of its all-zero border rows and columns.

    Coordinates ``-8..8`` with a 3 x 3 Gaussian if ``radius <= 8``, else
    ``-ceil(radius)..ceil(radius)`` with 5 x 5; disk = ``X^2 + Y^2 <= radius^2`` (a
    fractional radius, from a decimal level, is used as it is) normalised to sum 1 in float32, then ``cv2.GaussianBlur`` of that size with sigma ``alias`` (its own
    reflect-101 border included): OpenCV's float32 Gaussian taps and its float32
    separable arithmetic (:func:`~._exact.separable`, the same bits on any CPU).
    Trimming exact zeros changes no convolution result.
    """
    if radius <= 8:
        coords, ksize = np.arange(-8, 9), (3, 3)
    else:
        span = math.ceil(radius)
        coords, ksize = np.arange(-span, span + 1), (5, 5)
    xx, yy = np.meshgrid(coords, coords)
    d = np.asarray(xx ** 2 + yy ** 2 <= radius ** 2, dtype=np.float32)
    d /= np.sum(d)
    g = opencv_gaussian_kernel(ksize[0], alias)
    k = separable(d, g, g, "mirror")
    keep = np.flatnonzero(k.any(axis=0))
    # The kernel is symmetric, so the same span serves rows and columns and stays centred.
    k = np.ascontiguousarray(k[keep[0]:keep[-1] + 1, keep[0]:keep[-1] + 1])
    k.flags.writeable = False
    return k


@lru_cache(maxsize=16)
def direct_kernel(radius: float, alias: float) -> np.ndarray:
    """:func:`disk_kernel` for the direct float32 sum on the 0..255 integer values, its subnormal
    entries (level 1's alias 0.1 leaves a dozen, ~1e-45) raised to the least normal float32.

    Why: x86 multiplies subnormals ~30x slower (level 1 took 20 ms a 192 x 640 image,
    level 2 1.3 ms). Why the bytes stay: the sum takes the same taps in the same order (it
    skips only zeros); every tap is >= 0 and every pixel an integer 0..255, so a partial sum
    holding any normal term is at least ``m``, the least normal entry, while all the
    subnormal taps together, either way, stay below ``m * 2**-33``: too small to change a
    float32 sum, a product's rounding (FMA included), or a result, which without a normal
    term is below 1e-30 and truncates to 0 either way. Where that margin does not hold,
    the kernel is used as it is."""
    k = disk_kernel(radius, alias)
    tiny = np.finfo(np.float32).tiny
    sub = (k != 0) & (k < tiny)
    normal = k[k >= tiny]
    if not sub.any() or not normal.size or sub.sum() * 255.0 * tiny >= float(normal.min()) * 2.0 ** -33:
        return k
    k = np.where(sub, tiny, k).astype(np.float32)
    k.flags.writeable = False
    return k


@register(("radius", "alias"), LEVELS, deterministic=True, scaled=True)
def defocus_blur(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """Convolve each channel with :func:`disk_kernel` ``(radius, alias)`` with OpenCV
    ``filter2D`` semantics (reflect-101 border): ``clip01(filter2D(f, disk))``, truncated
    to uint8. Computed on the 0..255 values in float32 (:func:`~._exact.correlate2d`: a
    direct sum in a fixed order for small kernels, an FFT for large ones), which matches the float64 formula to about 1e-4 of a level. Where the
    float64 kernel sums to just under 1 (levels 1-3, by ~1e-8) the formula puts flat areas
    a hair below an integer, which truncates one level lower than float32 resolves; that
    accounts for the 0.02-0.05 mean difference seen at level 1.

    Between integer levels: ``radius`` and ``alias`` linear; the disk takes the pixels
    within the fractional radius, so it grows by whole rings of pixels as ``radius``
    passes each distance ``sqrt(X^2 + Y^2)``.

    With a severity size, ``radius`` and ``alias`` are multiplied by its ``scale``."""
    radius, alias = interpolate(LEVELS, level)
    if scale is not None:
        radius, alias = radius * scale, alias * scale
    out = correlate2d(x, direct_kernel(radius, alias), spectrum_kernel=disk_kernel(radius, alias))
    return truncate_to_uint8(out, 1.0)
