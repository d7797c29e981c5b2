import numpy as np

from ._ops import to_uint8
from .registry import WEATHER, register

LEVELS = (0.4, 0.3, 0.2, 0.1, 0.05)


@register(WEATHER, ("c",), LEVELS, deterministic=True)
def contrast(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Pull every channel towards its mean: ``clip01((f - m) * c + m)``, ``m`` the
    per-channel mean of ``f = x / 255``; truncated to uint8."""
    c = LEVELS[level - 1]
    f = x / 255.0
    m = f.mean(axis=(0, 1), keepdims=True)
    return to_uint8((f - m) * c + m)
