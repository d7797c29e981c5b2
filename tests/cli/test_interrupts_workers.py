"""Ctrl-C and SIGTERM stop the commands that run worker processes (`evaluate --jobs`,
`gt kitti --jobs`, `build --jobs`) at once: one line, exit status 130, no worker's
traceback, no process left behind (issue 26). test_reliability.py stops builds mid-way.

The inputs are large enough that the commands really start workers (more than 500 maps for
evaluate; several runs of frames for gt), and each task sent to a worker is larger than a
pipe's buffer (evaluate's variants name 1000 images): a queue's feeder thread blocked on
such a task, with no worker left to read it, used to hang the command at exit.

The command is stopped at a known point, not at a guessed time: the test wraps the worker
pool so that it says READY on stderr once its workers are started (they may still be
importing numpy: a Ctrl-C there used to print their tracebacks), or once the first result
is back and the workers run the next tasks (the command then waits for the signal).
"""

from __future__ import annotations

import signal

import numpy as np
import pytest
from tests.helpers.gt_trees import write_tree
from tests.helpers.signals import signal_when_ready
from tests.helpers.trees import kitti_tree

# Every test here is a long end-to-end run (make test-fast leaves them out).
pytestmark = pytest.mark.slow

STOP_AT = """
import multiprocessing, signal, sys, threading, time
# A shell that starts the suite in the background leaves SIGINT ignored in its children; a
# handler here (not SIG_IGN) also gives the workers a terminal's SIGINT, as they start.
signal.signal(signal.SIGINT, signal.default_int_handler)
from robodepth_cli import workers
real, at = workers.in_order, sys.argv[1]

def ready():
    sys.stderr.write("READY\\n")
    sys.stderr.flush()

def watch(jobs):
    while len(multiprocessing.active_children()) < jobs:
        time.sleep(0.001)
    ready()

def stopping(fn, tasks, jobs, *args, **kwargs):
    results = real(fn, tasks, jobs, *args, **kwargs)
    try:
        yield next(results)
        if at == "result":  # the first result is back, the workers run the next tasks
            ready()
            time.sleep(60)  # a lost signal fails the test in a minute instead of hanging it
        yield from results
    finally:
        results.close()

if at == "start":  # once two workers are started (still importing, say)
    threading.Thread(target=watch, args=(2,), daemon=True).start()
workers.in_order = stopping
from robodepth_cli.cli import main
sys.argv = ["robodepth", *sys.argv[2:]]
main()
"""

FRAMES = 1000  # > 500 maps per worker, and a variant's task over 64 KiB pickled
LEVELS = "1,2,3"


@pytest.fixture(scope="module")
def big_kitti_c(tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("big")
    split = kitti_tree(d / "raw", [(i, "l", ".png") for i in range(FRAMES)], size=(32, 32))
    out = d / "KITTI_C"
    res = cli("build", "kitti-c", "--root", d / "raw", "--split", split, "--out", out, "--size",
              "32x32", "--corruptions", "brightness", "--levels", LEVELS, "--jobs", "1", "--no-gt")
    assert res.exit_code == 0, res.output
    rng = np.random.default_rng(0)
    gts = np.empty(FRAMES, object)
    for i in range(FRAMES):
        gts[i] = rng.uniform(1, 80, (32, 96)).astype(np.float32)
    np.savez(out / "gt_depths.npz", data=gts)
    pred = d / "PRED"
    for v in ["clean", *(f"brightness/{lv}" for lv in LEVELS.split(","))]:
        (pred / v).parent.mkdir(parents=True, exist_ok=True)
        np.save(pred / f"{v}.npy", rng.uniform(0.001, 0.2, (FRAMES, 32, 32)).astype(np.float32))
    return out, pred


@pytest.fixture(scope="module")
def kitti_raw(tmp_path_factory, fixtures_dir):
    root, split, _ = write_tree(tmp_path_factory.mktemp("raw"), fixtures_dir, frames_per_drive=12)
    return root, split


def stop(args, at: str, sig, whole_group: bool, cwd):
    """Run ``robodepth ARGS``, send ``sig`` when its workers have started (``at="start"``)
    or have returned a first result (``at="result"``), to the process group or to the
    command alone; return (exit status, stderr after the signal)."""
    stopped = signal_when_ready(STOP_AT, [at, *args], sig, cwd=cwd, whole_group=whole_group,
                                wait_for_group=True)
    assert stopped.group_gone, "a worker outlived the command"
    return stopped.returncode, stopped.after


NOTHING = "robodepth: interrupted; nothing was written\n"


@pytest.mark.parametrize("at, sig, whole_group", [
    ("start", signal.SIGINT, True),  # Ctrl-C in a terminal: the whole group
    ("start", signal.SIGTERM, True),  # a scheduler ending the job
    ("result", signal.SIGINT, True),
    ("result", signal.SIGTERM, True),
    ("result", signal.SIGTERM, False),  # kill PID: the workers are not signalled
], ids=["start-ctrl-c", "start-sigterm", "busy-ctrl-c", "busy-sigterm", "busy-sigterm-main-only"])
def test_evaluate_with_workers_stops_at_once(big_kitti_c, tmp_path, at, sig, whole_group):
    dataset, pred = big_kitti_c
    out = tmp_path / "r.csv"
    # --jobs 3: two workers beside this process, which evaluates too
    status, err = stop(["evaluate", dataset, "--pred", pred, "--out", out, "--jobs", "3",
                        "--no-progress"], at, sig, whole_group, tmp_path)
    assert (status, err) == (130, NOTHING)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("at, sig", [("start", signal.SIGINT), ("result", signal.SIGTERM)],
                         ids=["start-ctrl-c", "busy-sigterm"])
def test_gt_kitti_with_workers_stops_at_once(kitti_raw, tmp_path, at, sig):
    root, split = kitti_raw
    out = tmp_path / "gt_depths.npz"
    status, err = stop(["gt", "kitti", "--root", root, "--split", split, "--out", out, "--jobs", "2",
                        "--no-progress"], at, sig, True, tmp_path)
    assert (status, err) == (130, NOTHING)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_build_stops_at_once_while_its_workers_start(fixtures_dir, tmp_path, sig):
    out = tmp_path / "KITTI_C"
    status, err = stop(["build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split",
                        fixtures_dir / "kitti_split.txt", "--out", out, "--size", "32x96",
                        "--corruptions", "brightness", "--levels", "1", "--jobs", "2", "--no-gt",
                        "--no-progress"], "start", sig, True, tmp_path)
    assert status == 130, err
    assert err.splitlines()[-1] == "robodepth: interrupted; rerun the same command to resume", err
    assert "Traceback" not in err and "Process" not in err, err


def test_a_ctrl_c_held_while_a_worker_starts_kills_that_worker(monkeypatch):
    """The Ctrl-C held back during a worker's start is raised as the start ends: the worker
    just started must be killed with the others (it was left running, and its start-up then
    failed on the inputs the command had removed, printing a traceback)."""
    import time

    from robodepth_cli import workers

    started = []
    real_start = workers._start_held

    def start_then_interrupt(process):
        real_start(process)
        started.append(process)
        raise KeyboardInterrupt  # as signals_held delivers a Ctrl-C that came during the start

    monkeypatch.setattr(workers, "_start_held", start_then_interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            list(workers.in_order(abs, [(-1,)], 1, time.sleep, (60,)))
        assert len(started) == 1 and not started[0].is_alive()
    finally:
        for process in started:
            if process.is_alive():
                process.kill()
                process.join()
