import numpy as np

from ._jit import njit
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
    # numpy compares float32 with a Python float in float32, so the thresholds are rounded
    # to float32 here, for the same decisions.
    out = np.empty(x.shape, np.uint8)
    _salt_and_pepper(np.ascontiguousarray(x).reshape(-1), u.reshape(-1),
                     np.float32(amount * 0.5), np.float32(amount), out.reshape(-1))
    return out


@njit
def _salt_and_pepper(x, u, pepper, replaced, out):
    """``out = (u < pepper ? 0 : 255) if u < replaced else x``, element by element."""
    for i in range(x.size):
        v = np.uint8(0) if u[i] < pepper else np.uint8(255)
        out[i] = v if u[i] < replaced else x[i]
    return out
