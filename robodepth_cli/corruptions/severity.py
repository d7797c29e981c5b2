"""Continuous severity: any level ``s = i + t`` in [1, 5] takes each parameter from entries
``i`` and ``i + 1`` of its corruption's five by the rule the corruption declares for it
(``linear``, ``round``, ``nearest``, ``blend``: the table in docs/severity-and-chains.md,
:func:`interpolate`). At an integer level every rule gives that level's own entry, so the
output is byte-identical to the integer level's."""

from __future__ import annotations

import math
import numbers
from typing import NamedTuple, Sequence

from ..errors import RobodepthError
from ..sourcekeys import level_text

LINEAR, ROUND, NEAREST, BLEND = "linear", "round", "nearest", "blend"
RULES = (LINEAR, ROUND, NEAREST, BLEND)


class LevelError(RobodepthError):
    """A severity level that is not a number in the allowed range."""


class Blend(NamedTuple):
    """A ``blend`` parameter between two levels: the lower and upper level's values and the
    upper one's weight ``t``."""

    lower: object
    upper: object
    t: float


def parse_level(value, *, top: int, what: str = "level", owner: str = "", bottom: int = 1) -> int | float:
    """``value`` (a number, or its text as typed) as a severity level in ``bottom..top``:
    an ``int`` when it is a whole number (``2.0`` is level 2), else a ``float``.

    The one check of every level anywhere (``corrupt -l``, ``build --levels``, a chain's
    step, the torch transforms): :class:`LevelError` naming ``what``, the value and the
    range (of ``owner``, a dataset, when given) otherwise."""
    raw = value
    if isinstance(value, str):
        try:
            value = float(value.strip())
        except ValueError:
            value = None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise LevelError(f"{what}: {raw!r} is not a number; levels are {bottom}..{top} "
                         f"(decimals allowed, e.g. 2.5)")
    of = f" for {owner}" if owner else ""
    v = float(value)
    if not math.isfinite(v) or not bottom <= v <= top:
        shown = raw.strip() if isinstance(raw, str) else level_text(v) if math.isfinite(v) else raw
        raise LevelError(f"{what}: level {shown} is out of range{of}; valid levels: {bottom}..{top}")
    return int(v) if v == int(v) else v


def bracket(level) -> tuple[int, float]:
    """``(i, t)`` with ``level = i + t``, ``i`` the integer level below (or at) ``level``
    and ``0 <= t < 1``; ``t`` is exactly 0 at an integer level."""
    v = float(level)
    i = math.floor(v)
    return int(i), v - i


def _one(lo, hi, t: float, rule: str, near):
    if rule == LINEAR:
        return lo + t * (hi - lo)
    if rule == ROUND:
        return int(math.floor(lo + t * (hi - lo) + 0.5))
    if rule == NEAREST:
        return near
    if rule == BLEND:
        return Blend(lo, hi, t)
    raise ValueError(f"unknown interpolation rule {rule!r}")


def interpolate(table: Sequence, level, rules: Sequence[str] | None = None):
    """The parameter entry of ``level`` from ``table`` (one entry per integer level, a tuple
    per level when there are several parameters, the value itself when there is one),
    each parameter by its rule in ``rules`` (default: all ``linear``).

    At an integer level this is ``table[level - 1]`` itself."""
    i, t = bracket(level)
    if t == 0.0:
        return table[i - 1]
    lower, upper = table[i - 1], table[i]
    nearest = upper if t >= 0.5 else lower
    if rules is None:
        rules = (LINEAR,) * (len(lower) if isinstance(lower, tuple) else 1)
    if len(rules) == 1:
        return _one(lower, upper, t, rules[0], nearest)
    return tuple(_one(lo, hi, t, rule, near)
                 for lo, hi, rule, near in zip(lower, upper, rules, nearest))


def parse_levels(value, *, top: int, what: str = "levels", owner: str = "") -> tuple:
    """The levels ``value`` selects, sorted without repeats: ``all`` (the integer levels
    ``1..top``), one level, a list of them, or comma-separated text (``1,2.5,4``), each
    checked by :func:`parse_level`. :class:`LevelError` naming ``what`` otherwise."""
    if isinstance(value, str) and value.strip() == "all":
        return tuple(range(1, top + 1))
    items = [p.strip() for p in value.split(",")] if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)):
        items = [items]
    if not items or any(isinstance(p, str) and not p for p in items):
        raise LevelError(f"{what}: expected levels such as 2 or 1,2.5,4 or 'all', got {value!r}")
    return tuple(sorted({parse_level(p, top=top, what=what, owner=owner) for p in items}))
