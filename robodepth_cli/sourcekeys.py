"""From a source image's path to the *key* a build names and seeds its outputs with.

A build seeds every job with the key of its source (``<variant>/<level>/<key>`` is also the
output path). The manifest records the source path as found under the root; this module
turns that path back into the key, so code outside a build (the PyTorch transforms) can
draw exactly what a build draws for that image.

* ``custom``: the path relative to the root with its extension replaced by ``.png``
  (``city/a.JPG`` -> ``city/a.png``; no extension: ``.png`` appended).
* ``kitti-c``, ``kitti-c-hr``, ``kitti-s``: ``kitti_data/`` + the path with its image
  extension replaced by ``.png`` (a key that already starts with ``kitti_data/`` is kept).
* ``nyudepth2-c``: the path with its image extension replaced by ``.png``.

A level's part of an output path and of a job's key is its canonical text (:func:`level_text`).
"""

from __future__ import annotations

from pathlib import PurePosixPath

from .errors import InvalidValueError

KITTI_PREFIX = "kitti_data"
# The extensions a preset split's source may have (a custom source's is always replaced).
PRESET_EXTS = (".png", ".jpg", ".jpeg")


def relative_parts(text: str, what: str) -> list[str]:
    """The components of a relative posix path, refusing anything that could leave the root
    (absolute paths, ``..``, empty or ``.`` components, backslashes, NUL) with
    :class:`~robodepth_cli.errors.InvalidValueError` calling it ``what``."""
    if not text or "\\" in text or "\0" in text or text.startswith("/"):
        raise InvalidValueError(f"{what} {text!r} is not a relative path")
    parts = text.split("/")
    if any(p in ("", ".", "..") for p in parts):
        raise InvalidValueError(f"{what} {text!r} has an empty, '.' or '..' component")
    return parts


def custom_key(rel: str) -> str:
    """``rel`` (posix, relative to the root) with its extension replaced by ``.png``."""
    p = PurePosixPath(rel)
    return str(p.with_suffix(".png")) if p.suffix else f"{rel}.png"


def _png(rel: str) -> str:
    p = PurePosixPath(rel)
    return str(p.with_suffix(".png")) if p.suffix.lower() in PRESET_EXTS else f"{rel}.png"


def seed_key(dataset: str, path: str) -> str:
    """The key a build of ``dataset`` uses for the source recorded as ``path`` (the
    manifest's ``source`` column, or the key itself, or an output path relative to OUT
    is *not* accepted: strip ``<variant>/<level>/`` first)."""
    rel = str(path).replace("\\", "/").lstrip("/")
    if dataset == "custom":
        return custom_key(rel)
    if dataset.startswith("kitti"):
        rel = _png(rel)
        return rel if rel.startswith(KITTI_PREFIX + "/") else f"{KITTI_PREFIX}/{rel}"
    return _png(rel)


def neighbour_key(key: str, offset: int) -> str | None:
    """The key of the frame ``offset`` away from the KITTI frame ``key``
    (``.../data/0000000069.png`` and -1: ``.../data/0000000068.png``); None before frame 0.
    The neighbours of ``build --frames`` are named so, and ``predict`` finds them so."""
    p = PurePosixPath(key)
    n = int(p.stem) + offset
    return None if n < 0 else str(p.with_name(f"{n:0{len(p.stem)}d}{p.suffix}"))


def level_text(level) -> str:
    """The canonical text of a level: ``3`` for an integer level (as every name, seed and
    manifest row has always written it), the shortest round-trip decimal otherwise
    (``2.5``, ``1.25``). It names directories and keys random streams."""
    v = float(level)
    return str(int(v)) if v == int(v) else repr(v)
