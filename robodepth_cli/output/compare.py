"""``robodepth verify OUT --against OTHER``: is my build the same as yours?

Both sides are compared output by output. A side is a build's folder (its files on disk), an
export's folder (its images in shards, its manifest at ``robodepth/manifest.csv``) or a
``manifest.csv`` alone (its rows only; its files, when they lie beside it, are used for the
differences). An output is

- missing on a side whose manifest does not list it (or lists it as failed), or whose
  files are on disk and lack it (deleted);
- differing when the two manifests give other sha256s, or when a side's file does not
  match its own manifest (what is on disk is compared, not what a manifest claims);
- identical otherwise.

Where both files can be read, a differing output is decoded and its largest pixel
difference taken.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Iterator

import numpy as np

from .layout import MANIFEST, variant_dir
from .folder import OutputFolder
from .manifest import ManifestError, Row, read_manifest_file


@dataclass
class Side:
    """One side of a comparison: its successful manifest rows, the listed outputs whose file
    is gone or holds other bytes than the row says, and ``files(paths)``, which yields
    ``(path, bytes)`` for those of ``paths`` it can read (in any order)."""

    rows: dict[str, Row]
    gone: set[str] = field(default_factory=set)
    changed: set[str] = field(default_factory=set)
    files: Callable[[Iterable[str]], Iterator[tuple[str, bytes]]] = lambda paths: iter(())


def disk_files(base: Path) -> Callable[[Iterable[str]], Iterator[tuple[str, bytes]]]:
    """The ``files`` of a side whose outputs lie under ``base``."""

    def files(paths):
        for p in paths:
            try:
                yield p, (base / p).read_bytes()
            except OSError:  # missing or unreadable: no pixel difference
                continue

    return files


@dataclass
class VariantComparison:
    outputs: int = 0  # listed by either side
    identical: int = 0
    differ: int = 0
    only_here: int = 0  # listed by OUT only, or deleted from OTHER's files
    only_there: int = 0  # listed by OTHER only, or deleted from OUT's files
    largest: int | None = None  # largest pixel difference of a differing pair of files
    unread: int = 0  # differing outputs without both files read (no difference taken)

    @property
    def same(self) -> bool:
        return self.identical == self.outputs

    def text(self) -> str:
        parts = [f"{self.identical} identical", f"{self.differ} differ",
                 f"{self.only_there} missing here", f"{self.only_here} missing there"]
        if self.largest is not None:
            parts.append(f"largest pixel difference {self.largest}")
        if self.unread:
            parts.append(f"{self.unread} differing with no pixel difference taken (a file "
                         f"missing, unreadable or of another size)")
        return ", ".join(parts)


def pixels(data: bytes) -> np.ndarray:
    """The values of an encoded image; OSError or ValueError when it is not one."""
    import io

    from PIL import Image

    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im)


def largest_difference(a: np.ndarray, b: np.ndarray) -> int | None:
    """The largest absolute difference of two images' values; None when their shapes differ."""
    if a.shape != b.shape:
        return None
    return int(np.abs(a.astype(np.int32) - b.astype(np.int32)).max(initial=0))


def other_rows(other: Path) -> tuple[dict[str, Row], Path]:
    """OTHER's successful rows and the folder its outputs are relative to; an export's
    folder is given here as its ``robodepth/`` folder (the one holding its manifest)."""
    other = Path(other)
    if other.is_file():
        rows, base = read_manifest_file(other), other.parent
    elif other.is_dir():
        if not (other / MANIFEST).is_file():
            raise ManifestError(f"--against: {other}: no {MANIFEST}; give a robodepth build, "
                                f"an export or a {MANIFEST}")
        rows, base = OutputFolder(other).recorded(), other
    else:
        raise ManifestError(f"--against: {other}: does not exist")
    if not rows:
        raise ManifestError(f"--against: {other}: an empty manifest")
    return {p: r for p, r in rows.items() if not r.error}, base


def compare(mine: Side, theirs: Side) -> dict[str, VariantComparison]:
    """Per variant directory (``clean``, ``fog/3``, a chain's or a style's), in path order."""
    result: dict[str, VariantComparison] = {}
    differing: dict[str, VariantComparison] = {}
    for path in sorted(mine.rows.keys() | theirs.rows.keys()):
        row = mine.rows.get(path) or theirs.rows[path]
        v = result.setdefault(variant_dir(row.variant, row.level), VariantComparison())
        here = path in mine.rows and path not in mine.gone
        there = path in theirs.rows and path not in theirs.gone
        v.outputs += 1
        if not there:
            v.only_here += 1
            v.only_there += not here  # OUT lacks it too (deleted from both sides)
        elif not here:
            v.only_there += 1
        elif (mine.rows[path].sha256 == theirs.rows[path].sha256
              and path not in mine.changed and path not in theirs.changed):
            v.identical += 1
        else:
            v.differ += 1
            differing[path] = v
    _take_differences(differing, mine, theirs)
    return result


def _take_differences(differing: dict[str, VariantComparison], mine: Side, theirs: Side) -> None:
    """Each differing output's largest pixel difference into its variant's count: OTHER's
    files are read once, in the order its side gives them (an export's, shard by shard)."""
    done = set()
    for path, data in theirs.files(sorted(differing)):
        if path not in differing or path in done:
            continue
        done.add(path)
        here = dict(mine.files([path])).get(path)
        d = None
        if here is not None:
            try:
                d = largest_difference(pixels(here), pixels(data))
            except (OSError, ValueError):  # not an image
                d = None
        v = differing[path]
        if d is None:
            v.unread += 1
        else:
            v.largest = d if v.largest is None else max(v.largest, d)
    for path, v in differing.items():
        if path not in done:
            v.unread += 1
