"""Which source images a build reads: the split's entries found under the root (or in NYU's
labeled file), or for a custom build the images found under the root or listed in
``--list``. Each becomes a :class:`~.jobs.Source`; a missing or unusable image is that
image's failure, and only a root where none is usable refuses the build.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from ..files import sha256_bytes
from ..imageio import exif_orientation
from ..sources import splits
from ..sources.datasets import Dataset, Entry, read_split
from .checks import BuildError
from .config import BuildConfig
from .jobs import Source


def check_root(root: Path, labeled_ok: bool = False) -> Path:
    """``root`` as an absolute path (symlinks kept, so messages name what the user typed,
    and workers in other directories can still read it): a directory, or with
    ``labeled_ok`` also a file (NYU's official labeled .mat); :class:`BuildError` otherwise."""
    root = Path(root)
    if not root.exists():
        raise BuildError(f"{root}: the root directory does not exist")
    if not root.is_dir() and not (labeled_ok and root.is_file()):
        raise BuildError(f"{root}: the root is not a directory")
    return Path(os.path.abspath(root))


def find_sources(root: Path, split_path: Path, ds: Dataset, limit: int | None = None, *,
                 shown_root: Path | None = None) -> list[Source]:
    """One :class:`Source` per entry of the split (its first ``limit`` entries), in split
    order, under the absolute directory ``root``. Raises :class:`BuildError` when none of
    them is there (most likely the wrong root), naming ``shown_root`` (default ``root``)."""
    entries = read_split(split_path, ds.split_format)[:limit]
    if root.is_file():
        sources = labeled_sources(root, split_path, entries)
    else:
        sources = [Source.find(root, e) for e in entries]
    if all(s.error for s in sources):
        raise BuildError(f"{shown_root or root}: none of the {len(sources)} images of {split_path} "
                         f"is there; wrong --root? (first: {sources[0].error})")
    return sources


def labeled_sources(path: Path, split_path: Path, entries: list[Entry]) -> list[Source]:
    """The sources of a NYU split in the official labeled file at ``path``: frame ``N`` of
    the file for ``SCENE/rgb_N``. A line whose frame is not in the file, or is of another
    scene, is that image's failure; a file that is not the labeled file is a
    :class:`BuildError`."""
    from ..groundtruth import nyu as gt_nyu

    try:
        labeled = gt_nyu.opened(path)
    except gt_nyu.NyuError as exc:
        raise BuildError(str(exc)) from None
    sources = []
    for e in entries:
        rgb = e.key[: -len(".png")]  # the key is the split's RGB path with the extension .png
        try:
            i = gt_nyu.frame_index(labeled, rgb)
        except gt_nyu.NyuError as exc:
            sources.append(Source(e.key, "", None, f"{split_path}:{e.line}: {exc}"))
            continue
        sources.append(Source(e.key, gt_nyu.source_name(path, i), str(path), frame=i))
    return sources


def _oriented(src: Source) -> Source:
    """``src`` with its EXIF orientation (a custom build's sources only)."""
    if src.path is None:
        return src
    return replace(src, orientation=exif_orientation(src.path))


def orientation_record(ds: Dataset, sources: list[Source]) -> dict | None:
    """The build record's account of EXIF orientation: a custom build applies it and lists
    the sources it turned; the benchmarks' sources are read as stored (None)."""
    if not ds.discovers_sources:
        return None
    return {"applied": True, "turned": [s.rel for s in sources if s.orientation != 1]}


def gather_sources(ds: Dataset, cfg: BuildConfig, root: Path, out: Path,
                   shown_root: Path | None = None) -> tuple[list[Source], dict]:
    """The sources of the build and the record's ``split`` entry (how they were chosen;
    ``keys``: the entries built, in order): a preset's split file, or for a custom build the
    images found under the root or listed in ``--list`` (:mod:`robodepth_cli.sources.custom`)."""
    if ds.discovers_sources:
        from ..sources import custom

        found, split = custom.find_sources(root, cfg, out, dict(ds.splits).get(cfg.split))
        sources = [_oriented(Source.find(root, Entry(n, key, (rel,))))
                   for n, (key, rel) in enumerate(found, 1)]
        if all(s.error for s in sources):
            raise BuildError(f"{shown_root or root}: none of the {len(sources)} images of {split['path'] or 'the root'} is usable; "
                             f"wrong --root? (first: {sources[0].error})")
        return sources, split
    split_path = splits.split_path(cfg.split, root)
    sources = find_sources(root, split_path, ds, cfg.limit, shown_root=shown_root)
    split = {"path": os.path.abspath(split_path), "sha256": sha256_bytes(split_path.read_bytes()),
             "images": len(sources), "keys": [s.key for s in sources]}
    if cfg.frames:  # the neighbours follow the test frames (their ``anchor`` names which)
        from .neighbours import neighbour_sources

        sources, split["neighbours"] = neighbour_sources(root, sources, cfg.frames)
        split["frames"] = list(cfg.frames)
    return sources, split
