import numpy as np

from ._ops import to_uint8
from .registry import DATA, register

LEVELS = tuple(round(0.7 * s, 6) for s in (0.08, 0.12, 0.18, 0.26, 0.38))


@register(DATA, ("sigma",), LEVELS)
def iso_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Sensor noise at high ISO: photon noise ``u = clip01(Poisson(f * 25) / 25)``, then
    ``clip01(u + Normal(0, sigma))`` per pixel and channel, truncated to uint8."""
    sigma = LEVELS[level - 1]
    u = rng.poisson(x * (25 / 255.0)).astype(np.float32)
    u *= np.float32(1 / 25)
    np.minimum(u, 1.0, out=u)
    noise = rng.standard_normal(x.shape, dtype=np.float32)
    noise *= np.float32(sigma)
    noise += u
    return to_uint8(noise)
