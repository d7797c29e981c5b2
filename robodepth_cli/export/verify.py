"""``robodepth verify DIR`` of an export: every file in its shards against the build's
manifest carried in the export (``robodepth/manifest.csv``), as docs/export.md says. Each
shard is read whole, row by row (memory: one row group or one member), each row's bytes
hashed, and each file sorted into changed, missing or extra; a shard that differs from the
export record or cannot be read is named among the changed with the reason."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import reraise_interrupt
from ..files import sha256_bytes, sha256_file
from ..output.folder import OutputFolder
from ..output.manifest import ManifestError
from ..output.record import BuildStatus
from ..output.verify import VerifyReport
from ..output.layout import GT_FILE
from .layout import DATA, GT_CONFIG, META
from .reader import gt_rows, read_export_record, shard_rows


def verify_export(to: Path, *, progress=None) -> VerifyReport:
    to = Path(to)
    record = read_export_record(to)
    rows = OutputFolder(to / META).rows()
    if not rows:
        raise ManifestError(f"{to / META}: no manifest; not a robodepth export")
    expected = {p: r.sha256 for p, r in rows.items() if not r.error}
    maps = {(p, k): sha for e in record.get("shards") or [] if e["config"] == GT_CONFIG
            for p, k, sha in e.get("maps") or []}
    seen: set = set()
    changed, extra = [], []
    checked = 0
    named = set()
    for e in record.get("shards") or []:
        file = to / e["file"]
        named.add(e["file"])
        if not file.is_file():
            continue  # its files are missing
        if e.get("sha256") and sha256_file(file) != e["sha256"]:
            changed.append(f"{e['file']} (shard: its sha256 is not the export record's)")
        try:
            for name, data in _rows(file, record.get("format"), e):
                checked += 1
                want = maps.get(name) if isinstance(name, tuple) else expected.get(name)
                label = _label(name)
                if want is None or name in seen:
                    extra.append(f"{label} (in {e['file']})")
                    continue
                seen.add(name)
                if sha256_bytes(data) != want:
                    changed.append(label)
                if progress:
                    progress(1)
        except Exception as exc:  # noqa: BLE001 -- any reader error means a damaged shard
            reraise_interrupt(exc)
            changed.append(f"{e['file']} (shard: unreadable, {type(exc).__name__}: {exc})")
    for dirpath, _, files in os.walk(to / DATA):
        for name in files:
            rel = Path(dirpath, name).relative_to(to).as_posix()
            if rel not in named:
                extra.append(rel)
    # A ground-truth file of the build counts as exported when every map of it is there.
    gt_files = {p for p, _ in maps}
    missing = sorted(p for p in expected if p not in seen and p not in gt_files)
    missing += sorted(_label(m) for m in maps if m not in seen)
    unfinished = ""
    if record.get("status") != "finished":
        # Stopped (or killed) before its end: the files of the shards not written yet are
        # not missing, they are still to come.
        shards = record.get("shards") or []
        there = sum(1 for e in shards if (to / e["file"]).is_file())
        unfinished = (f"{to}: an unfinished export ({there} of {len(shards)} shards written); "
                      "rerun the export command to finish it")
        missing = []
    return VerifyReport(checked, missing, changed, sorted(extra), [],
                        status=BuildStatus(record["status"]) if record.get("status") == "running" else None,
                        unfinished=unfinished)


def _rows(file: Path, fmt: str, entry: dict):
    """(name, bytes) of each row of a shard: an image's path in the build, or a ground-truth
    map's (path of its file, image key) with its ``.npy`` bytes."""
    if entry["config"] != GT_CONFIG:
        yield from shard_rows(file, fmt, entry["prefix"])
        return
    for path, key, data in gt_rows(file, fmt):
        yield (path, key), data


def _label(name) -> str:
    """How a row is named in the report: its path, or ``<file> (<key>)`` for a map."""
    if not isinstance(name, tuple):
        return name
    path, key = name
    return f"{path} ({key})" if key and path == GT_FILE else path
