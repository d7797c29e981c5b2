"""Checks that keep one output directory holding one build, and the build's plan.

- :func:`check_apart`: ROOT and OUT must not overlap (a build would overwrite its sources);
- :func:`check_sources_outside`: no source may resolve into OUT through a symlink;
- :func:`check_same_build`: a build into an OUT made by another dataset, size or seed is
  refused; ``--limit`` and subsets of the same build extend it;
- :func:`merge_plans` / :func:`planned_outputs`: the record of what was asked for, which
  ``robodepth verify`` compares the tree against (an interrupted build is incomplete, not
  fine).

The plan of an OUT is kept in ``build.json`` as ``plans``: one entry per distinct request
(``variants``, ``levels``, ``keys`` of the split entries), so that a ``--limit 2`` look
followed by the full build, or one corruption now and another later, all count.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from ..errors import RobodepthError
from ..output.folder import OutputDirError
from ..output.record import BuildRecord


def _real(path: Path) -> Path:
    return Path(os.path.realpath(path))


def check_apart(root: Path, out: Path) -> None:
    """Refuse when ``root`` and ``out`` are the same directory or one lies inside the other,
    after resolving symlinks (``out`` need not exist yet). The paths are named as typed."""
    r, o = _real(root), _real(out)
    if r == o:
        relation = "are the same directory"
    elif o.is_relative_to(r):
        relation = "lies inside --root"
    elif r.is_relative_to(o):
        relation = "contains --root"
    else:
        return
    via = ""
    if (str(r), str(o)) != (os.path.abspath(root), os.path.abspath(out)):
        via = f" (through symlinks: {r} and {o})"
    what = (f"--root {root} and --out {out} {relation}" if r == o
            else f"--out {out} {relation} {root}")
    raise OutputDirError(f"{what}{via}; a build would overwrite or mix with its own source "
                         f"images: choose an output directory outside the root")


def check_sources_outside(paths: Iterable[str | None], out: Path) -> None:
    """Refuse when a source image resolves (through a symlink under the root) into ``out``:
    writing that output could overwrite or delete the source itself."""
    o = _real(out)
    for p in paths:
        if p is not None:
            real = _real(Path(p))
            if real.is_relative_to(o):
                raise OutputDirError(f"{p}: resolves to {real} (through a symlink), inside --out "
                                     f"{out}; a build never reads its own outputs")


# --- one build per OUT ---------------------------------------------------------------------

def png_method(out: Path, requested: str | None, previous: BuildRecord | None) -> str:
    """How this build writes its PNGs: ``requested`` (``--png``), else the way the build in
    ``out`` was written, else fast. A request for the other way than ``out``'s build is refused: its files would be
    left as they are (same pixels, so they pass verify) while new ones came out the other
    way, and the record can name only one."""
    from ..imageio import DEFAULT_PNG

    if not previous or not previous.png:
        return requested or DEFAULT_PNG
    own = previous.png
    if requested and requested != own:
        raise OutputDirError(f"{out}: built with --png {own}; --png {requested} would mix two PNG "
                             f"encoders in one build (same pixels, other bytes): leave --png out "
                             f"to go on with {own}, or build into a new --out")
    return own


def _size_text(size) -> str:
    if isinstance(size, (list, tuple)) and len(size) == 2:
        return f"{size[0]}x{size[1]}"
    return "not given (each image at its own size)" if not size else str(size)


def check_same_build(out: Path, dataset: str, size: tuple[int, int] | None, seed: int,
                     previous: BuildRecord | None) -> None:
    """Refuse to build ``dataset`` at ``size`` with ``seed`` into ``out`` when its record
    ``previous`` says it holds another dataset, size or seed (naming the difference)."""
    if not previous:
        return
    old = {"dataset": previous.dataset, "size": tuple(previous.size or ()), "seed": previous.seed}
    new = {"dataset": dataset, "size": tuple(size or ()), "seed": seed}  # None: own sizes (custom)
    shown = {"dataset": lambda v: str(v), "size": _size_text, "seed": lambda v: str(v)}
    flag = {"dataset": "the dataset", "size": "--size", "seed": "--seed"}
    diffs = [f"{flag[k]} {shown[k](new[k])} (it holds {shown[k](old[k])})"
             for k in ("dataset", "size", "seed") if old[k] is not None and old[k] != new[k]
             and not (k == "size" and not old[k])]
    if diffs:
        raise OutputDirError(f"{out}: holds another build ({'; '.join(diffs)}); one output "
                             f"directory holds one build: choose another --out")


# --- the plan ------------------------------------------------------------------------------

def merge_plans(previous: BuildRecord | None, current: dict[str, list]) -> list[dict[str, list]]:
    """The requests recorded in ``previous`` plus ``current`` (once)."""
    merged = [p for p in (previous.requests() if previous else []) if p != current]
    return merged + [current]


def built_keys(entries: list[dict[str, list]]) -> list[str]:
    """Every source key the plans ``entries`` ask for, each once, in the order first asked:
    the extent of the whole build, which a later ``--limit`` look does not shrink. (A
    preset's requests are prefixes of its split, so this is the split's order.)"""
    return list(dict.fromkeys(k for p in entries for k in p["keys"]))


def planned_outputs(record: BuildRecord | None) -> set[str] | None:
    """Every output path the recorded plans ask for, or None without a record (or one that
    records no plan yet): then only the manifest can be checked."""
    entries = record.requests() if record else []
    if not entries:
        return None
    from ..sources.datasets import get_dataset
    from .neighbours import planned_keys

    ds = get_dataset(record.dataset)
    paths: set[str] = set()
    for p in entries:
        jobs = ds.jobs(p["variants"], p["levels"])
        for key in [*p["keys"], *planned_keys(p)]:
            paths.update(job.path(key) for job in jobs)
    return paths


class BuildError(RobodepthError):
    """A problem that makes the whole build impossible; nothing was written because of it
    (or, for a write error mid-build, everything finished so far is kept)."""


def check_depth_scale(ds, options, root: Path, sources) -> None:
    """A build with depth maps: the scale rule (an integer map needs ``--depth-scale``, a
    float map refuses it) checked on the first map that pairs, before any work, rather
    than failing every image after the build. Later maps follow the same rule as they are
    read."""
    from ..sources.depth_io import DepthError, check_scale, value_kind
    from ..sources.depth_pairs import pair, rule_of

    rule = rule_of(options, root, ds.depth_in_root) if ds.discovers_sources else None
    if rule is None or rule.fmt == "cityscapes":
        return
    for src in sources:
        found = pair(rule, src.rel) if not src.error else None
        if found is None or found.error:
            continue
        path = Path(rule.directory) / found.depth
        kind = value_kind(path, rule.fmt)
        if kind is not None:
            try:
                check_scale(path, kind, rule.scale)
            except DepthError as exc:
                raise RobodepthError(f"{exc} (the first depth map of the build)") from None
        return
