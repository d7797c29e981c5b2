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


def width_scale(x: np.ndarray, scale: float | None) -> float:
    """What the depth-aware corruptions' pixel parameters (tabulated at 640 pixels wide,
    the width of both benchmarks' severity sizes) are multiplied by: ``W / 640``, or with
    a severity size its ``scale``."""
    return x.shape[1] / 640.0 if scale is None else scale


def focused(x: np.ndarray, depth: np.ndarray, level, percentile: float, table,
            scale: float | None = None) -> np.ndarray:
    """``x`` through the thin lens of :mod:`._lens` focused at ``percentile`` of the depth,
    with the level's radius (of ``table``) times :func:`width_scale`."""
    radius = interpolate(table, level) * width_scale(x, scale)
    focus = float(np.percentile(depth, percentile))
    return round_to_uint8(lens_blur(x, depth, focus, radius))


@register(("radius_px",), RADIUS, deterministic=True, depth=True, scaled=True)
def near_focus(x: np.ndarray, depth: np.ndarray, level, rng: np.random.Generator,
               scale: float | None = None) -> np.ndarray:
    """Thin-lens defocus focused near: focal distance ``f`` = the 10th percentile of the
    depth; blur radius ``r(d) = R * min(1, |d - f| / d)`` pixels, ``R`` scaled by
    ``W / 640`` (with a severity size: by its scale); rendered in depth layers back to front (no bleeding of a sharp object over
    its blurred surroundings); rounded to the nearest level.

    Between integer levels: ``R`` linear."""
    return focused(x, depth, level, FOCUS_PERCENTILE, RADIUS, scale)
