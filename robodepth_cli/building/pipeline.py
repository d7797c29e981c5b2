"""``robodepth build``: from a resolved configuration to a complete, verifiable output tree.

:func:`build` reads as the list of its steps; everything that can make the whole build
impossible is checked before the first image is touched:

1. :func:`~.gather.gather_sources`: check the root (and that it and OUT do not overlap),
   read the split (a standard one is downloaded and checked on first use) and find every
   listed image, one :class:`~.jobs.Source` per entry; abort if none is there, if one
   resolves into OUT, or if OUT holds a build of another dataset, size or seed
   (:mod:`.checks`); a custom build finds its images under the root instead;
2. ``Dataset.renderer``: the object that turns a clean image into its variants (KITTI-S
   checks its checkpoints and style images here, still before OUT is touched);
3. :class:`~robodepth_cli.output.folder.OutputFolder`: create OUT, prove it writable, take
   its lock, refuse symlinks in it that lead outside it, delete temporary files a killed
   build left and record what it wrote;
4. :func:`plan`: one :class:`~.jobs.SourceJobs` per source, holding its jobs (clean + variants x levels)
   and, for each output already in the manifest with the current settings and made from
   the source as it is now (same size; same sha256, which the worker checks), the sha256
   to check it against;
5. :func:`run_tasks`: the executor runs :func:`~.jobs.run_source_jobs` on every task (in-process or in a
   pool of workers). A worker hashes the outputs that may be done and, only if something
   is left, decodes and resizes the source once, writes the clean image and renders the
   rest, writing each PNG atomically. It returns one ``(JobState, manifest row)`` per job,
   never images; the main process appends the rows to the manifest as tasks finish;
6. :func:`add_ground_truth` and :func:`finish`: the ground truth, the manifest, the record.

A source image that cannot be read fails its own outputs (rows with an error) and the rest
goes on; a write error (disk full, permissions) stops the build.
"""

from __future__ import annotations

import functools
import os
import platform
import shlex
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from .. import __version__
from ..errors import cannot_write
from ..imageio import PNG_ENCODERS, check_png
from ..output.folder import OutputFolder
from ..output.layout import RECORD
from ..output.manifest import Params, Row
from ..output.record import BuildRecord, BuildStatus, now, plan_entry
from ..sources.datasets import Dataset, get_dataset
from .renderers import Renderer, make_renderer as renderer_of
from .scenedepth import DEPTH
from . import checks as buildchecks
from .checks import BuildError
from .config import BuildConfig
from .executors import Executor, ExecutorError, checked_executor
from .gather import check_root, gather_sources, orientation_record
from .vanished import prune
from .jobs import (PNG_COMPRESS_LEVEL, Context, JobState, Source, SourceJobs, fingerprint, for_source,
                    run_source_jobs, same_source)

MAX_ERRORS_SHOWN = 10


@dataclass
class Summary:
    """What a build did. Its counts are of outputs (one file each: a clean image, a variant,
    a ground-truth file), except ``images`` and ``failed_images``: source images."""

    total: int  # outputs asked for
    written: int = 0
    skipped: int = 0
    failed: int = 0
    images: int = 0  # source images
    failed_images: int = 0  # source images with at least one failed output
    out: str = ""  # where the outputs went, as the user named it
    seconds: float = 0.0
    errors: list[str] = field(default_factory=list)  # distinct messages, first ones only
    fatal: str = ""  # the error that stopped the build
    interrupted: bool = False
    notes: list[str] = field(default_factory=list)  # e.g. why the ground truth was not made

    def add(self, state: JobState, row: Row) -> None:
        if state is JobState.WRITTEN:
            self.written += 1
        elif state is JobState.SKIPPED:
            self.skipped += 1
        else:
            self.failed += 1
            if row.error not in self.errors and len(self.errors) < MAX_ERRORS_SHOWN:
                self.errors.append(row.error)
            if state is JobState.FATAL:
                self.fatal = row.error

    def add_image(self, results: list[tuple[JobState, Row]]) -> None:
        """Count the outputs of one source image."""
        for state, row in results:
            self.add(state, row)
        if any(state in (JobState.FAILED, JobState.FATAL) for state, _ in results):
            self.failed_images += 1

    @property
    def complete(self) -> bool:
        return not (self.failed or self.fatal or self.interrupted)

    @property
    def status(self) -> BuildStatus:
        """The build record's ``status`` once the run is over."""
        return (BuildStatus.INTERRUPTED if self.interrupted else BuildStatus.STOPPED if self.fatal
                else BuildStatus.FINISHED if self.complete else BuildStatus.FAILURES)

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("total", "written", "skipped", "failed", "images",
                                               "failed_images", "seconds", "errors", "fatal",
                                               "interrupted", "notes")}

    def _failed_text(self) -> str:
        """``"14 failed (outputs of 2 images)"``: the two counts, each named."""
        if not self.failed_images:
            return f"{self.failed} failed"
        return f"{self.failed} failed (outputs of {_count(self.failed_images, 'image')})"

    def text(self) -> str:
        done = self.written + self.skipped + self.failed
        rate = self.written / self.seconds if self.seconds > 0 else 0.0
        lines = [f"{self.written} written, {self.skipped} skipped (already done), "
                 f"{self._failed_text()} of {self.total} outputs from "
                 f"{_count(self.images, 'source image')} in {self.seconds:.1f} s "
                 f"({rate:.1f} written/s)"]
        if self.interrupted or self.fatal:
            lines.append(f"stopped after {done} of {self.total} outputs; rerun the same command "
                         f"to resume")
        if self.errors:
            lines.append("failures (each row with an error in manifest.csv):")
            lines += [f"  {e}" for e in self.errors]
            if self.failed > len(self.errors):
                lines.append(f"  ... {self._failed_text()} in all")
        lines += [f"note: {n}" for n in self.notes]
        if self.out:
            lines.append(f"wrote {_count(self.written, 'output')} to {self.out}")
        return "\n".join(lines)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _upright_note(sources) -> list[str]:
    """The summary's note on sources turned upright by their EXIF orientation, if any."""
    turned = sum(1 for s in sources if s.orientation != 1)
    if not turned:
        return []
    return [f"{turned} source image{'s' if turned > 1 else ''} turned upright "
            f"by {'their' if turned > 1 else 'its'} EXIF orientation, as "
            f"viewers show {'them' if turned > 1 else 'it'} (listed in "
            f"{RECORD}: exif_orientation)"]


# --- the build, step by step (main process) ------------------------------------------------

def build(cfg: BuildConfig, root: Path, out: Path, *, progress: bool = False,
          command: list[str] | None = None, executor: Executor | None = None,
          gt: bool = True) -> Summary:
    """Build dataset ``cfg`` from ``root`` into ``out`` (see the module docstring).

    ``executor`` runs the tasks; by default a :class:`.executors.LocalExecutor` with ``cfg.jobs``
    workers (never more than there are source images). With ``gt``, the images are
    followed by the dataset's ground truth (:func:`add_ground_truth`).

    Raises :class:`BuildError`, ``SplitError`` or ``ManifestError`` for whole-build problems
    (before any work) and returns the :class:`Summary` otherwise; ``Summary.complete`` is
    False when images failed, a write error stopped the build, or it was interrupted
    (Ctrl-C; the manifest and record are saved first).
    """
    ds = get_dataset(cfg.dataset)
    typed_root, root = root, check_root(root, labeled_ok=ds.split_format == "nyu")
    buildchecks.check_apart(typed_root, out)
    sources, split = gather_sources(ds, cfg, root, Path(out), typed_root)
    buildchecks.check_sources_outside((s.path for s in sources), out)
    buildchecks.check_depth_scale(ds, cfg.options, root, sources)
    folder = OutputFolder(out)
    previous = folder.record() if folder.path.is_dir() else None
    buildchecks.check_same_build(out, ds.name, cfg.size, cfg.seed, previous)
    png = buildchecks.png_method(out, cfg.png, previous)
    check_png(png)
    renderer = make_renderer(ds, cfg, root, split.get("path"), sources)
    folder.prepare()
    with folder.lock():
        folder.claim()
        previous, dropped = prune(ds, folder, root, sources, previous)
        tasks = plan(ds, cfg, sources, folder.rows(), renderer)
        executor = checked_executor(executor, cfg.jobs, len(tasks), root, folder, worker_files(cfg),
                                    ds.libraries())
        if any(e is None for t in tasks for e in t.expected):
            # Work to do: let the renderer get ready once here rather than in every worker
            # (KITTI-S computes its style statistics); a rerun with nothing to do skips it.
            getattr(renderer, "warm_up", lambda: None)()
        plans = buildchecks.merge_plans(previous, plan_entry(cfg.variants, cfg.levels, [
            s.key for s in sources if not s.anchor], split.get("neighbours"), cfg.frames))
        # The record describes the whole build in OUT, not only this request: a `--limit 2`
        # look into a finished build must not shrink what evaluation and ground truth see.
        keys = buildchecks.built_keys(plans)
        split = {**split, "images": len(keys), "keys": keys}
        record = start_record(cfg, ds, root, folder, split, executor, command, plans, png,
                              orientation_record(ds, sources), getattr(renderer, "depth", None))
        ctx = Context(OutputFolder(os.path.abspath(out)), cfg.size, cfg.seed, renderer,
                      single_thread=executor.workers > 1 and len(tasks) > 1, png=png)
        summary = run_tasks(tasks, ctx, executor, folder, progress)
        summary.notes += _upright_note(sources) + ([dropped] if dropped else [])
        if gt and not (summary.interrupted or summary.fatal):
            add_ground_truth(ds, cfg, root, split.get("path"), sources, len(keys), folder, summary,
                             progress, rerun=shlex.join(command) if command else None)
        finish(folder, record, summary)
    return summary


def make_renderer(ds: Dataset, cfg: BuildConfig, root: Path, split_path: str | None, sources=()) -> Renderer:
    """The renderer, with the depth source a variant needs; it may refuse files (KITTI-S's), so before OUT."""
    from .scenedepth import depth_for

    return renderer_of(ds, cfg, depth_for(ds, cfg, root, split_path, sources))


def plan(ds: Dataset, cfg: BuildConfig, sources: list[Source], done: dict[str, Row],
         renderer: Renderer) -> list[SourceJobs]:
    """One task per source. An output counts as possibly done (its sha256 goes into the
    task) when ``done``, the manifest, has a row for it without an error, from the same
    source, seed, size and renderer fingerprint; the worker still checks the file."""
    jobs = tuple(ds.jobs(cfg.variants, cfg.levels))
    fingerprints = {job.variant: fingerprint(renderer, job) for job in jobs}  # once, not per source
    keyed = {v: f.startswith(DEPTH) for v, f in fingerprints.items()}
    tasks = []
    for src in sources:
        size = cfg.size or native_size(src)
        expected, hashes, stamps, refresh = [], set(), set(), False
        for job in jobs:
            r = done.get(job.path(src.key))
            parts = r.parsed if r is not None else Params()
            params, stamp = replace(parts, depth_stamp="").text(), parts.depth_stamp
            # A source that has gone missing does not spoil the outputs already made from it.
            same = (r is not None and not r.error
                    and ((r.source == src.rel and same_source(r, src)) or bool(src.error))
                    and r.seed == cfg.seed and (r.height, r.width) == size
                    and params == for_source(fingerprints[job.variant], src, job)
                    and bool(stamp) == keyed[job.variant])  # a depth-aware row names its depth
            expected.append(r.sha256 if same else None)
            if same:
                hashes.add(r.source_sha256)
                stamps.add(stamp)
                refresh = refresh or (not src.error and r.source_size is None)
        # Rows made from different bytes of this source (or with none recorded), or from
        # different depths: no claim (the worker compares them with the files as they are).
        source_sha = hashes.pop() if len(hashes) == 1 else ""
        stamps.discard("")
        stamp = stamps.pop() if len(stamps) == 1 else ("mixed" if stamps else "")
        tasks.append(SourceJobs(src, jobs, tuple(expected), source_sha, refresh, size, stamp))
    return tasks


def worker_files(cfg: BuildConfig) -> list[str]:
    """Files named in the configuration that workers read besides the images (KITTI-S:
    the checkpoints), as absolute paths; a cluster's workers must see them too."""
    # A custom build's --list is read by the main process only.
    return [os.path.abspath(v) for k, v in cfg.options.as_dict().items()
            if k not in ("list", "engine", "device") and isinstance(v, str) and os.path.isfile(v)]


def native_size(src: Source) -> tuple[int, int] | None:
    """The (H, W) of a source image from its header, None if it cannot be read (its task
    will say why)."""
    if src.error or not src.path:
        return None
    from ..imageio import stored_size

    return stored_size(src.path, src.orientation)


def start_record(cfg: BuildConfig, ds: Dataset, root: Path, folder: OutputFolder, split: dict,
                 executor: Executor, command: list[str] | None,
                 plans: list[dict] | None = None, png: str = "fast",
                 exif_orientation: dict | None = None, depth=None) -> BuildRecord:
    """Write the build record of a build that starts now (status ``running``) and return it.
    ``split`` is :func:`gather_sources`' account of the sources (``keys``: the entries
    built, in order); ``plans`` every request made
    into this OUT so far (see :mod:`robodepth_cli.building.checks`), which verify checks;
    ``png`` how the PNGs are written; ``depth`` the depth source of the depth-aware variants."""
    record = BuildRecord(
        robodepth=__version__, command=command or [], dataset=ds.name,
        config=cfg.as_dict(), seed=cfg.seed, root=str(root), out=str(folder.path.resolve()),
        split=split, plans=plans or [plan_entry(cfg.variants, cfg.levels, split["keys"])],
        versions=library_versions(ds), png_compress_level=PNG_COMPRESS_LEVEL,
        png=png, png_encoder=PNG_ENCODERS[png], executor=executor.describe(),
        started=now(), finished=None, status=BuildStatus.RUNNING,
        exif_orientation=exif_orientation, depth=depth.describe() if depth else None,
    )
    try:
        folder.write_record(record)
    except OSError as exc:
        raise BuildError(cannot_write(folder.record_file, exc)) from None
    return record


def run_tasks(tasks: list[SourceJobs], ctx: Context, executor: Executor, folder: OutputFolder,
              progress: bool) -> Summary:
    """Run every task through ``executor``, appending the manifest rows of each as it
    finishes. Stops at the first fatal error; Ctrl-C marks the summary interrupted."""
    summary = Summary(total=sum(len(t.jobs) for t in tasks), images=len(tasks), out=str(folder.path))
    t0 = time.perf_counter()
    try:
        _run(tasks, ctx, executor, folder, summary, progress)
    except KeyboardInterrupt:
        summary.interrupted = True
    except ExecutorError as exc:  # e.g. a cluster lost the workers it needs
        summary.fatal = str(exc)
    summary.seconds = round(time.perf_counter() - t0, 3)
    return summary


def _run(tasks: list[SourceJobs], ctx: Context, executor: Executor, folder: OutputFolder,
         summary: Summary, progress: bool) -> None:
    from ..progress import bar as progress_bar

    try:
        writer = folder.writer()
    except OSError as exc:
        summary.fatal = cannot_write(folder.manifest, exc)
        return
    bar = progress_bar("img", summary.total, progress=progress, smoothing=0.05)
    # Outputs whose rows predate the source records: written again even when skipped.
    refresh = {job.path(t.source.key) for t in tasks if t.refresh for job in t.jobs}
    with bar, writer:
        for results in executor.map_unordered(functools.partial(run_source_jobs, ctx=ctx), tasks):
            try:
                writer.append([r for state, r in results
                               if state is not JobState.SKIPPED or r.output in refresh])
            except OSError as exc:  # these images exist but are not recorded: a rerun redoes them
                summary.fatal = cannot_write(writer.path, exc)
            summary.add_image(results)
            bar.update(len(results))
            if summary.fatal:
                return


def add_ground_truth(ds: Dataset, cfg: BuildConfig, root: Path, split_path: str | None,
                     sources: list[Source], frames: int, folder: OutputFolder, summary: Summary,
                     progress: bool, rerun: str | None = None) -> None:
    """Write the ground truth of the first ``frames`` split entries (those in ``folder``), or of
    the ``sources`` of a build with depth (:mod:`robodepth_cli.groundtruth.write`), as
    manifest rows counted in ``summary``; when it cannot be made at all, only a note
    (naming ``rerun``, the command that adds it once the files are there)."""
    from ..groundtruth import write as build_gt

    plan = build_gt.plan_for(ds, cfg, root, split_path, sources, frames, rerun)
    if plan is None:
        return
    if plan.note:
        summary.notes.append(plan.note)
        return
    summary.total += len(plan.jobs)
    try:
        with folder.writer() as writer:
            for state, row in build_gt.run_gt(plan, folder, progress):
                state = JobState(state)
                if state is not JobState.SKIPPED:
                    writer.append([row])
                summary.add(state, row)
                if state is JobState.FATAL:
                    return
    except KeyboardInterrupt:
        summary.interrupted = True
    except OSError as exc:
        summary.fatal = cannot_write(folder.manifest, exc)
    finally:
        if plan.implausible:
            summary.notes.append(plan.unit_warning())


def finish(folder: OutputFolder, record: BuildRecord, summary: Summary) -> None:
    """Compact the manifest, clear what a stopped pool may have left, write the final
    record. A write error here is kept in ``summary.fatal`` (the outputs themselves are
    fine; a rerun repairs the bookkeeping)."""
    try:
        # Outputs of the images still in flight when the build stopped: written, and now
        # recorded (none after a build that ran to the end).
        summary.written += len(folder.merge_journal())
    except OSError as exc:  # the journal stays for the next build to merge
        summary.fatal = summary.fatal or cannot_write(folder.manifest, exc)
    try:
        folder.compact()
    except OSError as exc:  # the appended manifest stays valid, only unsorted
        summary.fatal = summary.fatal or cannot_write(folder.manifest, exc)
    if summary.interrupted or summary.fatal:
        # A pool stopped early kills its workers, perhaps in the middle of a write.
        folder.remove_temporaries()
    try:
        folder.write_record(replace(record, finished=now(), status=summary.status,
                                    summary=summary.as_dict()))
    except OSError as exc:
        summary.fatal = summary.fatal or cannot_write(folder.record_file, exc)


def library_versions(ds: Dataset) -> dict[str, str]:
    from importlib import metadata

    versions = {"python": platform.python_version(), "robodepth-cli": __version__}
    for name in ds.libraries():
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions
