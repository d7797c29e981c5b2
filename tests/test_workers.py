"""workers.in_order with ``here=``: this process runs tasks beside its workers; the results
and the error raised are those of task order, whoever ran each task."""

from __future__ import annotations

import os

import pytest

from robodepth_cli.workers import in_order


def square(i: int) -> tuple[int, int]:
    """A worker's task: ``i * i`` and the process that computed it."""
    if i in (2, 4):
        raise ValueError(f"task {i}")
    return i * i, os.getpid()


def test_here_runs_tasks_in_this_process_beside_the_workers_in_order():
    tasks = [(i,) for i in (0, 1, 3, 5, 6, 7, 8, 9)]
    got = list(in_order(square, tasks, 2, here=lambda i: (i * i, os.getpid())))
    assert [v for v, _ in got] == [i * i for (i,) in tasks]
    pids = [p for _, p in got]
    # the first two tasks are handed to the worker before this process takes one
    assert pids[0] == pids[1] != os.getpid()
    assert os.getpid() in pids and len(set(pids)) == 2


def test_here_the_error_is_that_of_the_first_task_in_order():
    def here(i):
        if i in (2, 4):
            raise ValueError(f"task {i}")
        return i * i, os.getpid()

    with pytest.raises((ValueError, RuntimeError), match="task 2"):
        list(in_order(square, [(i,) for i in range(8)], 2, here=here))


def test_jobs_1_with_here_starts_no_worker():
    got = list(in_order(square, [(0,), (1,), (3,)], 1, here=lambda i: (i * i, os.getpid())))
    assert got == [(0, os.getpid()), (1, os.getpid()), (9, os.getpid())]
