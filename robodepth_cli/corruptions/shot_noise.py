import numpy as np

from ._ops import to_uint8
from .registry import DATA, register

LEVELS = (60, 25, 12, 5, 3)


@register(DATA, ("lambda",), LEVELS)
def shot_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Photon noise: ``clip01(Poisson(f * lambda) / lambda)``, truncated to uint8."""
    lam = LEVELS[level - 1]
    counts = rng.poisson(x * (lam / 255.0))
    return to_uint8(counts, 255.0 / lam)
