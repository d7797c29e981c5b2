from functools import lru_cache

import numpy as np

from ._sampling import N_VALUES, ValueTable, poisson_gaussian_law
from .registry import register
from .severity import interpolate

LEVELS = tuple(round(0.7 * s, 6) for s in (0.08, 0.12, 0.18, 0.26, 0.38))
_PHOTONS = 25


@lru_cache(maxsize=None)
def output_law(level) -> ValueTable:
    """Law of one output element given its input value ``k``: with
    ``u = clip01(Poisson(k / 255 * 25) / 25)``, ``floor(clip01(u + Normal(0, sigma)) * 255)``."""
    return poisson_gaussian_law(np.arange(N_VALUES) / 255.0 * _PHOTONS, _PHOTONS, interpolate(LEVELS, level))


@register(("sigma",), LEVELS)
def iso_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Sensor noise at high ISO: photon noise ``u = clip01(Poisson(f * 25) / 25)``, then
    ``clip01(u + Normal(0, sigma))`` per pixel and channel, independently, truncated to
    uint8.

    Each element is drawn directly from that formula's exact output law given its input
    value (:func:`output_law`, inverse transform of one uniform; see ``_sampling``).

    Between integer levels: ``sigma`` linear."""
    return output_law(level).sample(x, rng)
