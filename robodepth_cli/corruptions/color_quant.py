import numpy as np

from .registry import register

LEVELS = (5, 4, 3, 2, 1)


@register(("bits",), LEVELS, deterministic=True)
def color_quant(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Keep the top ``bits`` bits of every channel value (Pillow's ``ImageOps.posterize``):
    ``x & ~(2**(8 - bits) - 1)``. Already uint8, so there is no rounding step."""
    bits = LEVELS[level - 1]
    mask = np.uint8((0xFF << (8 - bits)) & 0xFF)
    return np.bitwise_and(x, mask)
