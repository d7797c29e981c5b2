"""Motion blur and the shift-and-add routine snow shares.

Shifting with edge replication is sampling with a replicate border: the shifted copy by
``(dx, dy)`` is ``img[clamp(row - dy), clamp(col - dx)]``. The weighted sum of the copies is
therefore a sparse correlation, done here by one numba pass over the output rows that
adds every tap as a contiguous row segment plus its replicated edge.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ._jit import njit
from ._ops import truncate_to_uint8
from .registry import register
from .severity import LINEAR, ROUND, interpolate

LEVELS = ((10, 3), (15, 5), (15, 8), (15, 12), (20, 15))


@lru_cache(maxsize=64)
def _weights(radius: int, sigma: float) -> np.ndarray:
    width = 2 * radius + 1
    i = np.arange(width, dtype=np.float64)
    k = np.exp(-(i ** 2) / (2 * sigma ** 2))
    k /= k.sum()
    k.flags.writeable = False
    return k


def motion_taps(radius: int, sigma: float, angle: float, shape: tuple[int, int]):
    """The shifts and weights of the benchmark's motion blur of an image of ``shape``.

    ``width = 2 * radius + 1``; ``k_i = exp(-i^2 / (2 sigma^2))`` normalised to sum 1;
    ``(py, px) = (width * sin a, width * cos a)`` with ``a`` in degrees; tap ``i`` shifts by
    ``dy = -ceil(i * py / hypot - 0.5)``, ``dx = -ceil(i * px / hypot - 0.5)``, and the taps
    end before the first one with ``|dy| >= H`` or ``|dx| >= W``.

    Returns ``(dy, dx, k)``: int64, int64 and float64 arrays of equal length.
    """
    h, w = shape
    width = 2 * radius + 1
    k = _weights(radius, sigma)
    a = np.deg2rad(angle)
    py, px = width * np.sin(a), width * np.cos(a)
    hyp = math.hypot(py, px)
    dys, dxs = [], []
    for i in range(width):
        dy = -math.ceil(i * py / hyp - 0.5)
        dx = -math.ceil(i * px / hyp - 0.5)
        if abs(dy) >= h or abs(dx) >= w:
            break
        dys.append(dy)
        dxs.append(dx)
    n = len(dys)
    return np.array(dys, np.int64), np.array(dxs, np.int64), k[:n].copy()


@njit
def _shift_sum(img, dys, dxs, ks, out):
    """``out += sum_t ks[t] * img[clamp(row - dys[t]), clamp(col - dxs[t])]`` for an
    H x W x C ``img`` (any real dtype) into a float32 H x W x C ``out``; ``|dxs| < W``."""
    h, w, nch = img.shape
    src_rows = img.reshape(h, w * nch)
    out_rows = out.reshape(h, w * nch)
    for y in range(h):
        o = out_rows[y]
        for t in range(ks.shape[0]):
            sy = min(max(y - dys[t], 0), h - 1)
            src = src_rows[sy]
            k = np.float32(ks[t])
            dx = dxs[t]
            x0 = max(dx, 0)          # first column whose source lies inside the row
            x1 = min(w + dx, w)      # one past the last such column
            # The covered band: a contiguous segment (slices keep numba's indexing
            # wraparound checks out of the loop, so it vectorises).
            dst = o[x0 * nch:x1 * nch]
            seg = src[(x0 - dx) * nch:(x1 - dx) * nch]
            for q in range(dst.shape[0]):
                dst[q] += k * seg[q]
            # The uncovered bands repeat the first / last column.
            for xx in range(x0):
                for c in range(nch):
                    o[xx * nch + c] += k * src[c]
            for xx in range(x1, w):
                for c in range(nch):
                    o[xx * nch + c] += k * src[(w - 1) * nch + c]
    return out


# More taps than any tabulated level has (41): only a severity size's longer streaks are split.
LONG_TAPS = 64


def shift_blur(img: np.ndarray, radius: int, sigma: float, angle: float) -> np.ndarray:
    """The benchmark's ``_motion_blur``: ``sum_i k_i * shift(img, dx_i, dy_i)`` over the
    taps of :func:`motion_taps`, where ``shift`` moves the image by ``dx`` columns and
    ``dy`` rows (positive: right / down) and fills the uncovered band by repeating the
    nearest row or column moved in.

    ``img`` is H x W or H x W x C of any real dtype; returns float32 of the same shape,
    unclipped. A streak of more than :data:`LONG_TAPS` taps is applied as two shorter
    ones (:func:`~._large.split_streak`): the shifts all lead one way, so the replicated
    border of the first is the border of the whole.
    """
    src = np.ascontiguousarray(img)
    flat = src.ndim == 2
    if flat:
        src = src[..., None]
    taps = motion_taps(radius, sigma, angle, src.shape[:2])
    if len(taps[2]) > LONG_TAPS:
        from ._large import split_streak

        first, second = split_streak(*taps)
        src = _shift_sum(src, *first, np.zeros(src.shape, np.float32))
        taps = second
    out = _shift_sum(src, *taps, np.zeros(src.shape, np.float32))
    return out[..., 0] if flat else out


RULES = (ROUND, LINEAR)


def scaled_radius(radius: int, scale: float | None) -> int:
    """A streak's radius in pixels at the severity size's ``scale``: rounded, halves up."""
    return radius if scale is None else int(math.floor(radius * scale + 0.5))


@register(("radius", "sigma"), LEVELS, rules=RULES, scaled=True)
def motion_blur(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """:func:`shift_blur` of the 0..255 image with ``(radius, sigma)`` of the level and an
    angle drawn uniformly from [-45, 45) degrees; clipped to [0, 255] and truncated.

    Size rule: without a severity size (as imagecorruptions-imaug 1.1.5) the radius is in
    pixels whatever the image size (a 2048-wide frame is blurred over the same 21..41
    pixels as a 640-wide one); with one, ``radius`` (rounded, halves up) and ``sigma`` are
    multiplied by its ``scale``. The taps stop at the first shift that reaches the image's
    height or width, which only matters for images smaller than the kernel (e.g. 37 x 53
    at level 5).

    Between integer levels: ``sigma`` linear; ``radius`` linear, rounded to the nearest
    integer (halves up). The angle is drawn the same way at every level."""
    radius, sigma = interpolate(LEVELS, level, RULES)
    if scale is not None:
        radius, sigma = scaled_radius(radius, scale), sigma * scale
    angle = rng.uniform(-45, 45)
    return truncate_to_uint8(shift_blur(x, radius, sigma, angle), 1.0)
