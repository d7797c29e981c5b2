"""The files of a challenge: what the public and private folders hold, and their metadata
(the table in docs/challenge.md; :func:`gt_members` for the members of ``gt.npz``)."""

from __future__ import annotations

import csv
import io
import json
import os

from ..errors import RobodepthError

IMAGES = "images"
LIST = "list.txt"
META = "challenge.json"
README = "README.md"
GT = "gt.npz"
KEY = "key.csv"
BUILD = "build"
KEY_FIELDS = ("id", "position", "source", "corruption", "level", "seed", "sha256")
TRACKS = ("kitti", "nyu")
FORMAT = 1  # of challenge.json


def gt_members(image_id: str, depth):
    """The ``gt.npz`` members of one map: ``(<id>, map)`` when at least half its pixels are
    valid (finite, above 0); else its shape (int64 H, W), the flat row-major indices of the
    valid pixels (int32) and their depths (float32), which cost a tenth of the inflating."""
    import numpy as np

    depth = np.asarray(depth, np.float32)
    valid = np.flatnonzero(np.isfinite(depth) & (depth > 0))
    if valid.size * 2 >= depth.size or depth.size >= 2 ** 31:
        return [(image_id, depth)]
    return [(f"{image_id}.shape", np.array(depth.shape, np.int64)),
            (f"{image_id}.index", valid.astype(np.int32)),
            (f"{image_id}.depth", depth.reshape(-1)[valid])]


def read_gt(npz, image_id: str):
    """The map of ``image_id`` from an opened ``gt.npz`` (``np.load``): as stored, or rebuilt
    from its sparse members with 0 elsewhere; ``KeyError`` if it has none."""
    import numpy as np

    if image_id in npz.files:
        return npz[image_id]
    shape = tuple(int(v) for v in npz[f"{image_id}.shape"])
    depth = np.zeros(shape, np.float32)
    depth.reshape(-1)[npz[f"{image_id}.index"]] = npz[f"{image_id}.depth"]
    return depth


def read_meta(folder: str) -> dict:
    """The ``challenge.json`` of a public or private folder."""
    path = os.path.join(folder, META)
    try:
        with open(path, encoding="utf-8") as fh:
            meta = json.load(fh)
    except FileNotFoundError:
        raise RobodepthError(f"{folder}: no {META}; not a folder written by robodepth "
                             "challenge build") from None
    except (OSError, ValueError) as exc:
        raise RobodepthError(f"{path}: unreadable ({exc})") from None
    if not isinstance(meta, dict) or meta.get("track") not in TRACKS or \
            not isinstance(meta.get("images"), int):
        raise RobodepthError(f"{path}: not a challenge description (track, images)")
    return meta


def read_list(folder: str) -> list[str]:
    """The image ids of ``list.txt``, in order."""
    path = os.path.join(folder, LIST)
    try:
        with open(path, encoding="utf-8") as fh:
            ids = [line.strip() for line in fh if line.strip()]
    except OSError as exc:
        raise RobodepthError(f"{path}: {exc.strerror or exc}") from None
    if len(set(ids)) != len(ids):
        raise RobodepthError(f"{path}: an id is listed twice")
    return ids


def read_key(folder: str) -> list[dict]:
    """The rows of ``key.csv`` in list order (``position`` and ``level`` as integers)."""
    path = os.path.join(folder, KEY)
    try:
        with open(path, encoding="utf-8", newline="") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise RobodepthError(f"{path}: {exc.strerror or exc}") from None
    if not rows or tuple(rows[0]) != KEY_FIELDS:
        raise RobodepthError(f"{path}: not a challenge key (columns {', '.join(KEY_FIELDS)})")
    for r in rows:
        r["position"], r["level"], r["seed"] = int(r["position"]), int(r["level"]), int(r["seed"])
    rows.sort(key=lambda r: r["position"])
    return rows


def key_text(rows: list[dict]) -> str:
    """``key.csv``'s text for ``rows`` (dicts with :data:`KEY_FIELDS`)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, KEY_FIELDS, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def meta_text(meta: dict) -> str:
    return json.dumps(meta, indent=2, sort_keys=True) + "\n"
