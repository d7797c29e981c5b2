"""Forward camera motion during the exposure: a zoom whose strength follows depth."""

from __future__ import annotations

import numpy as np

from .depth import round_to_uint8
from ._warp import exposure
from .registry import register
from .severity import interpolate

# T: the forward path's length as a fraction of the median depth. At the median a pixel
# at radius rho spreads over rho * (1/(1 - T/2) - 1/(1 + T/2)): level 5 (0.16) as much as
# zoom_blur's level 2 (factors up to 1.16) there, nearer things (KITTI's road, NYU's
# floor) much more.
TRAVEL = (0.04, 0.07, 0.10, 0.13, 0.16)


@register(("travel",), TRAVEL, deterministic=True, depth=True)
def zoom_3d(x: np.ndarray, depth: np.ndarray, level, rng: np.random.Generator) -> np.ndarray:
    """Forward motion: the mean of the frames seen by a camera moving along its
    axis by ``o T Zm`` for offsets ``o`` in [-1/2, 1/2] (``Zm`` the median depth), each a
    z-buffered forward warp ``x' = c + (x - c) Z / (Z - o T Zm)`` about the image centre;
    points reaching the camera leave the view; each pixel the mean of the frames that see
    it (one frame per pixel of the longest path); rounded to the nearest level.

    Between integer levels: ``T`` linear."""
    return round_to_uint8(exposure(x, depth, travel=interpolate(TRAVEL, level)))
