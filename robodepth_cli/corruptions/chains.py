"""Compound corruptions: chains such as ``fog:3+gaussian_noise:2.5`` (docs/severity-and-chains.md).

A chain is 1..8 ``NAME:LEVEL`` steps joined by ``+``, applied in the order written; a step
without a level is a template that takes each of a command's levels in turn
(:func:`expand_chain`). :attr:`Chain.text` is the canonical text (levels as
:func:`~.severity.level_text` writes them): the variant's name everywhere and the key of
its random streams (:func:`robodepth_cli.seeding.chain_rngs`, one generator per step).
:attr:`Chain.dirname` is its directory in a build, ``:`` written ``-``; :func:`parse_chain`
reads either form back.

This module is light (no numpy): configurations, results files and scores parse chains
without loading the corruption engine."""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..benchmark_facts import ALL_CATEGORY, ALL_CORRUPTIONS, N_LEVELS
# The test of a chain's name is a benchmark fact (output/ orders variants by it without
# loading the corruptions); chains' users find it here too.
from ..benchmark_facts import looks_like_chain  # noqa: F401
from ..errors import RobodepthError
from .severity import LevelError, level_text, parse_level

MAX_STEPS = 8
_STEP = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*[:\-]\s*(\S.*?)\s*$")
_NAME = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*$")


@dataclass(frozen=True)
class Step:
    name: str
    level: int | float

    @property
    def text(self) -> str:
        return f"{self.name}:{level_text(self.level)}"


@dataclass(frozen=True)
class Chain:
    steps: tuple[Step, ...]

    @property
    def text(self) -> str:
        """Canonical form, e.g. ``fog:3+gaussian_noise:2.5``."""
        return "+".join(s.text for s in self.steps)

    @property
    def dirname(self) -> str:
        """File-system-safe directory name, e.g. ``fog-3+gaussian_noise-2.5``."""
        return "+".join(f"{s.name}-{level_text(s.level)}" for s in self.steps)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.steps)

    def __str__(self) -> str:
        return self.text


def parse_chain(text: str, *, top: int = N_LEVELS, where: str = "") -> Chain:
    """The chain ``text`` describes (its canonical or directory form).

    ``top`` is the highest level allowed (5; a benchmark may allow fewer: NYUDepth2-C 4).
    :class:`RobodepthError`, one line naming ``where`` (a flag or file), the chain and the
    problem, for: an empty chain or step, a step that is not ``NAME:LEVEL``, an unknown
    name, a level that is not a number in ``1..top``, more than 8 steps."""
    return expand_chain(text, (), top=top, where=where)[0]


def expand_chain(text: str, levels, *, top: int = N_LEVELS, where: str = "") -> list[Chain]:
    """The chains of a chain *template*: steps written without a level (``fog+gaussian_noise``,
    ``fog+contrast:2``) take each of ``levels`` in turn, one chain per level; a chain whose
    steps all have levels is itself, whatever ``levels`` holds. With no ``levels`` every step
    needs its own. Refused as :func:`parse_chain` refuses."""
    at = f"{where}: " if where else ""
    if not isinstance(text, str):
        raise RobodepthError(f"{at}chain {text!r}: expected text such as 'fog:3+gaussian_noise:2.5'")
    shown = text.strip()

    def fail(problem: str) -> RobodepthError:
        return RobodepthError(f"{at}chain {shown!r}: {problem}")

    if not shown:
        raise fail("empty; write steps NAME:LEVEL joined by '+', e.g. 'fog:3+gaussian_noise:2.5'")
    parts = shown.split("+")
    if len(parts) > MAX_STEPS:
        raise fail(f"{len(parts)} steps; a chain has at most {MAX_STEPS}")
    steps: list[tuple[str, int | float | None]] = []
    for k, part in enumerate(parts, 1):
        if not part.strip():
            raise fail(f"step {k} is empty (a '+' with nothing on one side)")
        m = _STEP.match(part)
        bare = _NAME.match(part) if levels else None
        if not m and not bare:
            raise fail(f"step {k} {part.strip()!r} is not NAME:LEVEL (e.g. 'fog:3')")
        name = (m or bare).group(1)
        if name not in ALL_CATEGORY:
            raise fail(f"step {k}: unknown corruption {name!r}; valid: {', '.join(ALL_CORRUPTIONS)}")
        if m:
            try:
                steps.append((name, parse_level(m.group(2), top=top, what=f"step {k} ({name})")))
            except LevelError as exc:
                raise fail(str(exc)) from None
        else:
            steps.append((name, None))
    if all(lv is not None for _, lv in steps):
        return [Chain(tuple(Step(n, lv) for n, lv in steps))]
    out = []
    for level in levels:
        try:
            level = parse_level(level, top=top, what="level")
        except LevelError as exc:
            raise fail(str(exc)) from None
        out.append(Chain(tuple(Step(n, level if lv is None else lv) for n, lv in steps)))
    return list(dict.fromkeys(out))
