"""``robodepth verify OUT --against OTHER``: is my build the same as yours?

Both builds' manifests are compared output by output: an output is identical when both
list it with the same sha256, differs when the hashes differ, and is missing on the side
that does not list it (or lists it as failed). Where both files are on disk, a differing
output is decoded and its largest pixel difference taken. OTHER is another build's folder
or a ``manifest.csv`` (its files, when they lie beside it, are used for the differences).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .layout import MANIFEST, variant_dir
from .manifest import ManifestError, Row, read_manifest_file, read_recorded


@dataclass
class VariantComparison:
    identical: int = 0
    differ: int = 0
    only_here: int = 0  # listed by OUT only
    only_there: int = 0  # listed by OTHER only
    largest: int | None = None  # largest pixel difference of a differing pair of files
    unread: int = 0  # differing outputs without both files on disk (no difference taken)

    @property
    def same(self) -> bool:
        return not (self.differ or self.only_here or self.only_there)

    def text(self) -> str:
        parts = [f"{self.identical} identical", f"{self.differ} differ",
                 f"{self.only_there} missing here", f"{self.only_here} missing there"]
        if self.largest is not None:
            parts.append(f"largest pixel difference {self.largest}")
        if self.unread:
            parts.append(f"{self.unread} differing with no pixel difference taken (a file "
                         f"missing, unreadable or of another size)")
        return ", ".join(parts)


def pixels(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im)


def largest_difference(a: np.ndarray, b: np.ndarray) -> int | None:
    """The largest absolute difference of two images' values; None when their shapes differ."""
    if a.shape != b.shape:
        return None
    return int(np.abs(a.astype(np.int32) - b.astype(np.int32)).max(initial=0))


def other_manifest(other: Path) -> tuple[dict[str, Row], Path]:
    """OTHER's successful rows and the folder its outputs are relative to."""
    other = Path(other)
    if other.is_file():
        rows, base = read_manifest_file(other), other.parent
    elif other.is_dir():
        if not (other / MANIFEST).is_file():
            raise ManifestError(f"--against: {other}: no {MANIFEST}; give a robodepth build "
                                f"or its {MANIFEST}")
        rows, base = read_recorded(other), other
    else:
        raise ManifestError(f"--against: {other}: does not exist")
    if not rows:
        raise ManifestError(f"--against: {other}: an empty manifest")
    return {p: r for p, r in rows.items() if not r.error}, base


def compare(out: Path, other: Path) -> dict[str, VariantComparison]:
    """Per variant directory (``clean``, ``fog/3``, a chain's or a style's), in path order."""
    mine = {p: r for p, r in read_recorded(Path(out)).items() if not r.error}
    theirs, base = other_manifest(other)
    result: dict[str, VariantComparison] = {}
    for path in sorted(mine.keys() | theirs.keys()):
        row = mine.get(path) or theirs[path]
        v = result.setdefault(variant_dir(row.variant, row.level), VariantComparison())
        if path not in theirs:
            v.only_here += 1
        elif path not in mine:
            v.only_there += 1
        elif mine[path].sha256 == theirs[path].sha256:
            v.identical += 1
        else:
            v.differ += 1
            _take_difference(v, Path(out) / path, base / path)
    return result


def _take_difference(v: VariantComparison, a: Path, b: Path) -> None:
    try:
        d = largest_difference(pixels(a), pixels(b))
    except (OSError, ValueError):  # a file missing or not an image
        d = None
    if d is None:  # another size: no pixel to pixel difference
        v.unread += 1
    else:
        v.largest = d if v.largest is None else max(v.largest, d)
