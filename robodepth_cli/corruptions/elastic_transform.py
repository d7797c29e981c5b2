import numpy as np

from .registry import SENSOR, register

LEVELS = ()  # TODO(helper): SPEC section 2 table


@register(SENSOR, (), LEVELS)
def elastic_transform(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Not implemented yet."""
    raise NotImplementedError("elastic_transform")
