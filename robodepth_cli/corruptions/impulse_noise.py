import numpy as np

from .registry import DATA, register

LEVELS = (0.03, 0.06, 0.09, 0.17, 0.27)


@register(DATA, ("amount",), LEVELS)
def impulse_noise(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Salt and pepper on every element (pixel and channel independently): with probability
    ``amount`` it is replaced, by 255 or by 0 with equal odds (scikit-image
    ``random_noise(mode='s&p', salt_vs_pepper=0.5)``)."""
    amount = LEVELS[level - 1]
    u = rng.random(x.shape, dtype=np.float32)
    out = x.copy()
    # One uniform per element decides both whether and how it is replaced.
    out[u < amount * 0.5] = 0
    out[(u >= amount * 0.5) & (u < amount)] = 255
    return out
