"""The one registry of corruptions, shared by the CLI, the builder, the docs and the tests.

Each corruption module defines a pure function ``name(x, level, rng) -> uint8 image`` and
registers it with :func:`register`, declaring its category and the parameter table of
SPEC section 2 (one entry per level, levels 1..5).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

WEATHER = "weather & lighting"
SENSOR = "sensor & movement"
DATA = "data & processing"
CATEGORIES = (WEATHER, SENSOR, DATA)

# SPEC section 2 order; the registry is listed in this order whatever the import order.
ORDER = (
    "brightness", "dark", "fog", "frost", "snow", "contrast",
    "defocus_blur", "glass_blur", "motion_blur", "zoom_blur", "elastic_transform",
    "color_quant",
    "gaussian_noise", "impulse_noise", "shot_noise", "iso_noise", "pixelate",
    "jpeg_compression",
)

CorruptionFn = Callable[[np.ndarray, int, np.random.Generator], np.ndarray]


@dataclass(frozen=True)
class Corruption:
    name: str
    category: str
    fields: tuple[str, ...]
    levels: tuple  # one parameter entry per level, levels 1..len(levels)
    deterministic: bool
    fn: CorruptionFn
    doc: str

    @property
    def n_levels(self) -> int:
        return len(self.levels)

    def params(self, level: int) -> dict:
        """The named parameters of ``level`` (1-based)."""
        entry = self.levels[level - 1]
        # With one field the entry is the value itself, even when that value is a sequence
        # (zoom_blur's factor sets).
        values = (entry,) if len(self.fields) == 1 else entry
        return dict(zip(self.fields, values))


_REGISTRY: dict[str, Corruption] = {}


def register(category: str, fields: Sequence[str], levels: Sequence, *, deterministic: bool = False):
    """Decorator: add a corruption function to the registry under its own name."""
    if category not in CATEGORIES:
        raise ValueError(f"unknown category {category!r}")

    def decorate(fn: CorruptionFn) -> CorruptionFn:
        name = fn.__name__
        if name not in ORDER:
            raise ValueError(f"{name!r} is not a SPEC corruption")
        if name in _REGISTRY:
            raise ValueError(f"{name!r} registered twice")
        _REGISTRY[name] = Corruption(
            name=name,
            category=category,
            fields=tuple(fields),
            levels=tuple(levels),
            deterministic=deterministic,
            fn=fn,
            doc=(fn.__doc__ or "").strip(),
        )
        return fn

    return decorate


def registry() -> dict[str, Corruption]:
    """All registered corruptions, in SPEC order."""
    return {name: _REGISTRY[name] for name in ORDER if name in _REGISTRY}
