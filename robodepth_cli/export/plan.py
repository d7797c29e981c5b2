"""What an export holds: the rows of each configuration and split, cut into shards.

The plan is made from the build's manifest and the sizes of its files alone, so the same
build and ``--shard-size`` always give the same shards: a stopped export resumes by
writing the shards that are not there yet.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InvalidValueError, RobodepthError
from ..output.layout import GT_DIR, GT_FILE, output_path, variant_dir
from .layout import GT_CONFIG, NEIGHBOURS, NO_LEVEL, shard_name, split_name

_UNITS = {"": 1, "b": 1, "kb": 10 ** 3, "mb": 10 ** 6, "gb": 10 ** 9}


class ExportError(RobodepthError):
    """A build that cannot be exported, or an export that cannot be written or read."""


def parse_size(text: str) -> int:
    """``500MB``, ``2GB``, ``64kB``, ``1000`` (bytes; decimal units) -> bytes."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([a-zA-Z]*)\s*", str(text))
    unit = m and m.group(2).lower()
    if not m or unit not in _UNITS:
        raise InvalidValueError(f"{text!r}: expected a size such as 500MB, 2GB or 64kB")
    size = int(float(m.group(1)) * _UNITS[unit])
    if size < 1:
        raise InvalidValueError(f"{text!r}: must be at least 1 byte")
    return size


@dataclass(frozen=True)
class Item:
    """One row of an export: one file of the build."""

    output: str  # its path in the build (and the row's image path)
    key: str  # the split's image key ("" for KITTI's one ground-truth file)
    variant: str
    level: int | float | None
    seed: int
    sha256: str  # the manifest's
    size: int  # bytes
    part: int = 0  # the ground truth: the map's index in its file (gt_depths.npz holds them all)


@dataclass
class Shard:
    config: str
    split: str
    index: int
    count: int  # shards of this split
    start: int  # the position in the split of its first row
    items: list[Item] = field(default_factory=list)

    @property
    def neighbours(self) -> bool:
        """Whether this shard holds neighbour frames (a split ``<split>_neighbours``)."""
        return self.split.endswith(NEIGHBOURS)

    def name(self, ext: str) -> str:
        return shard_name(self.config, self.split, self.index, self.count, ext)

    @property
    def size(self) -> int:
        return sum(i.size for i in self.items)


def config_name(variant) -> str:
    """The configuration of a :class:`~robodepth_cli.api.Variant`: its name, or a chain's
    directory name (a chain's text holds ``:``)."""
    return variant.relpath.split("/")[0]


def plan(out: Path, dataset, rows: dict, shard_bytes: int) -> list[Shard]:
    """Every shard of the export of ``dataset`` (an opened build at ``out``), variants in
    the build's order (each followed by its neighbour frames, a build with --frames), then
    the ground truth; ``rows``: the manifest's rows. :class:`ExportError` before any work if
    the build holds a file that no shard would."""
    groups: list[tuple[str, str, list[Item]]] = []
    around = neighbour_outputs(rows)
    for v in dataset.variants():
        # The images a variant lacks (no usable depth map: see _open_build) have no row.
        paths = [(output_path(v.name, v.level, key), key) for key in v.keys if key not in v.missing]
        groups.append((config_name(v), split_name(v.level), _items(out, rows, paths, v)))
        if around.get(v.relpath):
            paths = [(p, p[len(v.relpath) + 1:]) for p in around[v.relpath]]
            groups.append((config_name(v), split_name(v.level) + NEIGHBOURS,
                           _items(out, rows, paths, v)))
    truth = _ground_truth(out, dataset, rows)
    if truth:
        groups.append((GT_CONFIG, NO_LEVEL, truth))
    _check_everything(out, rows, groups)
    shards = []
    for config, split, items in groups:
        cuts: list[list[Item]] = [[]]
        filled = 0
        for item in items:
            if cuts[-1] and filled + item.size > shard_bytes:
                cuts.append([])
                filled = 0
            cuts[-1].append(item)
            filled += item.size
        start = 0
        for i, part in enumerate(cuts):
            shards.append(Shard(config, split, i, len(cuts), start, part))
            start += len(part)
    return shards


def _items(out: Path, rows: dict, paths, v) -> list[Item]:
    return [Item(p, key, v.name, v.level, rows[p].seed, rows[p].sha256, _size(out, p))
            for p, key in paths]


def neighbour_outputs(rows: dict) -> dict[str, list[str]]:
    """The neighbour frames of a build with --frames (rows whose ``params`` name the test
    frame they were rendered for), by variant directory, each list sorted by path."""
    found: dict[str, list[str]] = {}
    for path, r in rows.items():
        if r.parsed.neighbour_of and not r.error:
            found.setdefault(variant_dir(r.variant, r.level), []).append(path)
    return {d: sorted(paths) for d, paths in found.items()}


def _check_everything(out: Path, rows: dict, groups) -> None:
    """Refuse an export that would leave out a file of the build."""
    planned = {i.output for _, _, items in groups for i in items}
    left = sorted(p for p, r in rows.items() if not r.error and p not in planned)
    if left:
        raise ExportError(f"{out}: {len(left)} file(s) of the build would not be exported "
                          f"({', '.join(left[:3])}{', ...' if len(left) > 3 else ''}): the "
                          "manifest lists them but the build's record does not place them; "
                          f"run robodepth verify {out}, or rebuild into a new folder")


def _ground_truth(out: Path, dataset, rows: dict) -> list[Item]:
    """The build's ground truth as rows, one per map, from every file the manifest lists as
    made: ``gt_depths.npz`` (a map per image of the split, in its order) or ``gt/<depth
    name>`` (keyed by its image, split order; a file of no image of the split by its path)."""
    key_of = {f"{GT_DIR}/{n}": k for n, k in zip(dataset.depth_names(), dataset.keys)}
    items = []
    gt = rows.get(GT_FILE)
    if gt is not None and not gt.error:
        size = _size(out, GT_FILE) // max(len(dataset.keys), 1)
        items += [Item(GT_FILE, k, gt.variant, None, gt.seed, gt.sha256, size, i)
                  for i, k in enumerate(dataset.keys)]
    paths = [*key_of, *sorted(p for p in rows if p.startswith(GT_DIR + "/") and p not in key_of)]
    return items + [Item(p, key_of.get(p, ""), rows[p].variant, None, rows[p].seed, rows[p].sha256,
                         _size(out, p)) for p in paths if p in rows and not rows[p].error]


def _size(out: Path, path: str) -> int:
    try:
        return os.stat(out / path).st_size
    except OSError as exc:
        raise ExportError(f"{out / path}: listed in the manifest but cannot be read "
                          f"({exc.strerror}); run robodepth verify {out}") from None
