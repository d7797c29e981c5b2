"""``robodepth verify``: every file of a build against its manifest and its recorded plan.

A build is verified when every output the recorded plan asks for has a manifest row, every
row's file exists with the bytes its sha256 names, no failed job is recorded, and no file
lies in OUT that the manifest does not list (bookkeeping files aside).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from ..files import sha256_file
from ..versionlock import build_note
from .layout import BOOKKEEPING, JOURNAL, MANIFEST
from .folder import OutputFolder
from .manifest import ManifestError
from .record import BuildStatus


@dataclass
class VerifyReport:
    checked: int
    missing: list[str]  # in the manifest, not on disk
    changed: list[str]  # on disk with other bytes than the manifest says
    extra: list[str]  # on disk, not in the manifest
    failed: list[str]  # jobs the build recorded as failed
    reasons: dict[str, str] = field(default_factory=dict)  # failed output -> its error
    planned: int | None = None  # outputs the recorded plan asks for (None: no plan recorded)
    unbuilt: list[str] = field(default_factory=list)  # planned, with no manifest row at all
    built: int = 0  # planned outputs with a manifest row and no error
    status: BuildStatus | None = None  # the build record's status
    versions_note: str = ""  # the recorded versions that differ from the lock's, in one line
    unfinished: str = ""  # an export's: why it is not finished (its line), else ""

    @property
    def ok(self) -> bool:
        return not (self.missing or self.changed or self.extra or self.failed or self.unbuilt
                    or self.unfinished)

    def incomplete(self) -> str:
        """``"incomplete: 728 of 3640 outputs (build interrupted; rerun the build command
        to finish)"`` (an export's: :attr:`unfinished`), or "" when every planned output was
        built (or failed)."""
        if self.unfinished:
            return self.unfinished
        if not self.unbuilt:
            return ""
        why = {BuildStatus.RUNNING: "build interrupted", BuildStatus.INTERRUPTED: "build interrupted",
               BuildStatus.STOPPED: "build stopped by an error"}.get(self.status, "not built yet")
        return (f"incomplete: {self.built} of {self.planned} outputs ({why}; rerun the build "
                f"command to finish)")


def tree_files(out: Path) -> set[str]:
    """Every file under ``out`` (relative posix paths) except the bookkeeping files."""
    found = set()
    for dirpath, dirs, files in os.walk(out):
        rel = os.path.relpath(dirpath, out)
        if rel == ".":
            dirs[:] = [d for d in dirs if d != JOURNAL]
        for name in files:
            p = name if rel == "." else f"{rel}/{name}".replace(os.sep, "/")
            if p not in BOOKKEEPING:
                found.add(p)
    return found


def verify(out: Path, *, planned_outputs, threads: int = 4, progress=None,
           on_total=None) -> VerifyReport:
    """Re-hash every file of ``out`` against its manifest. ``on_total(n)`` is called once
    with the number of files to hash, then ``progress(n)`` as files are checked.
    ``planned_outputs(record)``: every output the build record's plans ask for (None when
    it keeps none): :func:`robodepth_cli.building.checks.planned_outputs`, which knows the
    datasets."""
    from concurrent.futures import ThreadPoolExecutor

    out = Path(out)
    if not out.exists():
        raise ManifestError(f"{out}: does not exist")
    if not out.is_dir():
        raise ManifestError(f"{out}: not a directory")
    folder = OutputFolder(out)
    holder = folder.lock_holder()
    if holder:
        raise ManifestError(f"{out}: a build (pid {holder}) is writing here right now; verify "
                            f"when it has finished")
    if not (out / MANIFEST).is_file():
        raise ManifestError(f"{out}: no {MANIFEST}; not a robodepth build output")
    rows = folder.recorded()  # a killed build's journal counts: its files are complete
    record = folder.record()
    planned = planned_outputs(record)
    on_disk = tree_files(out)
    failed = sorted(p for p, r in rows.items() if r.error)
    listed = {p: r for p, r in rows.items() if not r.error}
    missing = sorted(p for p in listed if p not in on_disk)
    extra = sorted(p for p in on_disk if p not in listed)
    present = sorted(p for p in listed if p in on_disk)

    def check(p: str) -> bool:
        return sha256_file(out / p) == listed[p].sha256

    changed = []
    if on_total:
        on_total(len(present))
    with ThreadPoolExecutor(threads) as pool:  # hashlib and file reads release the GIL
        for p, same in zip(present, pool.map(check, present)):
            if not same:
                changed.append(p)
            if progress:
                progress(1)
    report = VerifyReport(len(present), missing, changed, extra, failed,
                          reasons={p: rows[p].error for p in failed},
                          status=record.status if record else None,
                          versions_note=build_note(record.versions) if record else "")
    if planned is not None:
        report.planned = len(planned)
        report.unbuilt = sorted(p for p in planned if p not in rows)
        report.built = sum(1 for p in planned if p in listed)
    return report
