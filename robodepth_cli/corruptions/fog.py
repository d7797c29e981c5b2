import numpy as np

from .registry import WEATHER, register

LEVELS = ()  # TODO(helper): SPEC section 2 table


@register(WEATHER, (), LEVELS)
def fog(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Not implemented yet."""
    raise NotImplementedError("fog")
