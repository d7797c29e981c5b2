import numpy as np

from ._ops import to_uint8
from .registry import DATA, register

LEVELS = (0.08, 0.12, 0.18, 0.26, 0.38)


@register(DATA, ("sigma",), LEVELS)
def gaussian_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Additive white noise: ``clip01(f + Normal(0, sigma))`` per pixel and channel,
    truncated to uint8."""
    sigma = LEVELS[level - 1]
    noise = rng.standard_normal(x.shape, dtype=np.float32)
    noise *= np.float32(sigma)
    noise += x * np.float32(1 / 255)
    return to_uint8(noise)
