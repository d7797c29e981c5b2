"""The one registry of corruptions, shared by the CLI, the builder, the docs and the tests.

Each corruption module defines a pure function ``name(x, level, rng) -> uint8 image`` (a
depth-aware one ``name(x, depth, level, rng)``, registered with ``depth=True``) and
registers it with :func:`register`, declaring its parameter table (one entry per level,
levels 1..5) and how each parameter is interpolated between levels (:mod:`.severity`). Its category and its place in every listing come from
:mod:`robodepth_cli.benchmark_facts`, which names the corruptions that exist.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..benchmark_facts import ALL_CATEGORY, ALL_CORRUPTIONS, N_LEVELS
from .severity import LINEAR, RULES, interpolate

CorruptionFn = Callable[[np.ndarray, int, np.random.Generator], np.ndarray]


@dataclass(frozen=True)
class Corruption:
    name: str
    category: str
    fields: tuple[str, ...]
    levels: tuple  # one parameter entry per level, levels 1..len(levels)
    rules: tuple[str, ...]  # per field, how it is interpolated between levels
    deterministic: bool
    fn: CorruptionFn
    doc: str
    needs_depth: bool = False  # fn(x, depth, level, rng): depth in metres, H x W float32
    scaled: bool = False  # fn(..., scale=s) takes the severity size's factor (:mod:`.scaling`)

    @property
    def n_levels(self) -> int:
        return len(self.levels)

    def params(self, level) -> dict:
        """The named parameters of ``level``, an integer 1..5 or a decimal in between
        (interpolated by each field's rule; a ``blend`` field gives a
        :class:`~.severity.Blend`)."""
        entry = interpolate(self.levels, level, self.rules)
        # With one field the entry is the value itself, even when that value is a sequence
        # (zoom_blur's factor sets).
        values = (entry,) if len(self.fields) == 1 else entry
        return dict(zip(self.fields, values))


_REGISTRY: dict[str, Corruption] = {}


def register(fields: Sequence[str], levels: Sequence, *, rules: Sequence[str] | None = None,
             deterministic: bool = False, depth: bool = False, scaled: bool = False):
    """Decorator: add a corruption function to the registry under its own name, which must
    be one of :data:`robodepth_cli.benchmark_facts.ALL_CORRUPTIONS`; ``depth`` marks one that
    takes the scene's depth (:data:`~robodepth_cli.benchmark_facts.DEPTH_AWARE`), ``scaled`` one
    with spatial parameters, which takes the keyword ``scale`` (:mod:`.scaling`; None: the
    parameters as tabulated). ``rules`` names, per field, how
    it is interpolated between integer levels (default: all ``linear``); the function
    itself applies them (through :func:`~.severity.interpolate`)."""
    rules = tuple(rules) if rules is not None else (LINEAR,) * len(fields)

    def decorate(fn: CorruptionFn) -> CorruptionFn:
        name = fn.__name__
        if name not in ALL_CATEGORY:
            raise ValueError(f"{name!r} is not a known corruption")
        if len(levels) != N_LEVELS:
            raise ValueError(f"{name}: {len(levels)} parameter entries, expected one per level 1..{N_LEVELS}")
        if len(rules) != len(fields) or not set(rules) <= set(RULES):
            raise ValueError(f"{name}: rules {rules} do not match fields {tuple(fields)}")
        if name in _REGISTRY:
            raise ValueError(f"{name!r} registered twice")
        _REGISTRY[name] = Corruption(
            name=name,
            category=ALL_CATEGORY[name],
            fields=tuple(fields),
            levels=tuple(levels),
            rules=rules,
            deterministic=deterministic,
            fn=fn,
            doc=(fn.__doc__ or "").strip(),
            needs_depth=depth,
            scaled=scaled,
        )
        return fn

    return decorate


def registry() -> dict[str, Corruption]:
    """All registered corruptions, in benchmark order, the depth-aware ones last."""
    # Benchmark order, whatever order the modules were imported in.
    return {name: _REGISTRY[name] for name in ALL_CORRUPTIONS if name in _REGISTRY}
