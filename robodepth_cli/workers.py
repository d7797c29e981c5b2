"""Worker processes for work that must give the bytes of one process: ``evaluate --jobs``
and ``gt kitti --jobs``.

:func:`in_order` runs ``fn(task)`` in fresh (spawned) interpreters and yields the results
in task order, so the caller combines them exactly as one process would, and an error is
the one of the first task in order that has one. Spawned rather than forked: the caller
may hold threads (a progress bar's, OpenCV's) that a fork would copy in the middle of
their work.

This process owns the workers' lives, so that Ctrl-C and SIGTERM stop a command at once:
the workers start with both signals blocked (:func:`signals_held`; a terminal's Ctrl-C
reaches the whole process group, and a worker must not print its own traceback), and
when the caller stops for any reason (an interrupt, an error, closing the iterator) they
are killed and reaped before the exception goes on. Each worker gets one task at a time over its own pipe, read by
this thread: no queue feeder thread is left writing to a pipe that no worker reads (what
made ``concurrent.futures`` hang at interpreter exit after a SIGTERM).
"""

from __future__ import annotations

import contextlib
import os
import signal
from typing import Any, Callable, Iterator, Sequence


def default_jobs() -> int:
    """One worker per CPU this process may use."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def parse_jobs(value) -> int:
    """``--jobs`` (and a build config's ``jobs``) as every command reads it: an integer
    >= 1, or 'auto' or -1 for one worker per CPU (:func:`default_jobs`)."""
    from .errors import InvalidValueError
    from .integers import int_from_text, is_int

    number = int_from_text(value)
    if number == -1 and is_int(number) or isinstance(value, str) and value.strip() == "auto":
        return default_jobs()
    if not is_int(number) or number < 1:
        raise InvalidValueError(f"expected an integer >= 1, got {number!r} (or 'auto' or -1: one "
                                "worker per CPU)")
    return number


class WorkerDied(RuntimeError):
    """A worker process ended without returning its task's result (killed, out of memory)."""


class RemoteTraceback(Exception):
    """The traceback of an exception raised in a worker, shown as its cause."""

    def __str__(self):
        return self.args[0]


def in_order(fn: Callable[..., Any], tasks: Sequence[tuple], jobs: int,
             initializer: Callable[..., None] | None = None, initargs: tuple = (),
             here: Callable[..., Any] | None = None) -> Iterator[Any]:
    """``fn(*task)`` for every task in ``jobs`` spawned processes (each started with
    ``initializer(*initargs)``), yielded in task order. Leaving early (an error, an
    interrupt, closing the iterator) kills the workers; the tasks not started never run.

    ``here``: this process is one of the ``jobs``, running ``here(*task)`` between looks at
    the workers' results, while ``jobs - 1`` workers start and run; each worker then holds
    a second task, so that it never waits for this process to finish one of its own. The
    first tasks are this process's while the workers start (an interpreter each), which
    would otherwise leave the cores to imports."""
    import multiprocessing
    from multiprocessing.connection import wait

    context = multiprocessing.get_context("spawn")
    pipes: dict = {}  # this side of each worker's pipe -> its process
    finished = False
    spawned = min(jobs - 1 if here is not None else jobs, len(tasks))
    try:
        for _ in range(spawned):
            ours, there = context.Pipe()
            process = context.Process(target=_serve, args=(there, fn, initializer, initargs),
                                      daemon=True)
            # Known before it starts: a Ctrl-C held during the start is raised as the start
            # ends, and the process must be among those killed then.
            pipes[ours] = process
            _start_held(process)
            there.close()
        todo = iter(enumerate(tasks))
        busy: dict = {pipe: [] for pipe in pipes}  # pipe -> the indices of the tasks it holds
        done: dict = {}  # index -> (ok, value), until its turn comes
        depth = 1 if here is None else 2

        def hand_out(pipe) -> None:
            while len(busy[pipe]) < depth:
                task = next(todo, None)
                if task is None:
                    return
                pipe.send(task)
                busy[pipe].append(task[0])

        def collect(timeout) -> None:
            for pipe in wait([p for p, held in busy.items() if held], timeout):
                try:
                    index, ok, value = pipe.recv()
                except (EOFError, OSError):
                    _died(pipes[pipe])
                busy[pipe].remove(index)
                done[index] = (ok, value)
                hand_out(pipe)

        for pipe in pipes:
            hand_out(pipe)
        for turn in range(len(tasks)):
            while turn not in done:
                task = next(todo, None) if here is not None else None
                if task is None:
                    collect(None)  # nothing left for this process: wait for a result
                    continue
                done[task[0]] = _run_here(here, task[1])
                collect(0)
            yield _value(*done.pop(turn))
        finished = True
    finally:
        _stop(pipes, finished)


def _run_here(here: Callable[..., Any], args: tuple) -> tuple[bool, Any]:
    """``(ok, result or (exception, None))`` of ``here(*args)``, as a worker replies."""
    try:
        return True, here(*args)
    except Exception as exc:  # noqa: BLE001 - raised in its turn, as a worker's
        return False, (exc, None)


def _value(ok: bool, value):
    """A task's result, or its exception raised (a worker's with its traceback as cause)."""
    if ok:
        return value
    exc, text = value
    if text is None:
        raise exc
    raise exc from RemoteTraceback(text)


def _stop(pipes: dict, finished: bool) -> None:
    """End the workers (``pipes``: this side of each one's pipe -> its process): told to stop
    when every task is done, else killed; then waited for."""
    for pipe, process in pipes.items():
        if finished:
            with contextlib.suppress(OSError):
                pipe.send(None)  # every task is done: let it end by itself
        elif process.is_alive():
            process.kill()  # nothing a worker holds needs cleaning up: it writes nothing
        pipe.close()
    for process in pipes.values():
        if process.pid is not None:  # an interrupt can come before its start
            process.join()


def _died(process) -> None:
    """Raise for a worker that ended in the middle of a task. Killed by SIGINT or SIGTERM
    (where they cannot be blocked: not POSIX), the command is being stopped: an interrupt,
    which this process may not have seen yet."""
    process.join()
    if process.exitcode in (-signal.SIGINT, -signal.SIGTERM):
        raise KeyboardInterrupt
    raise WorkerDied(f"a worker process ended unexpectedly (exit status {process.exitcode}); "
                     "if it ran out of memory, use fewer --jobs")


def _start_held(process) -> None:
    """Start ``process`` with SIGINT and SIGTERM blocked (:func:`signals_held`)."""
    with signals_held():
        process.start()


@contextlib.contextmanager
def signals_held():
    """Ctrl-C and SIGTERM held back while worker processes start, and delivered when the
    block ends. Processes (and threads) started meanwhile inherit a mask blocking both, so
    they never act on the signals that a terminal's Ctrl-C or a scheduler sends the whole
    process group: this process stops them (killing them, as it does when signalled
    alone). Else a Ctrl-C while a worker starts (importing numpy...) prints the worker's
    traceback, and a pool whose workers die of SIGTERM under it fails with tracebacks of
    its own threads. In the main thread, this process's own handlers wait too: a pool
    interrupted half-started (joblib's) fails the same way."""
    import threading

    main = threading.current_thread() is threading.main_thread()
    caught: list[int] = []
    handlers = {}
    if main:
        for signum in (signal.SIGINT, signal.SIGTERM):
            handlers[signum] = signal.signal(signum, lambda signum, frame: caught.append(signum))
    masked = hasattr(signal, "pthread_sigmask")
    if masked:
        from multiprocessing import resource_tracker

        # Starting multiprocessing's resource tracker (which pools do on their first start)
        # unblocks both signals in this thread: have it run first.
        resource_tracker.ensure_running()
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held) if masked else None
    try:
        yield
    finally:
        if masked:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
        for signum in dict.fromkeys(caught):
            signal.raise_signal(signum)  # now, to the handler it was meant for


def _serve(pipe, fn, initializer, initargs) -> None:
    """A worker: run ``initializer``, then each task received until told to stop (None)
    or the parent goes away; send back ``(index, ok, result or exception)``."""
    import traceback
    from multiprocessing.reduction import ForkingPickler

    from .errors import RobodepthError

    if initializer is not None:
        initializer(*initargs)
    while True:
        try:
            task = pipe.recv()
        except (EOFError, OSError):
            return  # the parent is gone
        if task is None:
            return
        index, args = task
        try:
            reply = ForkingPickler.dumps((index, True, fn(*args)))
        except Exception as exc:  # noqa: BLE001 - the parent decides what it means
            text = "".join(traceback.format_exception(exc))
            if not isinstance(exc, RobodepthError):  # a bug: its traceback tells the rest
                exc = RuntimeError(f"{type(exc).__name__}: {exc}")
            reply = ForkingPickler.dumps((index, False, (exc, text)))
        try:
            pipe.send_bytes(reply)
        except (EOFError, OSError):
            return
