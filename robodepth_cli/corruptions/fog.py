"""Fog: a diamond-square plasma fractal added to the image."""

from __future__ import annotations

import math
import numpy as np

from ._jit import njit
from ._ops import truncate_to_uint8
from .registry import register
from .severity import interpolate

# (t, d): fog thickness and the plasma's wibble decay
LEVELS = ((1.5, 2.0), (2.0, 2.0), (2.5, 1.7), (2.5, 1.5), (3.0, 1.4))


def next_power_of_two(n: int) -> int:
    """The smallest power of two ``>= n`` (``n >= 1``)."""
    return 1 << (int(n) - 1).bit_length()


@njit
def _step(grid, u_centres, u_top, u_left, scale, shift, rows, cols):
    """One diamond-square step on the k x k torus ``grid``: the next finer grid's top-left
    ``2 rows`` x ``2 cols`` (``G'[2i, 2j]`` the corners, ``G'[2i, 2j + 1]`` the points
    ``(i s, h + j s)``, ``G'[2i + 1, 2j]`` the points ``(h + i s, j s)``, ``G'[2i + 1,
    2j + 1]`` the square centres), and the least and greatest value of the whole finer grid.

    Each new value is ``((a + b) + c) + d) * 0.25 + (u * scale + shift)`` in float32, in
    that order, ``u`` the point's uniform (``scale = 2 w^2``, ``shift = -w^2``): the
    arithmetic, and so the bits, of the numpy formulation this replaces."""
    k = grid.shape[0]
    quarter = np.float32(0.25)
    centres = np.empty((k, k), np.float32)
    lo = grid[0, 0]
    hi = grid[0, 0]
    for i in range(k):
        i1 = i + 1 if i + 1 < k else 0
        for j in range(k):
            j1 = j + 1 if j + 1 < k else 0
            g = grid[i, j]
            lo = min(lo, g)
            hi = max(hi, g)
            t = ((g + grid[i1, j]) + grid[i, j1]) + grid[i1, j1]
            v = t * quarter + (u_centres[i, j] * scale + shift)
            centres[i, j] = v
            lo = min(lo, v)
            hi = max(hi, v)
    out = np.empty((2 * rows, 2 * cols), np.float32)
    for i in range(k):
        i1 = i + 1 if i + 1 < k else 0
        i0 = i - 1 if i > 0 else k - 1
        for j in range(k):
            j1 = j + 1 if j + 1 < k else 0
            j0 = j - 1 if j > 0 else k - 1
            g = grid[i, j]
            c = centres[i, j]
            top = ((g + grid[i, j1]) + c) + centres[i0, j]
            top = top * quarter + (u_top[i, j] * scale + shift)
            left = ((g + grid[i1, j]) + c) + centres[i, j0]
            left = left * quarter + (u_left[i, j] * scale + shift)
            lo = min(lo, min(top, left))
            hi = max(hi, max(top, left))
            if i < rows and j < cols:
                out[2 * i, 2 * j] = g
                out[2 * i, 2 * j + 1] = top
                out[2 * i + 1, 2 * j] = left
                out[2 * i + 1, 2 * j + 1] = c
    return out, lo, hi


def plasma_fractal(n: int, decay: float, rng: np.random.Generator, shape=None) -> np.ndarray:
    """Diamond-square height map on an ``n`` x ``n`` torus (``n >= 2`` a power of two),
    float32, scaled to [0, 1]; only its top-left ``shape`` (rows, columns) part is
    returned if given (the scaling still uses the whole map).

    ``A[0, 0] = 0``, step ``s = n``, wibble ``w = 100``. While ``s >= 2``, with ``h = s / 2``:
    every square centre ``(h + i s, h + j s)`` becomes the mean of its four grid corners
    plus ``w * U(-w, w)``; then every diamond point ``(i s, h + j s)`` and ``(h + i s, j s)``
    becomes the mean of its four neighbours at distance ``h`` (two corners, two centres)
    plus ``w * U(-w, w)``; indices wrap around; then ``s = h`` and ``w = w / decay``.
    Finally ``A = (A - min A) / max(A - min A)``.

    Randomness, per step: one uniform array for the square centres, then one for the
    points ``(i s, h + j s)``, then one for ``(h + i s, j s)``, each in C order.
    The points of spacing ``s`` are kept as a dense grid ``G`` (``G[i, j] = A[i s, j s]``);
    the last step's four interleaved parts are only assembled where ``shape`` asks.
    """
    if n < 2 or n & (n - 1):
        raise ValueError(f"plasma size must be a power of two >= 2, got {n}")
    rows, cols = (n, n) if shape is None else shape
    if not (0 < rows <= n and 0 < cols <= n):
        raise ValueError(f"crop {shape} outside the {n} x {n} map")
    grid = np.zeros((1, 1), dtype=np.float32)
    step, wibble = n, 100.0
    while True:
        k = grid.shape[0]
        # Per step: the square centres' uniforms, then those of (i s, h + j s), then those
        # of (h + i s, j s), each in C order.
        u = [rng.random((k, k), dtype=np.float32) for _ in range(3)]
        scale, shift = np.float32(2.0 * wibble * wibble), np.float32(-wibble * wibble)
        last = step == 2
        r, c = ((rows + 1) // 2, (cols + 1) // 2) if last else (k, k)
        grid, lo, hi = _step(grid, *u, scale, shift, r, c)
        if last:
            break
        step //= 2
        wibble /= decay
    out = grid[:rows, :cols]
    out -= np.float32(lo)
    out /= np.float32(hi) - np.float32(lo)
    return out


def fog_map(shape: tuple[int, int], decay: float, rng: np.random.Generator, scale: float | None = None):
    """The H x W plasma of fog for an image of ``shape``: the top-left of a
    :func:`plasma_fractal` of side the smallest power of two >= max(H, W); with a severity
    size's ``scale``, that of the image at the severity size (``round(H / scale)`` x
    ``round(W / scale)``) resized to H x W: linear interpolation between pixel centres
    (SciPy ``ndimage.zoom``, order 1, edges replicated), after a box average over
    ``ceil(1 / scale)`` pixels when shrinking. SciPy's ndimage has no CPU-dependent code
    path, so the map is the same on any CPU."""
    height, width = shape
    if scale is not None:
        from scipy import ndimage

        h0, w0 = max(round(height / scale), 1), max(round(width / scale), 1)
        small = plasma_fractal(next_power_of_two(max(h0, w0, 2)), decay, rng, (h0, w0))
        if scale < 1:
            small = ndimage.uniform_filter(small, size=math.ceil(1 / scale), mode="nearest")
        out = ndimage.zoom(small, (height / h0, width / w0), order=1, mode="nearest", grid_mode=True)
        return np.ascontiguousarray(out[:height, :width], dtype=np.float32)
    return plasma_fractal(next_power_of_two(max(height, width)), decay, rng, (height, width))


@register(("t", "d"), LEVELS, scaled=True)
def fog(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """Fog: with ``m = max f`` and ``P`` a :func:`plasma_fractal` of side ``N`` (the
    smallest power of two >= max(H, W)) and decay ``d``, ``g = f + t * P[:H, :W]`` on every
    channel; result ``clip01(g * m / (m + t))``, truncated to uint8.

    Size rule: the map's side ``N`` grows with the image (64 for 37 x 53, 2048 for
    375 x 1242 and 1024 x 2048, 4096 for 2048 x 4096), so the fractal's largest features
    scale with the image, and only the top-left H x W of it is used (a wide image sees a
    band of the square map), as imagecorruptions-imaug 1.1.5 does. With a severity size,
    the map is that of the image at the severity size, resized to the image
    (:func:`fog_map`): its features keep their share of the image.

    Computed in float32 in the 0..255 domain: ``(x + 255 t P) * m / (m + t)``.

    Between integer levels: ``t`` and ``d`` linear (the fractal draws the same uniforms at
    every level; only their decay changes).
    """
    t, d = interpolate(LEVELS, level)
    plasma = fog_map(x.shape[:2], d, rng, scale)
    m = float(x.max()) / 255.0
    scale = np.float32(m / (m + t))
    thick = np.float32(255.0 * t)
    out = np.empty_like(x)
    if _add_fog(plasma, x, thick, scale, out):  # NaN only from a flat map: numpy's cast then
        out = truncate_to_uint8(plasma[:, :, None] * thick + x, scale)
    return out


@njit
def _add_fog(plasma, x, thick, scale, out):
    """``out = uint8(clip((plasma * thick + x) * scale, 0, 255))`` per pixel and channel, in
    float32 and in that order (the bits of the numpy expression); True if a value was NaN
    (``out`` is then not to be used)."""
    nan = False
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            p = plasma[i, j] * thick
            for c in range(x.shape[2]):
                v = (p + np.float32(x[i, j, c])) * scale
                nan |= np.isnan(v)
                out[i, j, c] = np.uint8(min(max(v, np.float32(0.0)), np.float32(255.0)))
    return nan
