"""One task of a build: a source image and all of its outputs, as a worker receives and
runs it (:func:`run_source_jobs`). The main process plans tasks and writes the manifest and record
(:mod:`.pipeline`); executors (:mod:`.executors`, :mod:`.cluster`) carry tasks to workers
and their manifest rows back.
"""

from __future__ import annotations

import enum
import itertools
import signal
import threading
from dataclasses import dataclass
from pathlib import Path

from ..errors import RobodepthError, cannot_write, failure_reason, os_reason, reraise_interrupt
from ..files import sha256_bytes, sha256_file
from ..imageio import ImageError, load_clean, resize_lanczos, write_png
from ..output.folder import OutputFolder
from ..output.manifest import Params, Row
from ..sources.datasets import CLEAN, Entry, Job, locate
from .executors import stopping
from .renderers import Renderer
from .scenedepth import DEPTH

PNG_COMPRESS_LEVEL = 1  # zlib level: pixels are identical at any level; 1 is the fastest


class JobState(enum.Enum):
    """What became of one job (one output file) in this run."""

    SKIPPED = "skipped"  # the file on disk matches its manifest row: nothing to do
    WRITTEN = "written"
    FAILED = "failed"  # this job or its source is broken; any stale file at its path is removed
    FATAL = "fatal"  # the file could not be written (disk full, permissions): the build stops


@dataclass(frozen=True)
class Source:
    """One entry of the split and where its image was found under the root."""

    key: str  # the entry's dataset-relative key, which names its outputs (see datasets)
    rel: str  # the image's path relative to the root; "" when it was not found
    path: str | None  # the image's absolute path; None when it was not found
    error: str = ""  # why the image cannot be used; "" when it was found
    frame: int | None = None  # the image's index when ``path`` is NYU's labeled .mat file
    size: int | None = None  # bytes, when found (a file of its own)
    mtime: int | None = None  # modification time in ns since the epoch, when found
    # The image's EXIF orientation, applied when it is read (custom builds: photos are built
    # the way viewers show them); 1 = as stored, always for the benchmarks' own sources.
    orientation: int = 1
    # A neighbour frame (``--frames``): the key of the test frame it is rendered for, whose
    # scene draws it shares (see corruptions/frames.py); "" for a test frame.
    anchor: str = ""
    # With ``--frames``: the image paths of the test frame's sequence in time order (None:
    # not in the drive), this frame's index in it and the test frame's, for the corruptions
    # over time; () otherwise.
    sequence: tuple = ()
    position: int = 0
    center: int = 0
    # What identifies the sequence's files (their sizes and times): the outputs of the
    # corruptions over time are made again when any frame of their sequence changed.
    sequence_id: str = ""

    @classmethod
    def find(cls, root: Path, entry: Entry) -> "Source":
        try:
            rel, path = locate(root, entry)
            st = path.stat()
        except ImageError as exc:
            return cls(entry.key, "", None, str(exc))
        except OSError as exc:  # vanished or unreadable between the two calls
            return cls(entry.key, "", None, f"{root / entry.candidates[0]}: {os_reason(exc)}")
        return cls(entry.key, rel, str(path), size=st.st_size, mtime=st.st_mtime_ns)


@dataclass(frozen=True)
class SourceJobs:
    """One source image and all of its outputs. Small: this is what a worker receives."""

    source: Source
    jobs: tuple[Job, ...]
    expected: tuple[str | None, ...]  # per job: sha256 of a matching manifest row, else None
    # sha256 of the source recorded by those rows ("" if none): a source with other bytes
    # (same size, even the same time) redoes every output.
    source_sha256: str = ""
    # Whether some matching row predates the recorded source size/time/hash: its skipped
    # outputs get their row again, now with them.
    refresh: bool = False
    size: tuple[int, int] | None = None  # the outputs' (H, W) when known before decoding
    # The depth stamp (what identifies the source's depth map) recorded by the matching rows
    # of its depth-aware outputs ("" if none): a depth that changed redoes them.
    depth_stamp: str = ""


@dataclass(frozen=True)
class Context:
    """What every task of a build shares."""

    folder: OutputFolder  # absolute: a worker may run elsewhere
    size: tuple[int, int] | None  # None: every image at its own size
    seed: int
    renderer: Renderer
    single_thread: bool  # True in pool workers: the pool already uses every core
    png: str = "fast"  # how the PNGs are written (imageio.PNG_METHODS)


def run_source_jobs(task: SourceJobs, ctx: Context) -> list[tuple[JobState, Row]]:
    """Make the outputs of one source image that are not already done; one
    ``(JobState, manifest row)`` per job (see :class:`JobState`)."""
    _configure_worker(ctx.single_thread)
    out = ctx.folder.path
    src = task.source
    hw = list(task.size or ctx.size or (0, 0))  # the decoded image's own, once decoded
    source_sha, expected = _source_hash(task)
    expected, stamp = _depth_checked(task, ctx.renderer, expected)

    def row(job: Job, sha: str = "", error: str = "") -> Row:
        return Row(job.path(src.key), src.rel, job.variant, job.level, ctx.seed, hw[0], hw[1], sha, error,
                   fingerprint(ctx.renderer, job, src, stamp), src.size, src.mtime, source_sha)

    results: list[tuple[JobState, Row]] = []
    todo: list[Job] = []
    for job, sha in zip(task.jobs, expected):
        if sha is not None and _sha_or_none(out / job.path(src.key)) == sha:
            results.append((JobState.SKIPPED, row(job, sha)))
        else:
            todo.append(job)
    if not todo:
        return results

    def fail(job: Job, message: str) -> None:
        (out / job.path(src.key)).unlink(missing_ok=True)
        results.append((JobState.FAILED, row(job, error=message)))

    clean, message = load_source(src, ctx.size)
    if clean is None:
        for job in todo:
            fail(job, message)
        return results

    clean.flags.writeable = False
    hw[:] = clean.shape[:2]
    # Lazily, so only one rendered image is alive at a time.
    rendered = itertools.chain(
        ((j, clean) for j in todo if j.variant == CLEAN),
        ctx.renderer.render(clean, src.key, [j for j in todo if j.variant != CLEAN],
                            **_frames_of(src, clean, todo, ctx.size)))
    with ctx.folder.journal() as journal:
        for job, img in rendered:
            if isinstance(img, BaseException):
                fail(job, f"{src.path}: {_job_name(job)}: {failure_reason(img)}")
                continue
            target = out / job.path(src.key)
            try:
                data = _write(target, img, ctx.png)
            except OSError as exc:
                results.append((JobState.FATAL, row(job, error=cannot_write(target, exc))))
                return results
            results.append((JobState.WRITTEN, row(job, sha256_bytes(data))))
            try:
                # Recorded now, not when the whole image is done: a stop loses at most the
                # outputs being written, not an image's 91.
                journal.append(results[-1][1])
            except OSError:
                pass  # only a safety net: the row still reaches the manifest with the task
    return results


def _write(target: Path, img, method: str) -> bytes:
    """:func:`write_png` of one output, unless the build was stopped while its image was
    rendered (:func:`.executors.stopping`; KeyboardInterrupt then)."""
    if stopping():
        raise KeyboardInterrupt
    return write_png(target, img, PNG_COMPRESS_LEVEL, method=method)


def _source_hash(task: SourceJobs) -> tuple[str, tuple]:
    """The source's sha256 ("" when not hashed) and the outputs' recorded hashes that still
    stand: none of them when the source's bytes changed (everything is redone)."""
    src = task.source
    # A frame inside a container (NYU's labeled .mat) is not hashed: that would read the
    # whole multi-GB file for every image.
    source_sha = (_sha_or_none(Path(src.path)) or "") if src.path and src.frame is None else ""
    if task.source_sha256 and source_sha and source_sha != task.source_sha256:
        return source_sha, (None,) * len(task.jobs)
    return source_sha, task.expected


_configured = False


def _configure_worker(single_thread: bool) -> None:
    global _configured
    if single_thread and not _configured:
        import cv2

        cv2.setNumThreads(1)  # two processes on two cores: extra OpenCV threads only contend
        if threading.current_thread() is threading.main_thread():  # not so in a Dask worker
            # Ctrl-C reaches the whole process group; the main process stops the pool, and a
            # worker interrupted on its own would only print a traceback.
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        _keep_freed_memory()
        _configured = True


def _keep_freed_memory() -> None:
    """Let glibc reuse freed blocks for the next image's large temporaries instead of
    returning them to the system and faulting fresh pages in again for every image. A
    no-op where there is no glibc."""
    import ctypes

    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 256 << 20)  # M_MMAP_THRESHOLD: arrays up to 256 MB come from the heap
        libc.mallopt(-1, 1 << 30)  # M_TRIM_THRESHOLD: keep up to 1 GB of freed heap
    except (OSError, AttributeError):
        pass


def fingerprint(renderer: Renderer, job: Job, src: Source | None = None, stamp: str = "") -> str:
    """The manifest's ``params`` of ``job`` (of the source ``src``, whose depth has
    ``stamp``): what besides the seed and size decides its pixels (:func:`for_source` of the
    renderer's fingerprint)."""
    params = "" if job.variant == CLEAN else renderer.fingerprint(job.variant)
    if src is None:
        return params
    return for_source(params, src, job, stamp if params.startswith(DEPTH) else "")


def _depth_checked(task: SourceJobs, renderer: Renderer, expected: tuple) -> tuple[tuple, str]:
    """``expected`` without the depth-aware outputs when the source's depth changed since
    they were made, and its depth stamp now ("" when no job needs depth)."""
    keyed = [depth_keyed(renderer, job) for job in task.jobs]
    stamp = renderer.depth_stamp(task.source.key) if any(keyed) else ""
    if stamp != task.depth_stamp:
        expected = tuple(None if k else e for k, e in zip(keyed, expected))
    return expected, stamp


def depth_keyed(renderer: Renderer, job: Job) -> bool:
    """Whether ``job``'s output is made from its source's depth map (and keyed on it)."""
    return job.variant != CLEAN and renderer.fingerprint(job.variant).startswith(DEPTH)


def for_source(params: str, src: Source, job: Job, stamp: str = "") -> str:
    """``params`` of ``job`` made from ``src``. A neighbour frame's begin with
    ``neighbour_of=<test frame key>``, which lists it under its test frame in the manifest and
    redoes it when it is rendered for another one; a corruption over time's end with
    ``sequence=<id>`` (its sequence's files); a depth-aware output's with ``map=<stamp>`` (the
    sha256 of its depth's files). A single-frame build's are unchanged otherwise."""
    from ..benchmark_facts import TEMPORAL

    sequence = src.sequence_id if src.sequence_id and job.variant in TEMPORAL else ""
    return Params(params, src.anchor or "", sequence or "", stamp).text()


def load_source(src: Source, size: tuple[int, int] | None):
    """(clean image, "") or (None, why the source cannot be used): the source decoded, turned
    upright if it must be, and resized to ``size`` (None: its own), as every build's outputs
    start (``robodepth run`` starts from it too)."""
    if src.error:
        return None, src.error
    try:
        if src.frame is not None:
            from ..groundtruth.nyu import source_image

            return resize_lanczos(source_image(src.path, src.frame), size), ""
        return load_clean(src.path, size, orient=src.orientation != 1), ""
    except RobodepthError as exc:  # ImageError, or a labeled file's NyuError
        return None, str(exc)
    except Exception as exc:  # e.g. Pillow's DecompressionBombError: still this image's problem
        reraise_interrupt(exc)
        return None, f"{src.path}: {failure_reason(exc)}"


def _frames_of(src: Source, clean, todo: list[Job], size) -> dict:
    """What a renderer needs besides the image for a frame of a sequence: its test frame's
    key (``anchor``) and, for a corruption over time, the clean frames of its sequence."""
    if not src.sequence:
        return {}
    from ..benchmark_facts import TEMPORAL

    kw = {"anchor": src.anchor or src.key}
    if any(j.variant in TEMPORAL for j in todo):
        # A frame that cannot be read is left out of the sequence, like one the drive lacks.
        frames = [clean if i == src.position else None if path is None
                  else load_source(Source("", "", path), size)[0] for i, path in enumerate(src.sequence)]
        kw["sequence"] = (frames, src.position, src.center)
    return kw


def _job_name(job: Job) -> str:
    return job.variant if job.level is None else f"{job.variant} level {job.level}"


def _sha_or_none(path: Path) -> str | None:
    try:
        return sha256_file(path)
    except OSError:
        return None


def same_source(row: Row, src: Source) -> bool:
    """Whether ``row`` was made from the source as it is now, as far as its size and time
    tell: a different size always means a change; with a recorded hash (compared by the
    worker) the time does not matter, so a copied root is not rebuilt; without one, a
    different time counts as a change."""
    if row.source_size != src.size:
        return False
    return bool(row.source_sha256) or row.source_mtime == src.mtime
