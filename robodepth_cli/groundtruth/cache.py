"""The ground truth kept between evaluations: a file's (or a folder of PNGs') maps, in the
form :class:`.read.GroundTruth` keeps them under one rule of valid pixels, written once
into the user's cache and memory-mapped by every later evaluation of the same ground truth
under the same rule, instead of inflated and decoded again (KITTI's ``gt_depths.npz``:
~2 s; NYU's 654 PNGs: ~4 s).

An entry is named by the SHA-256 of everything that decides its contents: the release and
this format's version, the resolved path, the identity and times of the file or of each PNG
(``st_dev``, ``st_ino``, size, ``st_mtime_ns``, ``st_ctime_ns``: any write changes the
ctime, so a changed file is read again), the PNGs' names in order, and the rule (protocol,
crop, depth range). ``<key>.bin`` holds the arrays; ``<key>.json`` describes them and is
written last, so an entry is complete or absent. One that does not describe its arrays
exactly (damaged, cut short, another release's) is read around and written again. The
newest entries are kept: at most :data:`MOST`, and :data:`BUDGET` bytes together.

The folder is ``ground-truth/`` under :func:`~robodepth_cli.files.cache_dir`;
``ROBODEPTH_GT_CACHE=off`` turns the cache off. Where it cannot be written, it is not
used: the evaluation reads the ground truth and its results are the same.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Sequence

import numpy as np

from ..files import atomic_output, cache_dir, is_temporary, sha256_bytes, write_atomic
from ..formats import RELEASE, VERSIONS, stamp

SCHEMA = "robodepth-gt-cache"
MOST = 8  # entries kept
BUDGET = 2 << 30  # bytes kept in all (one NYU entry: ~400 MB; one KITTI: ~100 MB)
_DTYPES = {"|u1", "<u2", "<i2", "<u4", "<i4", "<i8", "<f4", "<f8"}


def folder() -> Path | None:
    """Where the entries are, or None when ``ROBODEPTH_GT_CACHE`` turns the cache off."""
    if os.environ.get("ROBODEPTH_GT_CACHE", "").strip().lower() in ("off", "0", "no", "false"):
        return None
    return cache_dir() / "ground-truth"


def entry_key(path: Path, names: Sequence[str] | None, rule: str) -> str | None:
    """The name of the entry of the ground truth at ``path`` (a file, or with ``names`` a
    folder of those PNGs) under ``rule``; None when a file cannot be looked at (the read
    that follows says why)."""
    try:
        files = [path / n for n in names] if names is not None else [path]
        stats = [[s.st_dev, s.st_ino, s.st_size, s.st_mtime_ns, s.st_ctime_ns]
                 for s in (f.stat() for f in files)]
        where = str(path.resolve())
    except (OSError, RuntimeError):
        return None
    return sha256_bytes(json.dumps([RELEASE, VERSIONS[SCHEMA], where, list(names) if names is not None else None,
                                    stats, rule]).encode())


def load(key: str) -> tuple[str, list, list, list[str] | None] | None:
    """The entry ``key``: ``(arrays file, shapes, entries, keys)`` as :meth:`.read.GroundTruth.write_arrays`
    described them (each array checked to lie inside the file), or None when there is none
    or it is not whole."""
    where = folder()
    if where is None:
        return None
    bin_path, json_path = where / f"{key}.bin", where / f"{key}.json"
    try:
        meta = json.loads(json_path.read_text())
        shapes, entries, keys = _checked(meta, bin_path.stat().st_size)
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None
    try:
        os.utime(json_path)  # the newest: kept longest
    except OSError:
        pass
    return str(bin_path), shapes, entries, keys


def _checked(meta: dict, size: int) -> tuple[list, list, list[str] | None]:
    """``(shapes, entries, keys)`` of an entry's description, each array inside the
    ``size`` bytes of its file; ValueError when the description is not one."""
    if [meta.get(k) for k in ("schema", "schema_version", "robodepth")] != list(stamp(SCHEMA).values()):
        raise ValueError("another release's")
    shapes = [tuple(int(x) for x in s) for s in meta["shapes"]]
    entries = []
    for pixels, placed, divisor in meta["entries"]:
        arrays = []
        for offset, dtype, shape in placed:
            shape = tuple(int(x) for x in shape)
            if dtype not in _DTYPES or offset < 0 or min(shape, default=0) < 0:
                raise ValueError("not an array")
            if offset + int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize > size:
                raise ValueError("cut short")
            arrays.append((int(offset), dtype, shape))
        if len(arrays) != (2 if pixels else 1) or not (divisor is None or isinstance(divisor, (int, float))):
            raise ValueError("not an entry")
        entries.append((bool(pixels), arrays, divisor))
    keys = meta.get("keys")
    if len(shapes) != len(entries) or keys is not None and len(keys) != len(entries):
        raise ValueError("counts differ")
    return shapes, entries, None if keys is None else [str(k) for k in keys]


def store(key: str, source: str, shapes: list, keys: list[str] | None, write) -> None:
    """Write the entry ``key``: ``write(fh)`` writes the arrays into a binary file and
    returns their entries (:meth:`.read.GroundTruth.write_arrays`); then drop the oldest
    entries beyond :data:`MOST` and :data:`BUDGET`. Nothing when the cache is off or
    cannot be written."""
    where = folder()
    if where is None:
        return
    try:
        with atomic_output(where / f"{key}.bin") as fh:
            entries = write(fh)
        meta = {**stamp(SCHEMA), "source": source, "shapes": [list(s) for s in shapes],
                "entries": entries, "keys": keys}
        write_atomic(where / f"{key}.json", json.dumps(meta).encode())
        _prune(where, keep=key)
    except OSError:
        return


def _prune(where: Path, keep: str) -> None:
    """Remove the oldest entries (by their description's time) beyond the limits, never
    ``keep`` (the one just written), and what writers that were killed left: arrays with
    no description, temporary files (older than a minute: not another one's, still
    being written)."""
    import time

    found = []
    stale = time.time() - 60
    for p in where.iterdir():
        if is_temporary(p.name) or p.suffix == ".bin" and not p.with_suffix(".json").exists():
            try:
                if p.stat().st_mtime < stale:
                    p.unlink()
            except OSError:
                continue
    for meta in where.glob("*.json"):
        data = meta.with_suffix(".bin")
        try:
            found.append((meta.stat().st_mtime_ns, meta, data, data.stat().st_size))
        except OSError:
            continue
    found.sort(reverse=True)
    total = 0
    for n, (_, meta, data, size) in enumerate(found):
        total += size
        if meta.stem != keep and (n >= MOST or total > BUDGET):
            for p in (meta, data):  # the description first: an entry is whole or absent
                try:
                    p.unlink()
                except OSError:
                    pass
