"""Contrast: pull every channel towards its mean."""

from __future__ import annotations

import cv2
import numpy as np

from ._ops import truncate_to_uint8
from .registry import register
from .severity import interpolate

LEVELS = (0.4, 0.3, 0.2, 0.1, 0.05)

_VALUES = np.arange(256, dtype=np.float64)[:, None] / 255.0


@register(("c",), LEVELS, deterministic=True)
def contrast(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """``clip01((f - m) * c + m)`` truncated to uint8, ``m`` the per-channel mean of
    ``f = x / 255``.

    The output of a channel depends only on that channel's value, so the formula is
    evaluated in float64 once per value (a 256-entry table per channel) and applied with
    ``cv2.LUT``.

    Between integer levels: ``c`` linear.
    """
    c = interpolate(LEVELS, level)
    m = np.asarray(cv2.mean(np.ascontiguousarray(x))[:3], dtype=np.float64) / 255.0
    table = truncate_to_uint8((_VALUES - m) * c + m)
    return cv2.LUT(x, table.reshape(256, 1, 3))
