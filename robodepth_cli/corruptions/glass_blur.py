"""Glass blur: blur, local pixel shuffling, blur again."""

from __future__ import annotations

import numpy as np

from ._jit import njit
from ._ops import gaussian, truncate_to_uint8
from .registry import register
from .severity import LINEAR, NEAREST, interpolate

# (sigma, delta, iterations)
LEVELS = ((0.7, 1, 2), (0.9, 2, 1), (1.0, 2, 3), (1.1, 3, 2), (1.5, 4, 2))


def swap_offsets(shape, delta: int, iterations: int, rng: np.random.Generator) -> np.ndarray:
    """All the random offsets of the shuffle, in the order they are used:
    ``offsets[i, a, b] = (dx, dy)`` for pass ``i`` and the ``a``-th row and ``b``-th column
    of the descending scan (``h = H - delta - a``, ``w = W - delta - b``), each drawn
    uniformly from ``[-delta, delta)``; one ``rng.integers`` call, dx before dy."""
    height, width = shape[:2]
    rows, cols = max(height - 2 * delta, 0), max(width - 2 * delta, 0)
    return rng.integers(-delta, delta, size=(iterations, rows, cols, 2), dtype=np.int8)


def _blur_levels(img: np.ndarray, sigma: float) -> np.ndarray:
    """``uint8(floor(gauss(img / 255, sigma) * 255))`` of the uint8 ``img`` at a severity
    size: the exact Gaussian while its kernel is short (up to 41 taps), beyond that three box
    blurs of the same variance (:func:`~._large.box_gaussian`) in float32 on the 0..255
    values, a flat region keeping its level (1e-3 of a level added before the truncation,
    which float32's rounding would otherwise take one level lower half the time)."""
    if int(4.0 * sigma + 0.5) <= 20:
        return truncate_to_uint8(gaussian(img / 255.0, sigma, truncate=4.0, mode="nearest"))
    import cv2

    from ._large import box_gaussian

    v = box_gaussian(img.astype(np.float32), sigma, cv2.BORDER_REPLICATE)
    v += np.float32(1e-3)
    return truncate_to_uint8(v, 1.0)


def block_sources(shape, scale: float, delta: int, iterations: int, rng: np.random.Generator):
    """The shuffle of an image of ``shape`` at a severity size's ``scale``: the shuffle of
    the severity size's grid (``round(H / scale)`` x ``round(W / scale)`` cells, its offsets
    drawn by :func:`swap_offsets` as at that size), each cell a block of about ``scale``
    pixels a side that moves whole. Returns int32 H x W ``(rows, cols)``: the pixel each
    pixel takes its value from (the block's displacement, in pixels, clipped to the image)."""
    h, w = shape[:2]
    gh, gw = max(round(h / scale), 1), max(round(w / scale), 1)
    cells = np.empty((gh, gw, 2), np.int32)
    cells[..., 0] = np.arange(gh, dtype=np.int32)[:, None]
    cells[..., 1] = np.arange(gw, dtype=np.int32)[None, :]
    shuffle_pixels(cells, swap_offsets((gh, gw), delta, iterations, rng), delta)
    return tuple(_fine(cells[..., axis], axis, (h, w), (gh, gw)) for axis in (0, 1))


def _fine(cells: np.ndarray, axis: int, shape, grid) -> np.ndarray:
    """The source row (``axis`` 0) or column (1) of every pixel, from the source cells of
    the grid: the own cell's displacement in cells, in pixels (rounded, by table), added to
    the pixel's own index and clipped to the image."""
    n, g = shape[axis], grid[axis]
    own = [(np.arange(m, dtype=np.int64) * k // m).astype(np.int32) for m, k in zip(shape, grid)]
    moved = cells[own[0][:, None], own[1][None, :]]
    moved -= own[axis][:, None] if axis == 0 else own[axis][None, :]
    reach = int(np.abs(moved).max(initial=0))
    table = np.rint(np.arange(-reach, reach + 1) * (n / g)).astype(np.int32)
    out = table[moved + reach]
    out += np.arange(n, dtype=np.int32)[:, None] if axis == 0 else np.arange(n, dtype=np.int32)[None, :]
    return np.clip(out, 0, n - 1, out=out)


@njit
def shuffle_pixels(img, offsets, delta):
    """In place, for every pass ``i``: for ``h`` from ``H - delta`` down to ``delta + 1``,
    for ``w`` from ``W - delta`` down to ``delta + 1``, with
    ``(dx, dy) = offsets[i, H - delta - h, W - delta - w]``, set pixel ``(h, w)`` to the
    current value of pixel ``(h + dy, w + dx)``, which keeps its value (the benchmark's
    "swap", see :func:`glass_blur`). Sequential: a pixel written earlier can be copied
    again."""
    height, width, channels = img.shape
    for i in range(offsets.shape[0]):
        for h in range(height - delta, delta, -1):
            a = height - delta - h
            for w in range(width - delta, delta, -1):
                b = width - delta - w
                hp = h + offsets[i, a, b, 1]
                wp = w + offsets[i, a, b, 0]
                for ch in range(channels):
                    img[h, w, ch] = img[hp, wp, ch]
    return img


# delta and iterations do not rise together (levels 1 -> 2: delta 1 -> 2, passes 2 -> 1), so
# they switch together, to the nearer level's pair, instead of being rounded one by one.
RULES = (LINEAR, NEAREST, NEAREST)


@register(("sigma", "delta", "iterations"), LEVELS, rules=RULES, scaled=True)
def glass_blur(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """Glass blur: ``y = uint8(floor(gauss(f, sigma) * 255))`` with ``gauss`` scikit-image's
    ``filters.gaussian`` per channel (mode ``nearest``, truncate 4); then ``iterations``
    passes of local pixel shuffling: for ``h`` from ``H - delta`` down to ``delta + 1``, for
    ``w`` from ``W - delta`` down to ``delta + 1``, draw ``dx`` then ``dy`` uniformly from
    ``[-delta, delta)`` and "swap" pixels ``(h, w)`` and ``(h + dy, w + dx)``, sequentially;
    result ``clip01(gauss(y / 255, sigma))``, truncated to uint8.

    The "swap" is what the benchmark's code does, not a true exchange: it is the tuple
    assignment ``x[h, w], x[h', w'] = x[h', w'], x[h, w]`` on numpy (and numba) row views
    of an H x W x 3 array; the second view already holds the copied pixel, so pixel
    ``(h, w)`` takes the value of ``(h', w')`` and ``(h', w')`` is unchanged. The benchmark's
    data (tests/data/reference) and the ``imagecorruptions`` oracle both follow the copy,
    so that is what is done here.

    Size rule: without a severity size (as imagecorruptions-imaug 1.1.5) sigma and delta
    are in pixels at any size; the scan writes rows ``delta + 1 .. H - delta`` and the same
    span of columns, leaving the first ``delta + 1`` and the last ``delta - 1`` unwritten;
    ``iterations * (H - 2 delta) * (W - 2 delta)`` offset pairs are drawn. With a severity
    size, ``sigma`` is multiplied by its ``scale`` and the shuffle is that of the severity
    size's grid, moving blocks of ``scale`` pixels (:func:`block_sources`): the same
    passes and chains of copies, each displacement and each shuffled piece ``scale`` times
    larger. (Widening the draw to ``[-delta s, delta s)`` instead over-spreads, since a
    pixel then copies one already moved in this pass more often; and moving single pixels
    leaves a grain ``s`` times finer than at the severity size.)

    All offsets are drawn up front (:func:`swap_offsets`) and the swaps run in a numba
    kernel (:func:`shuffle_pixels`). The blurs run in float64 on ``x / 255`` as the
    benchmark does: in flat regions ``gauss(k / 255) * 255`` lands a rounding error below
    or above ``k``, and truncation turns that into ``k - 1`` or ``k``.

    Between integer levels: ``sigma`` linear; ``delta`` and ``iterations`` are those of the
    nearest integer level (a half goes to the upper level), so level 1.5 shuffles like
    level 2 and blurs with sigma 0.8.
    """
    sigma, delta, iterations = interpolate(LEVELS, level, RULES)
    if scale is not None:
        rows, cols = block_sources(x.shape, scale, delta, iterations, rng)
        rows *= x.shape[1]
        rows += cols  # one flat index: a single gather
        y = _blur_levels(x, sigma * scale).reshape(-1, x.shape[2])[rows]
        return _blur_levels(y, sigma * scale)
    offsets = swap_offsets(x.shape, delta, iterations, rng)
    y = truncate_to_uint8(gaussian(x / 255.0, sigma, truncate=4.0, mode="nearest"))
    shuffle_pixels(y, offsets, delta)
    return truncate_to_uint8(gaussian(y / 255.0, sigma, truncate=4.0, mode="nearest"))
