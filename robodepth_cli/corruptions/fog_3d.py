"""Fog that thickens with distance: Koschmieder's law on the scene's depth."""

from __future__ import annotations

import math

import numpy as np

from .depth import round_to_uint8
from .registry import register
from .severity import interpolate

# Meteorological visibility V in metres per level: 'fog' is V < 1 km; 300 m is light fog
# over a street, 20 m a dense bank. KITTI's depths reach 80 m, so every level hides its far
# field and levels 4-5 its middle distance; NYU's rooms (0.5-10 m) fade only from level 4.
VISIBILITY = (300.0, 150.0, 75.0, 40.0, 20.0)

# Koschmieder: an object's contrast falls to 2 % (the visibility threshold) at V, so
# beta = -ln(0.02) / V.
KOSCHMIEDER = -math.log(0.02)  # 3.912

AIRLIGHT = 0.8 * 255.0  # the horizon's brightness under overcast fog, a light grey


@register(("visibility_m",), VISIBILITY, deterministic=True, depth=True)
def fog_3d(x: np.ndarray, depth: np.ndarray, level, rng: np.random.Generator) -> np.ndarray:
    """Fog by depth: transmission ``t = exp(-beta d)`` with ``beta = 3.912 / V`` (V the
    visibility in metres, where contrast falls to 2 %), ``I = J t + A (1 - t)`` per channel
    with airlight ``A = 0.8 * 255``, computed in float64 and rounded to the nearest level.

    Between integer levels: ``V`` linear."""
    beta = KOSCHMIEDER / interpolate(VISIBILITY, level)
    t = np.exp(-beta * depth.astype(np.float64))[:, :, None]
    return round_to_uint8(x * t + AIRLIGHT * (1.0 - t))
