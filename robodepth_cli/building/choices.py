"""The rule of each build configuration key (:data:`_CHECKS`): what a value may be, and the
names, levels and chains it selects; a refusal is a :class:`ConfigError` naming where the
value came from (:mod:`.config` resolves the layers)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..benchmark_facts import TEMPORAL
from ..errors import RobodepthError
from ..imageio import parse_size
from ..sources import splits
from ..integers import int_from_text, is_int

ALL = "all"
NONE = "none"  # corruptions: none, e.g. to build only chains


def takes_frames(ds) -> bool:
    """Whether dataset ``ds`` takes ``frames`` (neighbour frames: KITTI's sequences)."""
    return ds.leveled and ds.split_format == "eigen"


class ConfigError(RobodepthError):
    """A configuration value that cannot be used; the message names its origin and key."""


def _int(loc: str, v, minimum: int) -> int:
    v = int_from_text(v)
    if not is_int(v) or v < minimum:
        raise ConfigError(f"{loc}: expected an integer >= {minimum}, got {v!r}")
    return v


def _names(loc: str, v) -> list:
    """A list from a YAML list, ``all``, or comma-separated text; empty lists refused."""
    if isinstance(v, str):
        v = [s.strip() for s in v.split(",") if s.strip()]
    elif is_int(v) or isinstance(v, float):
        v = [v]
    if not isinstance(v, list) or not v:
        raise ConfigError(f"{loc}: expected a non-empty list or {ALL!r}, got {v!r}")
    return v


def choose_names(loc: str, v, valid: tuple[str, ...], noun: str, *, owner: str = "",
                 known: tuple[str, ...] = (), extra: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The names ``v`` selects from ``valid`` (``all``, a list, or comma-separated text),
    in the given order without repeats; :class:`ConfigError` naming ``loc`` otherwise.
    A name in ``known`` but not in ``valid`` is refused as one that ``owner`` lacks.
    Names in ``extra`` may be listed but ``all`` does not select them."""
    if v == ALL:
        return valid
    v = _names(loc, v)
    valid = valid + tuple(n for n in extra if n not in valid)
    for name in v:
        if name in valid:
            continue
        if name in known:
            raise ConfigError(f"{loc}: {owner} has no {noun} {name!r}; valid: {', '.join(valid)}")
        raise ConfigError(f"{loc}: unknown {noun} {name!r}; valid: {', '.join(valid)}")
    return tuple(dict.fromkeys(v))


def choose_levels(loc: str, v, valid: tuple[int, ...] | None, *, owner: str = "") -> tuple:
    """The levels ``v`` selects (``all``, a number, a list, or comma-separated text),
    sorted without repeats: integers, or decimals between them (``2.5``). ``all`` means
    ``valid`` (the integer levels); any other level must lie in ``valid``'s span, else it is
    refused naming ``owner`` (``valid`` None: 1..5). :class:`ConfigError` naming ``loc``."""
    from ..benchmark_facts import N_LEVELS
    from ..corruptions.severity import LevelError, parse_level

    if v == ALL:
        return tuple(valid or ())
    top = valid[-1] if valid else N_LEVELS
    try:
        return tuple(sorted({parse_level(lv, top=top, what=loc, owner=owner) for lv in _names(loc, v)}))
    except LevelError as exc:
        raise ConfigError(str(exc)) from None


def choose_chains(loc: str, v, top: int, names: tuple[str, ...], owner: str) -> tuple[str, ...]:
    """The chains ``v`` lists (a YAML list, or comma-separated text), each checked: steps
    among ``names`` (``owner``'s corruptions), levels within ``1..top``; as canonical texts
    in the given order without repeats. ``none`` or an empty list: no chains.
    :class:`ConfigError` naming ``loc``."""
    from ..corruptions.chains import parse_chain

    if v is None or v == NONE or v == []:
        return ()
    chains = [parse_chain(c, top=top, where=loc) for c in _names(loc, v)]
    for c in chains:
        for k, step in enumerate(c.steps, 1):
            if step.name not in names:
                raise ConfigError(f"{loc}: chain {c.text!r}: step {k}: {owner} has no corruption "
                                  f"{step.name!r}; valid: {', '.join(names)}")
    return tuple(dict.fromkeys(c.text for c in chains))


def check_train(loc: str, v, ds) -> dict[str, Any]:
    """The ``train`` mapping of a held-out protocol, checked: ``corruptions`` (names of
    ``ds``), ``steps`` (an integer or ``[min, max]`` within 1..8) and ``severity``
    (``[low, high]`` within the dataset's levels). A build records nothing of it;
    :meth:`robodepth_cli.torch.RandomChain.from_protocol` draws from it."""
    from ..corruptions.chains import MAX_STEPS
    from ..corruptions.severity import LevelError, parse_level

    if not isinstance(v, dict) or not v.get("corruptions"):
        raise ConfigError(f"{loc}: expected a mapping with corruptions (and optionally steps, severity)")
    unknown = sorted(set(v) - {"corruptions", "steps", "severity"})
    if unknown:
        raise ConfigError(f"{loc}: unknown key {unknown[0]!r}; valid: corruptions, steps, severity")
    out: dict[str, Any] = {"corruptions": choose_names(f"{loc}: corruptions", v["corruptions"], ds.variant_names(),
                                                        ds.variant_noun, owner=ds.name,
                                                        known=ds.known_variant_names())}
    steps = v.get("steps", [1, 3])
    steps = [steps, steps] if is_int(steps) else steps
    if (not isinstance(steps, list) or len(steps) != 2 or not all(is_int(s) for s in steps)
            or not 1 <= steps[0] <= steps[1] <= MAX_STEPS):
        raise ConfigError(f"{loc}: steps: expected an integer or [min, max] within 1..{MAX_STEPS}, got {steps!r}")
    out["steps"] = steps
    sev = v.get("severity", [1, ds.n_levels])
    try:
        if not isinstance(sev, list) or len(sev) != 2:
            raise LevelError(f"expected [low, high], got {sev!r}")
        sev = [parse_level(s, top=ds.n_levels, what="level", owner=ds.name) for s in sev]
    except LevelError as exc:
        raise ConfigError(f"{loc}: severity: {exc}") from None
    if sev[0] > sev[1]:
        raise ConfigError(f"{loc}: severity: low {sev[0]} above high {sev[1]}")
    out["severity"] = sev
    return out


# --- the rule of each key: (loc, value, base directory, dataset) -> the checked value -----
# An InvalidValueError becomes a ConfigError at loc (_Resolver._check).

_VARIANTS = "<the dataset's variant key>"  # corruptions, or kitti-s's only_styles


def _check_split(loc: str, v, base: Path, ds):
    if ds.discovers_sources and ds.splits:
        if v not in dict(ds.splits):  # a preset's named subsets, e.g. weather sets
            raise ConfigError(f"{loc}: {ds.name} has no split {v!r}; valid: "
                              f"{', '.join(dict(ds.splits))}")
        return v
    if ds.discovers_sources:
        raise ConfigError(f"{loc}: {ds.name} has no split: it builds the images found under "
                          f"--root (--pattern), or those of --list FILE")
    return splits.check_choice(v, ds.split_format, base, owner=ds.name)


def _check_size(loc: str, v, base: Path, ds):
    if v is None and ds.discovers_sources:
        return None  # each image at its own size
    if isinstance(v, list) and len(v) == 2 and all(is_int(s) for s in v):
        v = f"{v[0]}x{v[1]}"
    if not isinstance(v, str):
        raise ConfigError(f"{loc}: expected HxW such as 192x640, or [H, W], got {v!r}")
    return parse_size(v)


def _check_variants(loc: str, v, base: Path, ds):
    if v == NONE and ds.leveled:
        return ()  # only chains
    # The corruptions over time are named, never part of 'all'; they need --frames.
    over_time = TEMPORAL if takes_frames(ds) and v != ALL else ()
    return choose_names(loc, v, ds.variant_names() + over_time, ds.variant_noun,
                        owner=ds.name, known=ds.known_variant_names(),
                        extra=ds.depth_variant_names())


def _check_seed(loc: str, v, base: Path, ds):
    from ..seeding import check_seed

    try:
        return check_seed(v, loc)  # the rule of every command's seed; its message names loc
    except RobodepthError as exc:
        raise ConfigError(str(exc)) from None


def _check_jobs(loc: str, v, base: Path, ds):
    from ..workers import parse_jobs

    return parse_jobs(v)  # the rule of every command's --jobs


def _check_frames(loc: str, v, base: Path, ds):
    from .neighbours import check_frames

    return () if v is None else check_frames(v)


def _check_png(loc: str, v, base: Path, ds):
    from ..imageio import PNG_METHODS

    if v is not None and v not in PNG_METHODS:
        raise ConfigError(f"{loc}: expected one of {', '.join(PNG_METHODS)}, got {v!r}")
    return v


def _check_scheduler(loc: str, v, base: Path, ds):
    if v is not None and (not isinstance(v, str) or not v.strip()):
        raise ConfigError(f"{loc}: expected a Dask scheduler address such as "
                          f"tcp://head:8786, got {v!r}")
    return v and v.strip()


def _check_scheduler_file(loc: str, v, base: Path, ds):
    if v is not None and (not isinstance(v, str) or not v):
        raise ConfigError(f"{loc}: expected the path of a Dask scheduler file, got {v!r}")
    return v and str((base / Path(v).expanduser()).resolve())


_CHECKS = {
    "split": _check_split,
    "size": _check_size,
    _VARIANTS: _check_variants,
    "compose": lambda loc, v, base, ds: choose_chains(
        loc, v, ds.n_levels, ds.variant_names() + ds.depth_variant_names(), ds.name),
    "train": lambda loc, v, base, ds: check_train(loc, v, ds),
    # A dataset without levels accepts the key and ignores it.
    "levels": lambda loc, v, base, ds: choose_levels(loc, v, ds.levels() if ds.leveled else None,
                                                     owner=ds.name),
    "seed": _check_seed,
    "jobs": _check_jobs,
    "limit": lambda loc, v, base, ds: None if v is None else _int(loc, v, 1),
    "frames": _check_frames,
    "png": _check_png,
    "scheduler": _check_scheduler,
    "scheduler_file": _check_scheduler_file,
}


