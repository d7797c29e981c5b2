"""Where a build's tasks run: the seam between planning a build and executing it.

An executor takes a picklable function and a list of tasks and yields each task's result
as soon as it is done, in any order. The builder (the only caller) writes the manifest and
the build record from those results in its own process, so an executor never touches the
bookkeeping files; it only has to run ``fn(task)`` somewhere that sees the same root and
output directory.

:class:`LocalExecutor` is the default: in-process for one worker, else a joblib (loky)
process pool. :class:`robodepth_cli.building.cluster.DaskExecutor` runs the tasks on a Dask cluster;
it is imported (with dask) only when a build asks for a scheduler.
"""

from __future__ import annotations

import contextlib
import threading
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator, Protocol, Sequence

from ..errors import RobodepthError
from ..output.folder import OutputFolder


class ExecutorError(RobodepthError):
    """The executor cannot run the build (raised by ``check``, before any work) or lost
    the ability to go on (raised by ``map_unordered``; finished images are kept)."""


class Executor(Protocol):
    workers: int  # how many tasks run at once

    def check(self, root: Path, folder: OutputFolder, files: Sequence[str],
              libraries: Sequence[str]) -> None:
        """Before any work: refuse (:class:`ExecutorError`) if the processes that will run
        the tasks cannot read ``root`` and ``files`` with the client's contents, write in the
        existing ``folder``, or have other versions of ``libraries``."""

    def map_unordered(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[Any]:
        """``fn(task)`` for every task, yielded as each finishes. Closing the iterator early
        (a write error, Ctrl-C) cancels what has not started."""

    def describe(self) -> dict:
        """What the build record keeps about where the build ran."""


class LocalExecutor:
    """``workers`` processes on this machine (1: no pool at all, everything in-process)."""

    def __init__(self, workers: int):
        self.workers = max(1, int(workers))

    def check(self, root, folder, files, libraries) -> None:
        pass  # this machine's processes: the builder's own checks cover them

    def map_unordered(self, fn, tasks):
        if self.workers == 1:
            _STOPPING.clear()
            for t in tasks:
                yield _in_thread(fn, t)
            return
        from joblib import Parallel, delayed

        from ..workers import signals_held

        stopping = False
        previous_hook = threading.excepthook

        def hook(args):
            # A pool stopped as it starts: loky's manager thread can trip over the work
            # cancelled under it (KeyError); only noise after the interrupt's own line.
            if not (stopping and args.thread is not None and args.thread.name == "ExecutorManagerThread"):
                previous_hook(args)

        with warnings.catch_warnings(), contextlib.ExitStack() as stack:
            # Stopping early on a write error cancels the queued tasks on purpose; joblib's
            # warning about it would only bury the real message.
            warnings.filterwarnings("ignore", r".*tasks which were still being processed", UserWarning)
            stack.callback(setattr, threading, "excepthook", previous_hook)  # once the pool is shut
            threading.excepthook = hook
            try:
                with signals_held():  # the workers, started by the first tasks sent, ignore Ctrl-C
                    pool = stack.enter_context(Parallel(n_jobs=self.workers, return_as="generator_unordered"))
                    results = pool(delayed(fn)(t) for t in tasks)
                    stack.callback(results.close)  # its cancelling now, under the filter above
                yield from results
            except BaseException:
                stopping = True
                raise

    def describe(self) -> dict:
        return {"backend": "local", "workers": self.workers}


_STOPPING = threading.Event()  # set when a one-worker build stops: no output is written after
GRACE_S = 1.0  # how long a stopped build waits for the task's thread to finish a write


def stopping() -> bool:
    """Whether the one-worker build of this process is stopping (Ctrl-C, SIGTERM): its task,
    still running in its thread, must write nothing more."""
    return _STOPPING.is_set()


def _in_thread(fn, task):
    """``fn(task)`` in a thread of its own, waited for here. This thread (the main one)
    stays where Python runs its signal handlers, so Ctrl-C stops a one-worker build at once
    even while a compiled kernel runs for seconds without the GIL (on the main thread its
    handler would wait for the kernel's end). Stopped, the task is told to write nothing more
    (:func:`stopping`) and given :data:`GRACE_S` to finish a write under way; a kernel still
    running is left to end with the process."""
    import signal

    box: dict = {}

    def run():
        if hasattr(signal, "pthread_sigmask"):  # both signals go to the main thread
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            box["result"] = fn(task)
        except BaseException as exc:  # noqa: BLE001 - raised again in the main thread
            box["error"] = exc

    thread = threading.Thread(target=run, name="robodepth-task", daemon=True)
    thread.start()
    try:
        while thread.is_alive():
            thread.join(0.1)  # woken to run a handler even for a signal another thread took
    except BaseException:
        _STOPPING.set()
        thread.join(GRACE_S)
        raise
    if "error" in box:
        raise box["error"]
    return box["result"]


def checked_executor(executor: Executor | None, jobs: int, n_tasks: int, root: Path,
                     folder: OutputFolder, files: Sequence[str], libraries: Sequence[str]) -> Executor:
    """``executor``, or the local pool of ``jobs`` workers (never more than the ``n_tasks``
    images), checked to see the root, OUT and the ``files`` the workers read."""
    if executor is None:
        executor = LocalExecutor(min(jobs, n_tasks))
        _warn_above_cpus(executor.workers, jobs)
    # A labeled .mat root: the workers must see the folder that holds it.
    executor.check(root if root.is_dir() else root.parent, folder, files, libraries)
    return executor


def _warn_above_cpus(workers: int, jobs: int) -> None:
    import os
    import sys

    cpus = os.cpu_count() or 1
    if workers > cpus:  # each worker holds its own images: past one per CPU, only contention
        print(f"robodepth: warning: {workers} workers (--jobs {jobs}) on {cpus} CPU"
              f"{'s' if cpus > 1 else ''}: the extra workers only add memory and contention "
              f"(--jobs auto: one per CPU)", file=sys.stderr)
