"""Elastic transform."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ._exact import remap_reflect
from ._ops import gaussian
from .registry import register
from .severity import interpolate

LEVELS = (0.05, 0.065, 0.085, 0.1, 0.12)


@lru_cache(maxsize=4)  # 64 MB at 2048 x 4096: a few sizes only
def _offset_grid(h: int, w: int, shift: float) -> np.ndarray:
    """H x W x 2 float32 of ``(column - shift, row - shift)``: the identity map moved by a
    constant."""
    g = np.empty((h, w, 2), np.float32)
    g[..., 0] = np.arange(w, dtype=np.float64) - shift
    g[..., 1] = np.arange(h, dtype=np.float64)[:, None] - shift
    g.flags.writeable = False
    return g


def smoothed_uniforms(shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Two H x W fields of ``U(0, 1)``, the first for ``dx`` drawn first, each smoothed with
    ``gaussian(sigma=(0.01 H, 0.01 W), mode='reflect', truncate=3)``: float32 H x W x 2."""
    h, w = shape
    u = rng.random((2, h, w), dtype=np.float32)
    return gaussian(np.stack([u[0], u[1]], axis=-1), (0.01 * h, 0.01 * w), truncate=3, mode="reflect")


@register(("k",), LEVELS, scaled=True)
def elastic_transform(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """Random elastic warp. ``m = 0.005 * H`` for both directions; ``U(-m, m)`` fields of
    H x W for ``dx`` (drawn first) and ``dy``, each smoothed with ``gaussian(sigma=(0.01 H,
    0.01 W), mode='reflect', truncate=3)`` and multiplied by ``alpha = 250 * k``; every
    channel is resampled at ``(row + dy, col + dx)``, bilinear with a half-sample symmetric
    border (SciPy ``map_coordinates(order=1, mode='reflect')`` = OpenCV
    ``BORDER_REFLECT``); clipped and truncated.

    Size rule (as imagecorruptions-imaug 1.1.5): the smoothing sigma is 1% of the height
    and width and the amplitude ``0.005 H * 250 k`` grows with the height, but smoothing
    white noise over ``sigma`` pixels shrinks it as ``1 / sigma``: the displacement stays
    the same number of pixels at any size. With a severity size the amplitude is also
    multiplied by its ``scale``, so the displacement is a fixed share of the image.

    The uniforms are drawn on [0, 1) and mapped to [-m, m) after the smoothing, which is
    linear and keeps constants: ``alpha * gaussian(U(-m, m)) = 2 m alpha * gaussian(U(0, 1))
    - m alpha``, folded into the sampling coordinates. The resampling lerps the 0..255
    values at the float32 coordinates in float32 with fused multiply-adds, as OpenCV's
    ``remap`` does on a CPU with FMA (:func:`~._exact.remap_reflect`, the same bits on any
    CPU).

    Between integer levels: ``k`` linear.
    """
    h, w = x.shape[:2]
    m_alpha = 0.005 * h * 250 * interpolate(LEVELS, level)
    if scale is not None:
        m_alpha *= scale
    coords = smoothed_uniforms((h, w), rng)
    coords *= np.float32(2 * m_alpha)
    coords += _offset_grid(h, w, m_alpha)
    return remap_reflect(x, coords)
