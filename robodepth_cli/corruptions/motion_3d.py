"""Sideways camera motion during the exposure: parallax blur from the scene's depth."""

from __future__ import annotations

import numpy as np

from .depth import round_to_uint8
from ._warp import exposure
from .near_focus import width_scale
from .registry import register
from .severity import interpolate

# D: the path's length in pixels (at 640 wide) at the median depth; nearer things move
# more (D * Zm / Z). The spread of motion_blur's kernels in the 18 (about 6 to 30 pixels).
SHIFT = (6.0, 10.0, 15.0, 21.0, 28.0)


@register(("shift_px",), SHIFT, deterministic=True, depth=True, scaled=True)
def motion_3d(x: np.ndarray, depth: np.ndarray, level, rng: np.random.Generator,
              scale: float | None = None) -> np.ndarray:
    """Sideways motion: the mean of the frames seen by a camera moving horizontally
    along a path centred on the capture, each a z-buffered forward warp with depth
    ``Z``: ``x' = x - o D Zm / Z`` for offsets ``o`` in [-1/2, 1/2], ``D`` pixels (scaled by
    ``W / 640``; with a severity size, by its scale) at the median depth ``Zm``; each pixel
    the mean of the frames that see it (one frame per pixel of the longest path); rounded
    to the nearest level.

    Between integer levels: ``D`` linear."""
    return round_to_uint8(exposure(x, depth, shift_px=interpolate(SHIFT, level) * width_scale(x, scale)))
