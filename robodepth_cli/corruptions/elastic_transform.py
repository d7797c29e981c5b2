"""Elastic transform (SPEC section 2, definition 11)."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from ._ops import gaussian, to_uint8
from .registry import SENSOR, register

LEVELS = (0.05, 0.065, 0.085, 0.1, 0.12)


@lru_cache(maxsize=16)
def _grid(h: int, w: int) -> np.ndarray:
    """H x W x 2 float32 of (column, row): the identity map of ``cv2.remap``."""
    g = np.empty((h, w, 2), np.float32)
    g[..., 0] = np.arange(w, dtype=np.float32)
    g[..., 1] = np.arange(h, dtype=np.float32)[:, None]
    g.flags.writeable = False
    return g


def displacement(shape: tuple[int, int], k: float, rng: np.random.Generator) -> np.ndarray:
    """The smoothed random displacement field of an H x W image: float32 H x W x 2 holding
    ``(dx, dy)``.

    ``m = 0.005 * H`` for both directions; ``U(-m, m)`` of H x W is drawn for ``dx`` first,
    then for ``dy``; each is smoothed with ``gaussian(sigma=(0.01 H, 0.01 W),
    mode='reflect', truncate=3)`` and multiplied by ``alpha = 250 * k``. (The uniforms are
    drawn on [0, 1) and mapped to [-m, m) after the smoothing, which is linear and keeps
    constants: the same field, one pass fewer.)
    """
    h, w = shape
    m = 0.005 * h
    alpha = 250 * k
    u = rng.random((2, h, w), dtype=np.float32)
    smooth = gaussian(cv2.merge([u[0], u[1]]), (0.01 * h, 0.01 * w), truncate=3, mode="reflect")
    smooth -= np.float32(0.5)
    smooth *= np.float32(2 * m * alpha)
    return smooth


@register(SENSOR, ("k",), LEVELS)
def elastic_transform(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Resample every channel at ``(row + dy, col + dx)`` with the field of
    :func:`displacement` (``k`` of the level), bilinear with a half-sample symmetric
    border (SciPy ``map_coordinates(order=1, mode='reflect')`` = OpenCV
    ``BORDER_REFLECT``); clipped and truncated. Done by ``cv2.remap`` on the 0..255 values
    in float32.
    """
    h, w = x.shape[:2]
    coords = displacement((h, w), LEVELS[level - 1], rng)
    coords += _grid(h, w)
    out = cv2.remap(x.astype(np.float32), coords, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return to_uint8(out, 1.0)
