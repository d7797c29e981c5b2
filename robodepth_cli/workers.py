"""Worker processes for work that must give the bytes of one process: ``evaluate --jobs``
and ``gt kitti --jobs``.

:func:`in_order` runs ``fn(task)`` in fresh (spawned) interpreters and yields the results
in task order, so the caller combines them exactly as one process would, and an error is
the one of the first task in order that has one. Spawned rather than forked: the caller
may hold threads (a progress bar's, OpenCV's) that a fork would copy in the middle of
their work.
"""

from __future__ import annotations

import os
from typing import Any, Callable, Iterator, Sequence


def default_jobs() -> int:
    """One worker per CPU this process may use."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def in_order(fn: Callable[..., Any], tasks: Sequence[tuple], jobs: int,
             initializer: Callable[..., None] | None = None, initargs: tuple = ()) -> Iterator[Any]:
    """``fn(*task)`` for every task in ``jobs`` spawned processes (each started with
    ``initializer(*initargs)``), yielded in task order. Leaving early (an error, closing
    the iterator) cancels the tasks not started."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"),
                             initializer=initializer, initargs=initargs) as pool:
        futures = [pool.submit(fn, *task) for task in tasks]
        try:
            for future in futures:
                yield future.result()
        finally:
            for future in futures:
                future.cancel()
