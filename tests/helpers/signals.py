"""Stopping a command with a signal at a chosen moment: the interrupt tests' driver."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from typing import NamedTuple

from tests.helpers.paths import REPO


class Stopped(NamedTuple):
    returncode: int
    before: str  # stderr before the script's READY line
    after: str  # stderr after the signal
    group_gone: bool  # every process of its group ended (when asked for)


def group_gone(pgid: int, timeout: float = 10.0) -> bool:
    """Whether every process of the group has ended (the workers, and multiprocessing's
    resource tracker, which ends when the command does)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def signal_when_ready(script: str, args, sig, *, cwd, whole_group: bool = False,
                      wait_for_group: bool = False) -> Stopped:
    """Run ``python -c SCRIPT ARGS`` (the checkout first on its path) in a session of its own;
    when it writes the line READY on stderr, send ``sig`` to it (to its whole process group
    with ``whole_group``: Ctrl-C in a terminal) and wait for its end; with ``wait_for_group``,
    also for its group's. Whatever is left of the group afterwards is killed."""
    env = {**os.environ, "PYTHONPATH": f"{REPO}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.Popen([sys.executable, "-c", script, *map(str, args)], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        seen = []
        for line in proc.stderr:
            if line.strip() == "READY":
                break
            seen.append(line)
        else:
            raise AssertionError(f"the command ended before it was ready: {''.join(seen)}")
        if whole_group:
            os.killpg(proc.pid, sig)
        else:  # kill PID
            proc.send_signal(sig)
        try:
            rest = proc.communicate(timeout=120)[1]
        except subprocess.TimeoutExpired:
            raise AssertionError(f"still running two minutes after {sig.name}") from None
        gone = group_gone(proc.pid) if wait_for_group else True
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # whatever is left, after a failure
        proc.wait()
    return Stopped(proc.returncode, "".join(seen), rest, gone)
