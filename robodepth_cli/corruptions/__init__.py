"""The 18 corruptions of the RoboDepth benchmark.

``REGISTRY`` maps each name, in benchmark order, to its :class:`Corruption` record (category,
parameter table, function). :func:`corrupt` is the checked entry point.
"""

from __future__ import annotations

import numpy as np

from ..benchmarks import CATEGORIES, DATA, SENSOR, WEATHER
from ..imageio import as_rgb
from .registry import Corruption, registry

# Importing a module registers its corruption(s).
from . import (  # noqa: F401  (imported for registration)
    brightness, dark, fog, frost, snow, contrast,
    defocus_blur, glass_blur, motion_blur, zoom_blur, elastic_transform, color_quant,
    gaussian_noise, impulse_noise, shot_noise, iso_noise, pixelate, jpeg_compression,
)

REGISTRY: dict[str, Corruption] = registry()
NAMES: tuple[str, ...] = tuple(REGISTRY)

__all__ = ["REGISTRY", "NAMES", "CATEGORIES", "WEATHER", "SENSOR", "DATA", "Corruption",
           "corrupt", "get", "check_level"]


def get(name: str) -> Corruption:
    """The registry record of ``name``; ``ValueError`` listing the valid names otherwise."""
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown corruption {name!r}; valid: {', '.join(NAMES)}") from None


def check_level(corruption: Corruption, level) -> int:
    if isinstance(level, (bool, np.bool_)) or not isinstance(level, (int, np.integer)):
        raise ValueError(f"level must be an integer, got {level!r}")
    if not 1 <= level <= corruption.n_levels:
        raise ValueError(f"level {level} out of range for {corruption.name}: 1..{corruption.n_levels}")
    return int(level)


def corrupt(image: np.ndarray, name: str, level: int, rng: np.random.Generator) -> np.ndarray:
    """Apply corruption ``name`` at ``level`` to ``image``.

    ``image`` is uint8 RGB H x W x 3 with H, W >= 32; grayscale and RGBA are converted.
    All randomness comes from ``rng`` (a ``numpy.random.Generator``). Returns a new uint8
    H x W x 3 array; the input is never modified.
    """
    c = get(name)
    level = check_level(c, level)
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    x = as_rgb(image).view()
    x.flags.writeable = False  # corruption functions are pure: writing to the input fails loudly
    out = c.fn(x, level, rng)
    if out.dtype != np.uint8 or out.shape != x.shape:
        raise AssertionError(f"{name} returned {out.dtype} {out.shape} for {x.shape}")
    return out
