import numpy as np

from ._ops import truncate_to_uint8
from .registry import register
from .severity import BLEND, Blend, interpolate

LEVELS = (5, 4, 3, 2, 1)


def posterize(x: np.ndarray, bits: int) -> np.ndarray:
    """``x & ~(2**(8 - bits) - 1)``: the top ``bits`` bits of every value."""
    mask = np.uint8((0xFF << (8 - bits)) & 0xFF)
    return np.bitwise_and(x, mask)


@register(("bits",), LEVELS, rules=(BLEND,), deterministic=True)
def color_quant(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Keep the top ``bits`` bits of every channel value (Pillow's ``ImageOps.posterize``):
    ``x & ~(2**(8 - bits) - 1)``. Already uint8, so there is no rounding step.

    Between integer levels (``bits`` has no value in between): the blend
    ``(1 - t) * posterize(x, bits_i) + t * posterize(x, bits_{i+1})`` of the two
    neighbouring levels, ``t`` the fractional part of the level, truncated to uint8. Both
    only clear low bits, so every value moves monotonically from one to the other."""
    bits = interpolate(LEVELS, level, (BLEND,))
    if not isinstance(bits, Blend):
        return posterize(x, bits)
    # The output depends on the value alone: blend the 256 values once, then look them up.
    values = np.arange(256, dtype=np.uint8)
    mixed = (1.0 - bits.t) * posterize(values, bits.lower) + bits.t * posterize(values, bits.upper)
    return truncate_to_uint8(mixed, 1.0)[x]
