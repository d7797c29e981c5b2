"""Fog: a diamond-square plasma fractal added to the image."""

from __future__ import annotations

import numpy as np

from ._ops import truncate_to_uint8
from .registry import register
from .severity import interpolate

# (t, d): fog thickness and the plasma's wibble decay
LEVELS = ((1.5, 2.0), (2.0, 2.0), (2.5, 1.7), (2.5, 1.5), (3.0, 1.4))


def next_power_of_two(n: int) -> int:
    """The smallest power of two ``>= n`` (``n >= 1``)."""
    return 1 << (int(n) - 1).bit_length()


def _wibbled_mean(total: np.ndarray, wibble: float, rng: np.random.Generator) -> np.ndarray:
    """``total / 4 + w * U(-w, w)`` elementwise, float32, one uniform per element in C order."""
    u = rng.random(total.shape, dtype=np.float32)
    u *= np.float32(2.0 * wibble * wibble)
    u += np.float32(-wibble * wibble)
    total *= np.float32(0.25)
    total += u
    return total


def _wrapped(grid: np.ndarray, before: bool) -> np.ndarray:
    """``grid`` with one wrapped-around row and column added after it (``before=False``:
    the first row/column repeated at the end) or before it (the last ones repeated first),
    so torus neighbours become plain slices."""
    k0, k1 = grid.shape
    out = np.empty((k0 + 1, k1 + 1), dtype=grid.dtype)
    if before:
        out[1:, 1:] = grid
        out[0, 1:] = grid[-1]
        out[:, 0] = out[:, -1]
    else:
        out[:-1, :-1] = grid
        out[-1, :-1] = grid[0]
        out[:, -1] = out[:, 0]
    return out


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
        c = _wrapped(grid, before=False)
        centres = c[:-1, :-1] + c[1:, :-1]
        centres += c[:-1, 1:]
        centres += c[1:, 1:]
        centres = _wibbled_mean(centres, wibble, rng)
        m = _wrapped(centres, before=True)  # m[i + 1, j + 1] = centre (i, j)
        # (i s, h + j s): corners left and right, centres below and above
        top = c[:-1, :-1] + c[:-1, 1:]
        top += m[1:, 1:]
        top += m[:-1, 1:]
        top = _wibbled_mean(top, wibble, rng)
        # (h + i s, j s): corners above and below, centres right and left
        left = c[:-1, :-1] + c[1:, :-1]
        left += m[1:, 1:]
        left += m[1:, :-1]
        left = _wibbled_mean(left, wibble, rng)
        parts = (grid, top, left, centres)
        if step == 2:
            break
        grid = _interleave(parts, grid.shape)
        step //= 2
        wibble /= decay
    lo = min(float(p.min()) for p in parts)
    hi = max(float(p.max()) for p in parts)
    out = _interleave(parts, ((rows + 1) // 2, (cols + 1) // 2))[:rows, :cols]
    out -= np.float32(lo)
    out /= np.float32(hi) - np.float32(lo)
    return out


def _interleave(parts, half_shape) -> np.ndarray:
    """The next finer grid from one step's ``(corners, top, left, centres)``:
    ``G'[2i, 2j]``, ``G'[2i, 2j + 1]``, ``G'[2i + 1, 2j]``, ``G'[2i + 1, 2j + 1]``;
    only its first ``half_shape`` cells of each kind."""
    r, c = half_shape
    out = np.empty((2 * r, 2 * c), dtype=np.float32)
    corners, top, left, centres = parts
    out[0::2, 0::2] = corners[:r, :c]
    out[0::2, 1::2] = top[:r, :c]
    out[1::2, 0::2] = left[:r, :c]
    out[1::2, 1::2] = centres[:r, :c]
    return out


@register(("t", "d"), LEVELS)
def fog(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Fog: with ``m = max f`` and ``P`` a :func:`plasma_fractal` of side ``N`` (the
    smallest power of two >= max(H, W)) and decay ``d``, ``g = f + t * P[:H, :W]`` on every
    channel; result ``clip01(g * m / (m + t))``, truncated to uint8.

    Size rule: the map's side ``N`` grows with the image (64 for 37 x 53, 2048 for
    375 x 1242 and 1024 x 2048, 4096 for 2048 x 4096), so the fractal's largest features
    scale with the image, and only the top-left H x W of it is used (a wide image sees a
    band of the square map), as imagecorruptions-imaug 1.1.5 does.

    Computed in float32 in the 0..255 domain: ``(x + 255 t P) * m / (m + t)``.

    Between integer levels: ``t`` and ``d`` linear (the fractal draws the same uniforms at
    every level; only their decay changes).
    """
    t, d = interpolate(LEVELS, level)
    height, width = x.shape[:2]
    plasma = plasma_fractal(next_power_of_two(max(height, width)), d, rng, (height, width))
    m = float(x.max()) / 255.0
    scale = np.float32(m / (m + t))
    g = plasma[:, :, None] * np.float32(255.0 * t)
    g = g + x  # float32: the uint8 image is promoted
    return truncate_to_uint8(g, scale)
