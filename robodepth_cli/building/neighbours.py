"""The neighbour frames of a KITTI build with ``--frames`` (e.g. ``-1,1``): for each test
frame, the frames at those offsets in the same raw drive, camera and folder.

A neighbour is written where a test frame would be, ``<variant>/<level>/<its key>``, so a
multi-frame model's own KITTI loader (which reads frame ``n + offset`` beside frame ``n``)
finds it. One path holds one image, so a frame is rendered once per variant: a frame that
is itself a test frame keeps its test rendering (the benchmark's image), and a frame next to
several test frames is rendered for the first of them in split order (its scene draws are
that test frame's). A neighbour not in the drive (before frame 0, after the last frame) is
not written and listed as missing (None); a loader then does what it does for a missing
file (see docs/video.md).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import PurePosixPath

from ..errors import InvalidValueError
from ..sourcekeys import PRESET_EXTS, neighbour_key
from ..sources.datasets import Entry
from .jobs import Source

MAX_OFFSET = 10


def check_frames(value) -> tuple[int, ...]:
    """``-1,1`` (text or a list of integers) as sorted distinct non-zero offsets within
    ``±MAX_OFFSET``; :class:`InvalidValueError` otherwise. An empty value is no frames."""
    items = ([s.strip() for s in value.split(",")] if isinstance(value, str)
             else [value] if isinstance(value, int) else value)
    if not isinstance(items, (list, tuple)):
        raise InvalidValueError(f"expected frame offsets such as -1,1, got {value!r}")
    offsets = []
    for item in items:
        try:
            o = int(item)
            if isinstance(item, float) or str(item).strip() not in (str(o), f"+{o}"):
                raise ValueError
        except (TypeError, ValueError):
            raise InvalidValueError(f"{item!r} is not an integer frame offset (e.g. -1,1)") from None
        if o == 0 or abs(o) > MAX_OFFSET:
            raise InvalidValueError(f"offset {o}: expected a non-zero integer within "
                                    f"-{MAX_OFFSET}..{MAX_OFFSET} (0 is the test frame itself)")
        offsets.append(o)
    return tuple(sorted(set(offsets)))


def neighbour_sources(root, sources: list[Source], offsets) -> tuple[list[Source], dict]:
    """``sources`` (the test frames, split order), each followed by the neighbours rendered
    for it (so one worker often gets a whole sequence), each with its sequence, and the listing ``{test key: [neighbour key or None, ...]}``
    in offset order."""
    tests = {s.key for s in sources}
    owned: dict[str, Source] = {}
    listing: dict[str, list] = {}
    before = sum(1 for o in offsets if o < 0)
    ordered = []  # each test frame followed by the neighbours rendered for it
    for src in sources:
        # A test frame that is not there has no sequence: its own outputs fail, and its
        # neighbours are not made for it.
        found = [(_find(root, src, key) if key and not src.error else None)
                 for key in (neighbour_key(src.key, o) for o in offsets)]
        listing[src.key] = [f.key if f else None for f in found]
        timeline = found[:before] + [src] + found[before:]
        seq = {"sequence": tuple(f.path if f else None for f in timeline), "center": before,
               "sequence_id": _identity(timeline)}
        ordered.append(replace(src, position=before, **seq))
        for i, f in enumerate(timeline):
            if f is not None and f.key not in tests and f.key not in owned:
                owned[f.key] = replace(f, anchor=src.key, position=i, **seq)
                ordered.append(owned[f.key])
    return ordered, listing


def _identity(timeline: list) -> str:
    """A short digest of the frames of a sequence as found: key, size and time of each."""
    import hashlib

    text = "|".join("-" if f is None else f"{f.key}:{f.size}:{f.mtime}" for f in timeline)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _find(root, test: Source, key: str) -> Source | None:
    """The neighbour ``key`` of ``test`` under ``root`` (its own extension tried first), or
    None when the drive has no such frame."""
    stem = PurePosixPath(test.rel or _rel(key)).parent / PurePosixPath(key).stem
    first = PurePosixPath(test.rel).suffix if test.rel else ".png"
    exts = (first,) + tuple(e for e in PRESET_EXTS if e != first)
    src = Source.find(root, Entry(0, key, tuple(f"{stem}{e}" for e in exts)))
    return None if src.error else src


def _rel(key: str) -> str:
    return key.split("/", 1)[1]


def planned_keys(entry: dict) -> set[str]:
    """Every neighbour key a recorded plan entry lists (its outputs are planned too)."""
    return {k for row in (entry.get("neighbours") or {}).values() for k in row if k}
