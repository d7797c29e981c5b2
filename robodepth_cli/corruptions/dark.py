import numpy as np

from ._ops import to_uint8
from .registry import WEATHER, register

LEVELS = (0.60, 0.50, 0.40, 0.30, 0.20)
_PHOTONS = (60, 25, 12, 5, 3)
_READ_NOISE = (0.08, 0.12, 0.18, 0.26, 0.38)


@register(WEATHER, ("c",), LEVELS)
def dark(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Low light: ``n = ((f - min f) / (max f - min f))**2 * c`` (min and max over all
    pixels and channels; a constant image gives ``n = 0``), then Poisson-Gaussian sensor
    noise with ``i = level - 1``: ``p = 10 * [60, 25, 12, 5, 3][i]``,
    ``u = clip01(Poisson(n * p) / p)``, ``g = 0.1 * [.08, .12, .18, .26, .38][i]``,
    ``v = clip01(u + Normal(0, g))``; truncated to uint8."""
    c = LEVELS[level - 1]
    p = 10 * _PHOTONS[level - 1]
    g = 0.1 * _READ_NOISE[level - 1]
    lo, hi = int(x.min()), int(x.max())
    if hi > lo:
        n = ((x - lo) * (1.0 / (hi - lo))) ** 2 * c
    else:
        n = np.zeros(x.shape)
    u = rng.poisson(n * p).astype(np.float32)
    u *= np.float32(1 / p)
    np.minimum(u, 1.0, out=u)
    noise = rng.standard_normal(x.shape, dtype=np.float32)
    noise *= np.float32(g)
    noise += u
    return to_uint8(noise)
