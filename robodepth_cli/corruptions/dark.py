from functools import lru_cache

import numpy as np

from ._sampling import N_VALUES, ValueTable, poisson_gaussian_law
from .registry import register
from .severity import interpolate

LEVELS = (0.60, 0.50, 0.40, 0.30, 0.20)
_PHOTONS = (60, 25, 12, 5, 3)
_READ_NOISE = (0.08, 0.12, 0.18, 0.26, 0.38)
_TABLE = tuple(zip(LEVELS, _PHOTONS, _READ_NOISE))


@lru_cache(maxsize=16)  # keyed by the image extremes: (0, 255) on every fixture frame
def output_law(level, lo: int, hi: int) -> ValueTable:
    """Law of one output element given its input value ``k``, for an image whose values
    span ``lo..hi``: with ``n = ((k - lo) / (hi - lo))**2 * c`` (0 if ``hi == lo``),
    ``u = clip01(Poisson(n * p) / p)``, ``floor(clip01(u + Normal(0, g)) * 255)``."""
    c, photons, noise = interpolate(_TABLE, level)
    p, g = 10 * photons, 0.1 * noise
    # Rows outside lo..hi never occur in the image; clipping keeps their rates (and the
    # Poisson support of the table) within those of the image.
    f = np.clip(np.arange(N_VALUES), lo, hi) / 255.0
    if hi > lo:
        n = ((f - lo / 255.0) / (hi / 255.0 - lo / 255.0)) ** 2 * c
    else:
        n = np.zeros(N_VALUES)
    return poisson_gaussian_law(n * p, p, g)


@register(("c",), LEVELS)
def dark(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Low light: ``n = ((f - min f) / (max f - min f))**2 * c`` (min and max over all
    pixels and channels; a constant image gives ``n = 0``), then Poisson-Gaussian sensor
    noise with ``i = level - 1``: ``p = 10 * [60, 25, 12, 5, 3][i]``,
    ``u = clip01(Poisson(n * p) / p)``, ``g = 0.1 * [.08, .12, .18, .26, .38][i]``,
    ``v = clip01(u + Normal(0, g))`` per pixel and channel, independently; truncated to
    uint8.

    Each element is drawn directly from that formula's exact output law given its input
    value (:func:`output_law`, inverse transform of one uniform; see ``_sampling``).

    Between integer levels: ``c``, the photon count and the read noise each linear (the
    Poisson rate takes a fractional photon count as it is)."""
    return output_law(level, int(x.min()), int(x.max())).sample(x, rng)
