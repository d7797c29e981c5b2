"""Near focus: a thin lens focused on the near part of the scene, the distance blurred."""

from __future__ import annotations

import numpy as np

from .depth import round_to_uint8
from ._lens import lens_blur
from .registry import register
from .severity import interpolate

# R: blur radius in pixels (at 640 pixels wide) of a point at infinity; the defocus_blur
# radii of the 18, so the strongest blur matches the 2D corruption it extends.
RADIUS = (3.0, 4.0, 6.0, 8.0, 10.0)
FOCUS_PERCENTILE = 10.0  # focused on the depth nearer than 90 % of the pixels


def focused(x: np.ndarray, depth: np.ndarray, level, percentile: float, table) -> np.ndarray:
    """``x`` through the thin lens of :mod:`._lens` focused at ``percentile`` of the depth,
    with the level's radius (of ``table``) scaled to the image width."""
    radius = interpolate(table, level) * x.shape[1] / 640.0
    focus = float(np.percentile(depth, percentile))
    return round_to_uint8(lens_blur(x, depth, focus, radius))


@register(("radius_px",), RADIUS, deterministic=True, depth=True)
def near_focus(x: np.ndarray, depth: np.ndarray, level, rng: np.random.Generator) -> np.ndarray:
    """Thin-lens defocus focused near: focal distance ``f`` = the 10th percentile of the
    depth; blur radius ``r(d) = R * min(1, |d - f| / d)`` pixels, ``R`` scaled by
    ``W / 640``; rendered in depth layers back to front (no bleeding of a sharp object over
    its blurred surroundings); rounded to the nearest level.

    Between integer levels: ``R`` linear."""
    return focused(x, depth, level, FOCUS_PERCENTILE, RADIUS)
