import numpy as np

from ._ops import to_uint8
from .registry import WEATHER, register

LEVELS = (0.1, 0.2, 0.3, 0.4, 0.5)


@register(WEATHER, ("c",), LEVELS, deterministic=True)
def brightness(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Raise the HSV value: ``V' = clip01(V + c)`` with hue and saturation kept.

    In scikit-image's HSV convention every RGB channel is ``V`` times a function of
    (H, S), so the round trip ``hsv2rgb(H, S, V')`` is ``f * V' / V``; a black pixel
    (V = 0, S = 0) becomes the gray ``V' = c``. Result truncated to uint8.
    """
    c = LEVELS[level - 1]
    f = x / 255.0
    v = f.max(axis=2, keepdims=True)
    v_new = np.minimum(v + c, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(v > 0, f * (v_new / v), v_new)
    return to_uint8(out)
