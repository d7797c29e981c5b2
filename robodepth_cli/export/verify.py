"""``robodepth verify DIR`` of an export: every file in its shards against the build's
manifest carried in the export (``robodepth/manifest.csv``).

Each shard is read whole, row by row (memory: one row group or one member), and each
row's bytes hashed: a row whose bytes are not the manifest's is changed, a file of the
manifest that no shard holds is missing, a row the manifest does not list (or a second
row for one file) is extra, and so is a file under ``data/`` that the export record does
not name. A shard whose bytes differ from the export record, or that cannot be read, is
named among the changed with the reason; the files it should hold count as missing.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..files import sha256_bytes, sha256_file
from ..output.manifest import ManifestError, read_manifest
from ..output.verify import VerifyReport
from .layout import DATA, META
from .reader import read_export_record, shard_rows


def verify_export(to: Path, *, progress=None) -> VerifyReport:
    to = Path(to)
    record = read_export_record(to)
    rows = read_manifest(to / META)
    if not rows:
        raise ManifestError(f"{to / META}: no manifest; not a robodepth export")
    expected = {p: r.sha256 for p, r in rows.items() if not r.error}
    seen: set[str] = set()
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
            for output, data in shard_rows(file, record.get("format"), e["prefix"]):
                checked += 1
                if output not in expected or output in seen:
                    extra.append(f"{output} (in {e['file']})")
                    continue
                seen.add(output)
                if sha256_bytes(data) != expected[output]:
                    changed.append(output)
                if progress:
                    progress(1)
        except Exception as exc:  # noqa: BLE001 -- any reader error means a damaged shard
            changed.append(f"{e['file']} (shard: unreadable, {type(exc).__name__}: {exc})")
    for dirpath, _, files in os.walk(to / DATA):
        for name in files:
            rel = Path(dirpath, name).relative_to(to).as_posix()
            if rel not in named:
                extra.append(rel)
    missing = sorted(p for p in expected if p not in seen)
    return VerifyReport(checked, missing, changed, sorted(extra), [],
                        status=record.get("status", ""))
