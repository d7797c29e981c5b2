from functools import lru_cache

import numpy as np

from ._sampling import N_VALUES, ValueTable, gaussian_truncated_cdf
from .registry import register
from .severity import interpolate

LEVELS = (0.08, 0.12, 0.18, 0.26, 0.38)


@lru_cache(maxsize=None)
def output_law(level) -> ValueTable:
    """Law of one output element given its input value ``k``: ``floor(clip01(k / 255 + z) * 255)``
    with ``z ~ Normal(0, sigma)``."""
    return ValueTable(gaussian_truncated_cdf(np.arange(N_VALUES) / 255.0, interpolate(LEVELS, level)))


@register(("sigma",), LEVELS)
def gaussian_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Additive white noise: ``clip01(f + Normal(0, sigma))`` per pixel and channel,
    independently, truncated to uint8.

    Each element is drawn directly from that formula's exact output law given its input
    value (:func:`output_law`, inverse transform of one uniform; see ``_sampling``).

    Between integer levels: ``sigma`` linear."""
    return output_law(level).sample(x, rng)
