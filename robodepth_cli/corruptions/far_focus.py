"""Far focus: a thin lens focused on the far part of the scene, the near objects blurred."""

from __future__ import annotations

import numpy as np

from .near_focus import RADIUS, focused
from .registry import register

FOCUS_PERCENTILE = 90.0  # focused on the depth farther than 90 % of the pixels


@register(("radius_px",), RADIUS, deterministic=True, depth=True, scaled=True)
def far_focus(x: np.ndarray, depth: np.ndarray, level, rng: np.random.Generator,
              scale: float | None = None) -> np.ndarray:
    """Thin-lens defocus focused far: focal distance ``f`` = the 90th percentile of the
    depth; blur radius ``r(d) = R * min(1, |d - f| / d)`` pixels (``R`` reached from
    ``d = f / 2`` nearer), ``R`` scaled by ``W / 640`` (with a severity size: by its scale); rendered in depth layers back to
    front, a blurred near object spreading over the background as through a real lens;
    rounded to the nearest level.

    Between integer levels: ``R`` linear."""
    return focused(x, depth, level, FOCUS_PERCENTILE, RADIUS, scale)
