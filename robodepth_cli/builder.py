"""``robodepth build``: from a resolved configuration to a complete, verifiable output tree.

:func:`build` runs these steps; everything that can make the whole build impossible is
checked before the first image is touched:

1. check the root, read the split (a standard one is downloaded and checked on first use)
   and find every listed source image; abort if none is there;
2. create OUT, check it is writable, take its lock, refuse symlinks in it that lead outside
   it, delete temporary files a killed build left behind;
3. plan: one :class:`Task` per source image, holding its jobs (clean + variants x levels)
   and, for each output already listed in the manifest with the current settings, the
   sha256 to check it against;
4. run the tasks in a joblib pool (in-process for one worker). A worker hashes the outputs
   that may be done, and only if something is left decodes and resizes the source once,
   writes the clean image and renders the rest with the dataset's renderer, writing each
   PNG atomically. It returns manifest rows, never images;
5. append rows to the manifest as tasks finish, then compact it and write the build record.

A source image that cannot be read fails its own outputs (rows with an error) and the rest
goes on; a write error (disk full, permissions) stops the build.
"""

from __future__ import annotations

import functools
import itertools
import os
import platform
import signal
import sys
import tempfile
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from . import __version__, manifest, splits
from .config import BuildConfig
from .datasets import CLEAN, Dataset, Job, Renderer, get_dataset, locate, read_split
from .imageio import PNG_ENCODER, ImageError, load_clean, write_png
from .manifest import Row, sha256_bytes
from .errors import RobodepthError
from .executors import Executor, LocalExecutor

PNG_COMPRESS_LEVEL = 1  # zlib level: pixels are identical at any level; 1 is the fastest
MAX_ERRORS_SHOWN = 10


class BuildError(RobodepthError):
    """A problem that makes the whole build impossible; nothing was written because of it
    (or, for a write error mid-build, everything finished so far is kept)."""


@dataclass(frozen=True)
class Task:
    """One source image and all of its outputs. Small: this is what a worker receives."""

    key: str
    source: str  # relative to the root; "" when it was not found
    path: str | None  # absolute source path, None when not found
    error: str  # why the source cannot be used ("" if it can)
    jobs: tuple[Job, ...]
    expected: tuple[str | None, ...]  # per job: sha256 of a matching manifest row, else None


@dataclass(frozen=True)
class Context:
    """What every task of a build shares."""

    out: str
    size: tuple[int, int]
    seed: int
    renderer: Renderer
    single_thread: bool  # True in pool workers: the pool already uses every core


@dataclass
class Summary:
    total: int
    written: int = 0
    skipped: int = 0
    failed: int = 0
    seconds: float = 0.0
    errors: list[str] = field(default_factory=list)  # distinct messages, first ones only
    fatal: str = ""  # the error that stopped the build
    interrupted: bool = False

    def add(self, status: str, row: Row) -> None:
        if status == "written":
            self.written += 1
        elif status == "skipped":
            self.skipped += 1
        else:
            self.failed += 1
            if row.error not in self.errors and len(self.errors) < MAX_ERRORS_SHOWN:
                self.errors.append(row.error)
            if status == "fatal":
                self.fatal = row.error

    @property
    def complete(self) -> bool:
        return not (self.failed or self.fatal or self.interrupted)

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("total", "written", "skipped", "failed", "seconds",
                                               "errors", "fatal", "interrupted")}

    def text(self) -> str:
        done = self.written + self.skipped + self.failed
        rate = self.written / self.seconds if self.seconds > 0 else 0.0
        lines = [f"{self.written} written, {self.skipped} skipped (already done), {self.failed} failed"
                 f" of {self.total} images in {self.seconds:.1f} s ({rate:.1f} written/s)"]
        if self.interrupted or self.fatal:
            lines.append(f"stopped after {done} of {self.total}; rerun the same command to resume")
        if self.errors:
            lines.append("failures (each row with an error in manifest.csv):")
            lines += [f"  {e}" for e in self.errors]
            if self.failed > len(self.errors):
                lines.append(f"  ... {self.failed} failed images in all")
        return "\n".join(lines)


# --- worker side ---------------------------------------------------------------------------

_configured = False


def _configure_worker(single_thread: bool) -> None:
    global _configured
    if single_thread and not _configured:
        import cv2

        cv2.setNumThreads(1)  # two processes on two cores: extra OpenCV threads only contend
        # Ctrl-C reaches the whole process group; the main process stops the pool, and a
        # worker interrupted on its own would only print a traceback.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        _keep_freed_memory()
        _configured = True


def _keep_freed_memory() -> None:
    """Let glibc reuse freed blocks for the next image's large temporaries instead of
    returning them to the system and faulting fresh pages in again (about 7% of a worker's
    time here). A no-op where there is no glibc."""
    import ctypes

    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 256 << 20)  # M_MMAP_THRESHOLD: arrays up to 256 MB come from the heap
        libc.mallopt(-1, 1 << 30)  # M_TRIM_THRESHOLD: keep up to 1 GB of freed heap
    except (OSError, AttributeError):
        pass


def run_task(task: Task, ctx: Context) -> list[tuple[str, Row]]:
    """Make the outputs of one source image that are not already done.

    Returns ``(status, row)`` per job, status one of ``skipped`` (the file matches the
    manifest), ``written``, ``failed`` (this job or its source is broken; any stale file
    at its path is removed) or ``fatal`` (the file could not be written: the build stops).
    """
    _configure_worker(ctx.single_thread)
    out = Path(ctx.out)
    h, w = ctx.size

    def row(job: Job, sha: str = "", error: str = "") -> Row:
        return Row(job.path(task.key), task.source, job.variant, job.level, ctx.seed, h, w, sha, error,
                   _fingerprint(ctx.renderer, job))

    results: list[tuple[str, Row]] = []
    todo: list[Job] = []
    for job, sha in zip(task.jobs, task.expected):
        if sha is not None and _sha_or_none(out / job.path(task.key)) == sha:
            results.append(("skipped", row(job, sha)))
        else:
            todo.append(job)
    if not todo:
        return results

    def fail(job: Job, message: str) -> None:
        (out / job.path(task.key)).unlink(missing_ok=True)
        results.append(("failed", row(job, error=message)))

    clean, message = _load(task, ctx.size)
    if clean is None:
        for job in todo:
            fail(job, message)
        return results

    clean.flags.writeable = False
    # Lazily, so only one rendered image is alive at a time.
    rendered = itertools.chain(
        ((j, clean) for j in todo if j.variant == CLEAN),
        ctx.renderer.render(clean, task.key, [j for j in todo if j.variant != CLEAN]))
    for job, img in rendered:
        if isinstance(img, BaseException):
            fail(job, f"{task.path}: {_job_name(job)}: {type(img).__name__}: {img}")
            continue
        target = out / job.path(task.key)
        try:
            data = write_png(target, img, PNG_COMPRESS_LEVEL)
        except OSError as exc:
            results.append(("fatal", row(job, error=_cannot_write(target, exc))))
            return results
        results.append(("written", row(job, sha256_bytes(data))))
    return results


def _fingerprint(renderer: Renderer, job: Job) -> str:
    return "" if job.variant == CLEAN else renderer.fingerprint(job.variant)


def _load(task: Task, size: tuple[int, int]):
    """(clean image, "") or (None, why the source cannot be used)."""
    if task.error:
        return None, task.error
    try:
        return load_clean(task.path, size), ""
    except ImageError as exc:
        return None, str(exc)
    except Exception as exc:  # e.g. Pillow's DecompressionBombError: still this image's problem
        return None, f"{task.path}: {type(exc).__name__}: {exc}"


def _cannot_write(path, exc: OSError) -> str:
    return f"{path}: cannot write ({exc.strerror or exc})"


def _job_name(job: Job) -> str:
    return job.variant if job.level is None else f"{job.variant} level {job.level}"


def _sha_or_none(path: Path) -> str | None:
    try:
        return manifest.sha256_file(path)
    except OSError:
        return None


# --- main process --------------------------------------------------------------------------

def check_root(root: Path) -> Path:
    root = Path(root)
    if not root.exists():
        raise BuildError(f"{root}: the root directory does not exist")
    if not root.is_dir():
        raise BuildError(f"{root}: the root is not a directory")
    return Path(os.path.realpath(root))


def split_file(cfg: BuildConfig) -> Path:
    """The split file of ``cfg``: a standard split (cached, downloaded on first use) or the
    user's file."""
    if cfg.split in splits.records():
        return splits.standard_split(cfg.split)
    return Path(cfg.split)


def prepare_out(out: Path) -> Path:
    """Create ``out`` if needed and prove it writable; :class:`BuildError` otherwise."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise BuildError(f"{out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise BuildError(f"{out}: cannot write the output directory ({exc.strerror or exc})") from None
    return out


def plan(ds: Dataset, cfg: BuildConfig, located: list[tuple], done: dict[str, Row],
         renderer: Renderer) -> list[Task]:
    """One task per source. ``located`` holds (entry, source relpath, path, error)."""
    jobs = tuple(ds.jobs(cfg.variants, cfg.levels))
    fingerprints = {job.variant: _fingerprint(renderer, job) for job in jobs}
    tasks = []
    for entry, source, path, error in located:
        expected = []
        for job in jobs:
            r = done.get(job.path(entry.key))
            # A source that has gone missing does not spoil the outputs already made from it.
            same = (r is not None and not r.error and (r.source == source or bool(error))
                    and r.seed == cfg.seed and (r.height, r.width) == cfg.size
                    and r.params == fingerprints[job.variant])
            expected.append(r.sha256 if same else None)
        tasks.append(Task(entry.key, source, path and str(path), error, jobs, tuple(expected)))
    return tasks


def _locate_all(root: Path, entries) -> list[tuple]:
    located = []
    for e in entries:
        try:
            rel, path = locate(root, e)
            located.append((e, rel, path, ""))
        except ImageError as exc:
            located.append((e, "", None, str(exc)))
    return located


def library_versions(ds: Dataset) -> dict[str, str]:
    from importlib import metadata

    versions = {"python": platform.python_version(), "robodepth-cli": __version__}
    for name in ds.libraries():
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def build(cfg: BuildConfig, root: Path, out: Path, *, progress: bool = False,
          command: list[str] | None = None) -> Summary:
    """Build dataset ``cfg`` from ``root`` into ``out`` (see the module docstring).

    Raises :class:`BuildError`, ``SplitError`` or ``ManifestError`` for whole-build problems
    (before any work) and returns the :class:`Summary` otherwise; ``Summary.complete`` is
    False when images failed, a write error stopped the build, or it was interrupted
    (Ctrl-C; the manifest and record are saved first).
    """
    ds = get_dataset(cfg.dataset)
    root = check_root(root)
    split_path = split_file(cfg)
    entries = read_split(split_path, ds.split_format)[: cfg.limit]
    located = _locate_all(root, entries)
    if all(error for *_, error in located):
        raise BuildError(f"{root}: none of the {len(located)} images of {split_path} is there; "
                         f"wrong --root? (first: {located[0][3]})")
    try:
        # Before OUT is touched: a renderer may check the user's files (KITTI-S loads and
        # validates the checkpoints and style images here).
        renderer = ds.renderer(cfg)
    except ValueError as exc:
        raise BuildError(str(exc)) from None
    out = prepare_out(out)
    with manifest.BuildLock(out):
        leaving = manifest.links_leaving(out)
        if leaving:
            link, target = leaving[0]
            raise BuildError(f"{out / link}: a symlink to {target}, outside {out}; refused (a build "
                             f"writes only inside its output directory)")
        manifest.remove_temporaries(out)
        tasks = plan(ds, cfg, located, manifest.read_manifest(out), renderer)
        summary = Summary(total=sum(len(t.jobs) for t in tasks))
        executor = LocalExecutor(min(cfg.jobs, len(tasks)))
        record = {
            "robodepth": __version__, "command": command or [], "dataset": ds.name,
            "config": cfg.as_dict(), "seed": cfg.seed, "root": str(root), "out": str(out.resolve()),
            "split": {"path": str(split_path), "sha256": sha256_bytes(split_path.read_bytes()),
                      "images": len(entries)},
            "versions": library_versions(ds), "png_compress_level": PNG_COMPRESS_LEVEL,
            "png_encoder": PNG_ENCODER,
            "executor": executor.describe(),
            "started": _now(), "finished": None, "status": "running",
        }
        try:
            manifest.write_record(out, record)
        except OSError as exc:
            raise BuildError(_cannot_write(out / manifest.RECORD, exc)) from None
        ctx = Context(str(out), cfg.size, cfg.seed, renderer,
                      single_thread=cfg.jobs > 1 and len(tasks) > 1)
        t0 = time.perf_counter()
        try:
            _run(tasks, ctx, executor, out, summary, progress)
        except KeyboardInterrupt:
            summary.interrupted = True
        summary.seconds = round(time.perf_counter() - t0, 3)
        try:
            manifest.compact_manifest(out)
        except OSError as exc:  # the appended manifest stays valid, only unsorted
            summary.fatal = summary.fatal or _cannot_write(out / manifest.MANIFEST, exc)
        if summary.interrupted or summary.fatal:
            # A pool stopped early kills its workers, perhaps in the middle of a write.
            manifest.remove_temporaries(out)
        status = ("interrupted" if summary.interrupted else "stopped" if summary.fatal
                  else "finished" if summary.complete else "finished with failures")
        try:
            manifest.write_record(out, {**record, "finished": _now(), "status": status,
                                        "summary": summary.as_dict()})
        except OSError as exc:
            summary.fatal = summary.fatal or _cannot_write(out / manifest.RECORD, exc)
    return summary


def _run(tasks: list[Task], ctx: Context, executor: Executor, out: Path, summary: Summary,
         progress: bool) -> None:
    from tqdm import tqdm

    try:
        writer = manifest.ManifestWriter(out)
    except OSError as exc:
        summary.fatal = _cannot_write(out / manifest.MANIFEST, exc)
        return
    bar = tqdm(total=summary.total, unit="img", disable=None if progress else True,
               file=sys.stderr, dynamic_ncols=True, smoothing=0.05)
    with bar, writer:
        for results in executor.map_unordered(functools.partial(run_task, ctx=ctx), tasks):
            try:
                writer.append([r for status, r in results if status != "skipped"])
            except OSError as exc:  # these images exist but are not recorded: a rerun redoes them
                summary.fatal = _cannot_write(writer.path, exc)
            for status, r in results:
                summary.add(status, r)
            bar.update(len(results))
            if summary.fatal:
                return
