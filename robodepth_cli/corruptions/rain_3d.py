"""Rain by depth: falling drops in the 3D space in front of the camera, drawn as the
streaks an exposure records (Garg & Nayar's model of rain in images), hidden by the scene
where they are behind it."""

from __future__ import annotations

import math

import numpy as np

from .depth import round_to_uint8
from .registry import register
from .severity import interpolate

# Rain rate in mm/h per level: moderate (5, 10), heavy (25, 50: the heaviest hour of a
# year in many climates) and a cloudburst (100).
RATE = (5.0, 10.0, 25.0, 50.0, 100.0)

D_MIN = 1.0  # mm: the drops drawn; smaller ones make streaks too faint to see
Z_NEAR, Z_FAR = 0.5, 10.0  # m: the drops drawn; beyond 10 m a streak is under 0.1 px wide
EXPOSURE = 1 / 250  # s
FOCAL = 0.8  # focal length in image widths (a 64-degree horizontal field of view)
DROP = 0.8 * 255.0  # a drop refracts the whole sky: as bright as fog_3d's airlight
WIND = 15.0  # degrees: the streaks' tilt from vertical is uniform within +-WIND


def drops(rate: float) -> tuple[float, float, float]:
    """``(n, D, v)`` of rain at ``rate`` mm/h: drops larger than :data:`D_MIN` per m^3 and
    their mean diameter in mm under Marshall-Palmer's ``N(D) = 8000 exp(-L D)`` per m^3 per
    mm, ``L = 4.1 rate^-0.21`` per mm; their terminal speed in m/s (Atlas et al.'s fit of
    Gunn and Kinzer, ``v = 9.65 - 10.3 exp(-0.6 D)``)."""
    lam = 4.1 * rate ** -0.21
    n = 8000.0 / lam * math.exp(-lam * D_MIN)
    d = D_MIN + 1.0 / lam
    return n, d, 9.65 - 10.3 * math.exp(-0.6 * d)


@register(("rain_mm_per_h",), RATE, depth=True)
def rain_3d(x: np.ndarray, depth: np.ndarray, level, rng: np.random.Generator) -> np.ndarray:
    """Rain streaks by depth. Drops (Marshall-Palmer, diameter ``D`` > 1 mm, density ``n``,
    speed ``v``: :func:`drops`) fill the camera's view between 0.5 and 10 m uniformly in
    space: a Poisson number of them, ``n (W/f)(H/f)(Z1^3 - Z0^3) / 3``, with depth ``z``
    drawn with density proportional to ``z^2``, image position uniform, ``f = 0.8 W``
    pixels. Over an exposure ``T = 1/250`` s a drop at ``z`` draws a streak ``f v T / z``
    pixels long, tilted by one wind angle per image (uniform within 15 degrees), with
    opacity ``D / (v T)`` on each pixel it crosses (the share of the exposure it spends
    there) times ``min(1, f D / z)`` (a drop narrower than a pixel covers that part of it),
    where the scene is farther than the drop. Opacities add, capped at 1; the image goes
    towards the drop brightness ``0.8 * 255`` by them, rounded to the nearest level.

    Between integer levels: the rain rate linear."""
    h, w = x.shape[:2]
    n, dia, v = drops(interpolate(RATE, level))
    f = FOCAL * w
    count = rng.poisson(n * (w / f) * (h / f) * (Z_FAR ** 3 - Z_NEAR ** 3) / 3.0)
    z = np.cbrt(Z_NEAR ** 3 + rng.random(count) * (Z_FAR ** 3 - Z_NEAR ** 3))
    cx, cy = rng.uniform(0, w, count), rng.uniform(0, h, count)
    tilt = math.radians(rng.uniform(-WIND, WIND))
    length = f * v * EXPOSURE / z
    opacity = dia / 1000.0 / (v * EXPOSURE) * np.minimum(1.0, f * dia / 1000.0 / z)
    # each streak: one point per pixel of its length, centred on the drop's mid-exposure place
    steps = np.ceil(length).astype(np.intp) + 1
    which = np.repeat(np.arange(count), steps)
    t = np.arange(which.size) - np.repeat(np.cumsum(steps) - steps, steps)
    t = t / np.maximum(steps[which] - 1, 1) - 0.5
    py = np.floor(cy[which] + t * length[which] * math.cos(tilt)).astype(np.intp)
    px = np.floor(cx[which] + t * length[which] * math.sin(tilt)).astype(np.intp)
    inside = (py >= 0) & (py < h) & (px >= 0) & (px < w)
    which, py, px = which[inside], py[inside], px[inside]
    seen = depth[py, px] > z[which]
    cells = py[seen] * w + px[seen]
    alpha = np.minimum(np.bincount(cells, weights=opacity[which[seen]], minlength=h * w), 1.0)
    a = alpha.reshape(h, w, 1)
    return round_to_uint8(x * (1.0 - a) + DROP * a)
