"""The build record, ``OUT/build.json``: what was built, how, and how it ended.

A build writes its record when it starts (status ``running``) and again when it ends
(``finished``, ``finished with failures``, ``interrupted`` or ``stopped``, with the run's
summary): :class:`BuildStatus`.
:class:`BuildRecord` is the one typed form of the file: the builder writes it, ``verify``,
:func:`robodepth_cli.open_dataset`, the build checks and ``robodepth_cli.torch`` read it.
It carries its format version (``schema`` ``robodepth-build``, :mod:`robodepth_cli.formats`),
which covers the manifest beside it; a record of another version is refused in one line.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from datetime import datetime, timezone
from enum import Enum
from pathlib import Path
from typing import Any

from ..errors import RobodepthError
from ..files import write_atomic
from ..formats import FormatError, check

SCHEMA = "robodepth-build"


class RecordError(RobodepthError):
    """A ``build.json`` that cannot be read or is not a build record."""


class BuildStatus(str, Enum):
    """How a build stands, as its record says (a ``str``: JSON writes its value)."""

    RUNNING = "running"  # started, not ended (or killed: the next build resumes it)
    FINISHED = "finished"  # every planned output made
    FAILURES = "finished with failures"  # ran to the end; some images could not be made
    INTERRUPTED = "interrupted"  # Ctrl-C or SIGTERM
    STOPPED = "stopped"  # an error that stops every worker (a full disk, a lost cluster)


def now() -> str:
    """The record's timestamps: UTC, ISO 8601, to the second."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def plan_entry(variants, levels, keys, neighbours: dict | None = None, frames=()) -> dict[str, list]:
    """One request made into an OUT: which variants at which levels for which source keys;
    with ``--frames``, also the ``frames`` offsets and ``neighbours``: each test key's
    neighbour keys in offset order (None: not in the drive)."""
    entry = {"variants": list(variants), "levels": list(levels), "keys": list(keys)}
    if frames:
        entry["frames"] = list(frames)
        entry["neighbours"] = {k: list(v) for k, v in (neighbours or {}).items()}
    return entry


@dataclass
class BuildRecord:
    dataset: str | None
    config: dict[str, Any] = field(default_factory=dict)  # the resolved configuration
    seed: int | None = None
    # How the sources were chosen; ``keys``: the source keys built, in split order.
    split: dict[str, Any] = field(default_factory=dict)
    plans: list[dict[str, list]] | None = None  # every request made into this OUT so far
    robodepth: str = ""
    command: list[str] = field(default_factory=list)
    root: str = ""
    out: str = ""
    versions: dict[str, str] = field(default_factory=dict)
    png_compress_level: int | None = None
    png: str | None = None  # how the PNGs are written (--png)
    png_encoder: str | None = None
    executor: dict[str, Any] = field(default_factory=dict)
    started: str | None = None
    finished: str | None = None
    status: BuildStatus | None = None
    summary: dict[str, Any] | None = None  # absent until the build ends
    # A custom build: {"applied": true, "turned": [the sources turned upright by their EXIF
    # orientation]}; absent for the presets (read as stored).
    exif_orientation: dict[str, Any] | None = None
    # Where the depth-aware corruptions' depth came from ({"kind", "method", "version"});
    # absent when the build has none.
    depth: dict[str, Any] | None = None

    # ----------------------------------------------------------------------- reading

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "BuildRecord":
        known = {f.name for f in fields(cls)}
        values = {k: v for k, v in data.items() if k in known}
        values["config"] = data.get("config") if isinstance(data.get("config"), dict) else {}
        if not isinstance(values.get("split"), dict):
            values["split"] = {}
        if not isinstance(values.get("plans"), list):
            values["plans"] = None
        values.setdefault("dataset", None)
        values["status"] = BuildStatus(values["status"]) if values.get("status") else None
        return cls(**values)

    @property
    def keys(self) -> list[str] | None:
        """The source keys built, in split order, when the record lists them."""
        keys = self.split.get("keys")
        if isinstance(keys, list) and keys and all(isinstance(k, str) for k in keys):
            return keys
        return None

    @property
    def size(self) -> tuple[int, int] | None:
        """The output size (H, W), or None: each image at its own size (custom)."""
        size = self.config.get("size")
        return tuple(size) if size else None

    @property
    def frames(self) -> set[int]:
        """The neighbour offsets any request into this OUT built (``--frames``)."""
        return {o for p in self.requests() for o in p.get("frames", ())}

    @property
    def limit(self) -> int | None:
        return self.config.get("limit")

    def requests(self) -> list[dict[str, list]]:
        """The requests recorded (``plans``; [] before the first is recorded)."""
        return self.plans or []

    # ----------------------------------------------------------------------- writing

    def to_dict(self) -> dict[str, Any]:
        from ..formats import stamp

        data = {f.name: getattr(self, f.name) for f in fields(self)}
        for optional in ("summary", "plans", "png", "exif_orientation", "depth", "status"):  # absent, not null, when unset
            if data[optional] is None:
                del data[optional]
        return {**data, **stamp(SCHEMA)}


def read_record_file(path: Path) -> BuildRecord | None:
    """The build record in the file at ``path`` (None when there is none);
    :class:`RecordError` naming the file when it cannot be read or is not a record."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordError(f"{path}: cannot read the build record ({exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RecordError(f"{path}: not a build record ({exc}); if this directory is yours to "
                          f"reuse, delete the file") from None
    if not isinstance(data, dict):
        raise RecordError(f"{path}: not a build record (a JSON {type(data).__name__})")
    try:
        check(data, SCHEMA, str(path), "build again into a new folder")
    except FormatError as exc:
        raise RecordError(str(exc)) from None
    if data.get("status") and data["status"] not in {s.value for s in BuildStatus}:
        raise RecordError(f"{path}: unknown status {data['status']!r}; valid: "
                          + ", ".join(s.value for s in BuildStatus))
    return BuildRecord.from_dict(data)


def write_record_file(path: Path, record: BuildRecord) -> None:
    """Write the record to ``path`` atomically (sorted keys, so equal records are equal
    bytes)."""
    text = json.dumps(record.to_dict(), indent=2, sort_keys=True) + "\n"
    write_atomic(path, text.encode("utf-8"))
