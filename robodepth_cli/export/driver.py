"""The export driver: check everything first, then write the shards one by one.

Each shard is written under a temporary name and renamed when whole, and a line with its
sha256 is appended to ``robodepth/.shards.jsonl`` (rewriting the export record after every
shard would cost the square of their number): a stopped export, run again with the same
options, writes only the shards that are missing. At the end the export record
(``robodepth/export.json``) takes every shard's sha256, ``status`` says ``finished``, the
card is written and the journal removed.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from ..files import atomic_output, check_writable, sha256_file, write_atomic
from ..output.layout import MANIFEST, RECORD as BUILD_RECORD
from ..output.record import BuildStatus
from ..formats import stamp
from .layout import CARD, DATA, FORMATS, GT_CONFIG, JOURNAL, META, RECORD, SCHEMA
from .plan import ExportError, Shard, plan
from .card import holdings
from .reader import read_export_record
from .shards import WRITERS

_DONE = ("file", "sha256", "bytes", "maps")  # what the journal keeps of a finished shard


@dataclass
class ExportSummary:
    shards: int = 0
    written: int = 0  # shards written by this run (the rest were there already)
    rows: int = 0
    size: int = 0  # bytes of the shards
    source_size: int = 0  # bytes of the build's files exported
    # The images without a usable depth map (their ground truth and depth-aware outputs
    # do not exist), with the reason.
    no_depth: dict = field(default_factory=dict)


def _inside(a: Path, b: Path) -> bool:
    return a == b or b in a.parents


def _open_build(out: Path, open_dataset):
    from ..output.folder import OutputFolder

    dataset = open_dataset(out, warn=False)
    folder = OutputFolder(out)
    holder = folder.lock_holder()
    if holder:
        raise ExportError(f"{out}: a build (pid {holder}) is writing here right now; export "
                          "when it has finished")
    rows = folder.rows()
    # Images whose depth map is unusable have no ground truth and no depth-aware outputs;
    # a rerun cannot make them, so the build is exported without those files.
    status = dataset.record.status
    if status is BuildStatus.FAILURES and not _unexplained(dataset, rows):
        status = BuildStatus.FINISHED
    if dataset.failed or status not in (BuildStatus.FINISHED, None):
        why = dataset.incomplete() or f"{out}: the build's status is {getattr(status, 'value', '')!r}"
        raise ExportError(f"{why}; export a finished build (rerun the build command to finish it)")
    return dataset, rows


def _unexplained(dataset, rows: dict) -> list[str]:
    """The failed rows of the build that an unusable depth map does not explain."""
    from ..corruptions import depth_aware_variant
    from ..output.layout import GT_DIR, depth_gt_name, variant_dir

    lacking = {f"{GT_DIR}/{depth_gt_name(k)}" for k in dataset.no_depth}
    return [p for p, r in rows.items() if r.error and p not in lacking
            and not (depth_aware_variant(r.variant)
                     and p[len(variant_dir(r.variant, r.level)) + 1:] in dataset.no_depth)]


def _entry(shard: Shard, fmt: str) -> dict:
    prefix = "" if shard.config == GT_CONFIG else shard.items[0].output[:-len(shard.items[0].key) - 1]
    return {"file": shard.name(FORMATS[fmt]), "config": shard.config, "split": shard.split,
            "prefix": prefix, "start": shard.start, "rows": len(shard.items),
            "source_bytes": shard.size, "sha256": None, "bytes": None,
            **({"maps": None} if shard.config == GT_CONFIG else {})}


def export(out: Path, to: Path, fmt: str, shard_bytes: int, *, open_dataset, progress: bool = True,
           version: str = "") -> ExportSummary:
    """Export the finished build ``out`` into ``to`` as ``fmt`` shards (see the module);
    ``open_dataset``: :func:`robodepth_cli.api.open_dataset`, which reads the build."""
    from ..files import sha256_bytes
    from ..progress import bar

    out, to = Path(out), Path(to)
    if _inside(to.resolve(), out.resolve()) or _inside(out.resolve(), to.resolve()):
        raise ExportError(f"--to {to}: must be outside the build {out} (and not hold it): the "
                          "build stays as it is")
    dataset, rows = _open_build(out, open_dataset)
    check_writable(to / CARD, "--to")
    made = _made_by_this_run(to)  # removed again if a build file turns out changed mid-way
    manifest = (out / MANIFEST).read_bytes()
    shards = plan(out, dataset, rows, shard_bytes)
    entries = [_entry(s, fmt) for s in shards]
    header = {**stamp(SCHEMA), "format": fmt, "shard_size": shard_bytes,
              "dataset": dataset.name, "build_manifest_sha256": sha256_bytes(manifest)}
    _resume(to, header, entries)
    record = {**header, "status": "running", "shards": entries}
    try:
        write_atomic(to / META / MANIFEST, manifest)
        write_atomic(to / META / BUILD_RECORD, (out / BUILD_RECORD).read_bytes())
        _write_record(to, record)
    except OSError as exc:
        raise ExportError(_cannot(to, exc)) from None
    summary = ExportSummary(shards=len(shards), rows=sum(len(s.items) for s in shards),
                            source_size=sum(s.size for s in shards), no_depth=dataset.no_depth)
    write = WRITERS[fmt]
    with bar("B", summary.source_size, progress=progress, unit_scale=True, unit_divisor=1024,
             desc="export") as meter:
        for shard, e in zip(shards, entries):
            target = to / e["file"]
            gt = shard.config == GT_CONFIG
            if target.is_file() and e["sha256"] is None:  # renamed, then stopped: hash it now
                e["sha256"], e["bytes"] = sha256_file(target), target.stat().st_size
            # A ground-truth shard whose map hashes were not recorded is written again.
            if target.is_file() and e["bytes"] == target.stat().st_size and not (gt and e["maps"] is None):
                meter.update(shard.size)
                continue
            try:
                with atomic_output(target) as fh:
                    maps = write(fh, out, shard, gt, meter.update)
                    fh.flush()
                e["sha256"], e["bytes"] = sha256_file(target), target.stat().st_size
                if gt:
                    e["maps"] = maps
                with open(to / META / JOURNAL, "a", encoding="utf-8") as fh:
                    fh.write(json.dumps({k: e[k] for k in _DONE if k in e}) + "\n")
            except ExportError:  # a file of the build changed since the build: refused
                _undo(made)
                raise
            except OSError as exc:
                raise ExportError(_cannot(target, exc)) from None
            summary.written += 1
    _finish(to, dataset, record, fmt, version, holdings(shards, rows))
    summary.size = sum(e["bytes"] for e in entries)
    return summary


def _made_by_this_run(to: Path) -> tuple[Path, bool] | None:
    """(folder, whether it is to be removed itself) holding everything an export into
    ``to`` starting now will make: the topmost missing folder of ``to`` (removed), or ``to``
    itself when it exists without an export record (it is empty then, see :func:`_resume`;
    only its contents go); None when ``to`` holds a stopped export."""
    if read_export_record(to) is not None:
        return None
    top = to.absolute()
    while not top.parent.exists():
        top = top.parent
    return (top, True) if not top.exists() else (top, False)


def _undo(made: tuple[Path, bool] | None) -> None:
    """Remove what this run made (:func:`_made_by_this_run`): a refused export leaves no
    half-made folder behind."""
    import shutil

    if made is None:
        return
    folder, itself = made
    if itself:
        shutil.rmtree(folder, ignore_errors=True)
        return
    for child in list(folder.iterdir()) if folder.is_dir() else []:
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child, ignore_errors=True)
        else:
            child.unlink(missing_ok=True)


def _resume(to: Path, header: dict, entries: list[dict]) -> None:
    """Take the shards a stopped export of the same build and options finished in ``to``
    (into ``entries``); refused for a folder that holds something else."""
    previous = read_export_record(to)
    if previous is None and to.is_dir() and any(to.iterdir()):
        raise ExportError(f"--to {to}: not empty and not an export; choose a new or empty folder")
    if previous is None:
        return
    same = ({k: previous.get(k) for k in header} == header
            and [e["file"] for e in previous.get("shards", [])] == [e["file"] for e in entries])
    if not same:
        raise ExportError(f"--to {to}: holds an export of another build or with other options "
                          "(--format, --shard-size); choose a new or empty folder")
    done = {e["file"]: e for e in previous["shards"] if e.get("sha256")}
    done.update(_journal(to))
    for e in entries:
        if e["file"] in done:
            e.update({k: done[e["file"]].get(k) for k in _DONE if k in e})


def _finish(to: Path, dataset, record: dict, fmt: str, version: str, held: dict) -> None:
    from .card import card

    _remove_strays(to)
    record["status"] = "finished"
    try:
        write_atomic(to / CARD, card(dataset.record, record["shards"], fmt, version, held).encode("utf-8"))
        _write_record(to, record)
        (to / META / JOURNAL).unlink(missing_ok=True)
    except OSError as exc:
        raise ExportError(_cannot(to, exc)) from None


def _journal(to: Path) -> dict[str, dict]:
    """The shards a stopped export finished, by file: the journal's complete lines (a line
    cut short by a kill is ignored; its shard is hashed again)."""
    done = {}
    try:
        lines = (to / META / JOURNAL).read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        return done
    for line in lines:
        try:
            entry = json.loads(line)
            done[entry["file"]] = entry
        except (ValueError, KeyError, TypeError):
            continue
    return done


def _remove_strays(to: Path) -> None:
    """Temporary files a killed export left under ``data/``."""
    from ..files import is_temporary

    for dirpath, _, files in os.walk(to / DATA):
        for name in files:
            if is_temporary(name):
                os.unlink(os.path.join(dirpath, name))


def _write_record(to: Path, record: dict) -> None:
    write_atomic(to / META / RECORD, (json.dumps(record, indent=1) + "\n").encode("utf-8"))


def _cannot(path: Path, exc: OSError) -> str:
    from ..errors import cannot_write

    return cannot_write(path, exc, "--to")
