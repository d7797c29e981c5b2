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


def _gaussian(img: np.ndarray, sigma: float) -> np.ndarray:
    """``gaussian(img, sigma, truncate=4, mode='nearest')``; a kernel that only a severity
    size makes this wide (over 41 taps) by three box blurs of the same variance
    (:func:`~._large.box_gaussian`)."""
    if int(4.0 * sigma + 0.5) <= 20:
        return gaussian(img, sigma, truncate=4.0, mode="nearest")
    import cv2

    from ._large import box_gaussian

    return box_gaussian(img, sigma, cv2.BORDER_REPLICATE)


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
    cy = (np.arange(h, dtype=np.int64) * gh // h).astype(np.int32)
    cx = (np.arange(w, dtype=np.int64) * gw // w).astype(np.int32)
    moved = cells[cy[:, None], cx[None, :]]
    rows = np.rint((moved[..., 0] - cy[:, None]) * (h / gh)).astype(np.int32) + np.arange(h, dtype=np.int32)[:, None]
    cols = np.rint((moved[..., 1] - cx[None, :]) * (w / gw)).astype(np.int32) + np.arange(w, dtype=np.int32)[None, :]
    np.clip(rows, 0, h - 1, out=rows)
    np.clip(cols, 0, w - 1, out=cols)
    return rows, cols


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
        y = truncate_to_uint8(_gaussian(x / 255.0, sigma * scale))
        return truncate_to_uint8(_gaussian(y[rows, cols] / 255.0, sigma * scale))
    offsets = swap_offsets(x.shape, delta, iterations, rng)
    y = truncate_to_uint8(gaussian(x / 255.0, sigma, truncate=4.0, mode="nearest"))
    shuffle_pixels(y, offsets, delta)
    return truncate_to_uint8(gaussian(y / 255.0, sigma, truncate=4.0, mode="nearest"))
