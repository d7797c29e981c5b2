import numpy as np

from .registry import register
from .severity import interpolate

LEVELS = (0.03, 0.06, 0.09, 0.17, 0.27)


@register(("amount",), LEVELS)
def impulse_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Salt and pepper on every element (pixel and channel independently): with probability
    ``amount`` it is replaced, by 255 or by 0 with equal odds (scikit-image
    ``random_noise(mode='s&p', salt_vs_pepper=0.5)``).

    One uniform ``u`` per element decides both: ``u < amount / 2`` gives 0,
    ``amount / 2 <= u < amount`` gives 255.

    Between integer levels: ``amount`` linear."""
    amount = interpolate(LEVELS, level)
    u = rng.random(x.shape, dtype=np.float32)
    replaced = np.where(u < amount * 0.5, np.uint8(0), np.uint8(255))
    return np.where(u < amount, replaced, x)
