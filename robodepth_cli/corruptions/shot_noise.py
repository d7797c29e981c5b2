from functools import lru_cache

import numpy as np

from ._sampling import N_VALUES, ValueTable, poisson_pmf, truncated_value
from .registry import register
from .severity import interpolate

LEVELS = (60, 25, 12, 5, 3)


@lru_cache(maxsize=None)
def output_law(level) -> ValueTable:
    """Law of one output element given its input value ``k``:
    ``floor(clip01(Poisson(k / 255 * lambda) / lambda) * 255)``."""
    lam = interpolate(LEVELS, level)
    pmf = poisson_pmf(np.arange(N_VALUES) / 255.0 * lam)
    out = truncated_value(np.arange(pmf.shape[1]) / float(lam))  # non-decreasing in the count
    # P(output <= j) = P(count <= last count whose output is <= j)
    last = np.searchsorted(out, np.arange(N_VALUES), side="right") - 1
    cdf = np.cumsum(pmf, axis=1)
    return ValueTable(np.where(last >= 0, cdf[:, np.maximum(last, 0)], 0.0))


@register(("lambda",), LEVELS)
def shot_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Photon noise: ``clip01(Poisson(f * lambda) / lambda)`` per pixel and channel,
    independently, truncated to uint8.

    Each element is drawn directly from that formula's exact output law given its input
    value (:func:`output_law`, inverse transform of one uniform; see ``_sampling``).

    Between integer levels: ``lambda`` linear (a fractional photon count is used as it is)."""
    return output_law(level).sample(x, rng)
