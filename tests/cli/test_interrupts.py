"""Ctrl-C (SIGINT) and SIGTERM stop every command the same way: one line saying what was
kept, exit status 130, no partial file, never click's `Aborted!` (issue 19).

Each command runs in its own process with real signals. To stop it at a known point in its
work (not at a time guessed by the test), one function it calls is wrapped so that its N-th
call says READY on stderr and waits; the test then sends the signal.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers.gt_trees import write_labeled, write_split, write_tree
from tests.helpers.paths import REPO
from tests.helpers.signals import signal_when_ready

WAIT_AT = """
import importlib, signal, sys, time
# A shell that starts the suite in the background (no job control) leaves SIGINT ignored in
# its children, and Python then installs no KeyboardInterrupt handler: restore it, as a
# terminal would have it, so the test does not depend on how pytest was started.
signal.signal(signal.SIGINT, signal.default_int_handler)
module, name, nth = sys.argv[1], sys.argv[2], int(sys.argv[3])
target = importlib.import_module(module)
real = getattr(target, name)
calls = []

def waiting(*args, **kwargs):
    calls.append(1)
    if len(calls) == nth:
        sys.stderr.write("READY\\n")
        sys.stderr.flush()
        time.sleep(60)  # a lost signal fails the test in a minute instead of hanging it
    return real(*args, **kwargs)

setattr(target, name, waiting)
from robodepth_cli.cli import main
sys.argv = ["robodepth", *sys.argv[4:]]
main()
"""

NOTHING = "nothing was written"


def run_until(where: str, nth: int, args, sig, cwd: Path):
    """Run ``robodepth ARGS`` until the ``nth`` call of ``where`` (module:function), send
    ``sig``, and return (exit status, stderr)."""
    module, name = where.split(":")
    stopped = signal_when_ready(WAIT_AT, [module, name, nth, *args], sig, cwd=cwd)
    return stopped.returncode, stopped.before + stopped.after


def no_temporaries(folder: Path):
    return [p for p in folder.rglob("*") if p.name.endswith(".part")]


@pytest.fixture(scope="module")
def inputs(kitti_c, kitti_pred, tmp_path_factory, fixtures_dir):  # noqa: F811
    d = tmp_path_factory.mktemp("inputs")
    root, split, _ = write_tree(d, fixtures_dir, frames_per_drive=1)
    mat = d / "labeled.mat"
    write_labeled(mat)
    nyu_split = write_split(d / "nyu_split.txt", [0, 1, 2])
    results = d / "r.csv"
    results.write_text("corruption,level,abs_rel,a1\nclean,0,0.1,0.9\nfog,1,0.1,0.9\n")
    from tests.helpers.adain import save_checkpoints

    vgg, dec, *_ = save_checkpoints(d)
    frame = fixtures_dir / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"
    model = d / "usermodel.py"
    model.write_text("def brightness(images):\n    return 0.02 + images.mean(axis=3) / 2550\n")
    return {"dataset": kitti_c[0], "pred": kitti_pred, "kitti_raw": root, "kitti_split": split,
            "mat": mat, "nyu_split": nyu_split, "results": results, "vgg": vgg, "decoder": dec,
            "frame": frame, "fixtures": fixtures_dir, "model": model}


# (name, the function to stop in and at which call, arguments, what is kept, outputs that
# must not exist afterwards); {OUT} is a fresh folder per run.
CASES = [
    ("evaluate", "robodepth_cli.evaluation.evaluate:_evaluate_variant", 2,
     lambda i: ["evaluate", i["dataset"], "--pred", i["pred"], "--out", "{OUT}/r.csv", "--no-progress"],
     NOTHING, ["r.csv"]),
    ("gt kitti", "robodepth_cli.groundtruth.kitti:depth_map", 2,
     lambda i: ["gt", "kitti", "--root", i["kitti_raw"], "--split", i["kitti_split"], "--out",
                "{OUT}/gt_depths.npz", "--no-progress"],
     NOTHING, ["gt_depths.npz"]),
    ("gt nyu", "robodepth_cli.groundtruth.nyu:encode_depth_png", 2,
     lambda i: ["gt", "nyu", "--root", i["mat"], "--split", i["nyu_split"], "--out", "{OUT}/NYU_TEST",
                "--no-progress"],
     NOTHING, ["NYU_TEST"]),
    ("score", "robodepth_cli.evaluation.scores:score", 1,
     lambda i: ["score", i["results"], "-b", "kitti-c", "--allow-partial", "--plot", "{OUT}/ce.png"],
     NOTHING, ["ce.png"]),
    ("corrupt", "robodepth_cli.commands.common:write_png", 2,
     lambda i: ["corrupt", i["frame"], "-c", "brightness,contrast", "-l", "1", "--size", "32x96",
                "--out", "{OUT}/shots/"],
     "the images written so far are kept under {OUT}/shots/, each complete", ["shots/contrast"]),
    ("preview", "robodepth_cli.commands.common:write_png", 1,
     lambda i: ["preview", i["frame"], "-c", "brightness", "--size", "32x96", "--out", "{OUT}/sheet.png"],
     NOTHING, ["sheet.png"]),
    ("stylize", "robodepth_cli.commands.common:write_png", 1,
     lambda i: ["stylize", i["frame"], "--style", i["fixtures"] / "styles/sketch.png", "--vgg", i["vgg"],
                "--decoder", i["decoder"], "--size", "32x96", "--style-size", "32", "--out",
                "{OUT}/s.png"],
     NOTHING, ["s.png"]),
    ("verify", "robodepth_cli.output.verify:verify", 1,
     lambda i: ["verify", i["dataset"], "--no-progress"], NOTHING, []),
    ("predict", "robodepth_cli.models.predict:same_size_runs", 2,
     lambda i: ["predict", i["dataset"], "-m", f"python:{i['model']}:brightness", "--kind", "disp",
                "--out", "{OUT}/PRED", "--no-progress"],
     "the variants finished so far are kept under {OUT}/PRED, each complete; rerun the same "
     "command to continue", ["PRED/brightness/1.npy"]),
    ("run", "robodepth_cli.running.loop:_judge", 2,
     lambda i: ["run", "nyudepth2-c", "--root", i["mat"], "--split", i["nyu_split"], "-m",
                f"python:{i['model']}:brightness", "--kind", "depth", "--size", "32x48",
                "--corruptions", "brightness", "--levels", "1", "--out", "{OUT}/r.csv",
                "--no-progress"],
     "the finished variants are kept in {OUT}/r.csv.state.json; rerun the same command to "
     "continue", ["r.csv"]),
    ("build", "robodepth_cli.building.pipeline:run_tasks", 1,
     lambda i: ["build", "kitti-c", "--root", i["fixtures"] / "kitti_raw", "--split",
                i["fixtures"] / "kitti_split.txt", "--out", "{OUT}/KITTI_C", "--size", "32x96",
                "--corruptions", "brightness", "--levels", "1", "--jobs", "1", "--no-progress"],
     "rerun the same command to resume", []),
]


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
@pytest.mark.parametrize("name, where, nth, args, kept, absent", CASES, ids=[c[0] for c in CASES])
def test_every_command_stops_cleanly(inputs, tmp_path, sig, name, where, nth, args, kept, absent):
    out = tmp_path / "out"
    out.mkdir()
    argv = [str(a).replace("{OUT}", str(out)) for a in args(inputs)]
    status, err = run_until(where, nth, argv, sig, tmp_path)
    assert status == 130, err
    lines = err.strip().splitlines()
    assert lines[-1] == f"robodepth: interrupted; {kept.replace('{OUT}', str(out))}", err
    assert "Aborted" not in err and "Traceback" not in err, err
    for rel in absent:
        assert not (out / rel).exists(), rel
    assert not no_temporaries(out) and not no_temporaries(tmp_path)
    if name == "corrupt":
        assert [p.relative_to(out).as_posix() for p in out.rglob("*.png")] == ["shots/brightness/1.png"]
    if name == "gt nyu":
        assert list(out.iterdir()) == []
    if name == "predict":  # the first variant (clean) was finished before the signal
        assert (out / "PRED" / "clean.npy").is_file()
    if name == "run":  # likewise, kept as its row
        assert '"clean"' in (out / "r.csv.state.json").read_text()


def test_interrupts_are_documented(cli):
    text = " ".join(cli("--help").output.split())
    assert "Ctrl-C" in text and "130" in text
    doc = (REPO / "docs" / "evaluation.md").read_text()
    assert "SIGTERM" in doc and "130" in doc


# Stopped just after the output is in place (where the command says "wrote ..."): the line
# says the output is there, complete, never "nothing was written" (issue 26).
WRITTEN = [
    ("evaluate", lambda i: ["evaluate", i["dataset"], "--pred", i["pred"], "--out", "{OUT}/r.csv",
                            "--no-progress"], "r.csv"),
    ("gt kitti", lambda i: ["gt", "kitti", "--root", i["kitti_raw"], "--split", i["kitti_split"],
                            "--out", "{OUT}/gt_depths.npz", "--no-progress"], "gt_depths.npz"),
    ("gt nyu", lambda i: ["gt", "nyu", "--root", i["mat"], "--split", i["nyu_split"], "--out",
                          "{OUT}/NYU_TEST", "--no-progress"], "NYU_TEST"),
    ("score", lambda i: ["score", i["results"], "-b", "kitti-c", "--allow-partial", "--plot",
                         "{OUT}/ce.png"], "ce.png"),
    ("preview", lambda i: ["preview", i["frame"], "-c", "brightness", "--size", "32x96", "--out",
                           "{OUT}/sheet.png"], "sheet.png"),
]


@pytest.mark.slow
@pytest.mark.parametrize("name, args, output", WRITTEN, ids=[c[0] for c in WRITTEN])
def test_an_interrupt_after_the_output_is_written_says_so(inputs, tmp_path, name, args, output):
    out = tmp_path / "out"
    out.mkdir()
    argv = [str(a).replace("{OUT}", str(out)) for a in args(inputs)]
    status, err = run_until("robodepth_cli.commands.common:wrote", 1, argv, signal.SIGTERM, tmp_path)
    assert status == 130, err
    assert err.strip().splitlines()[-1] == \
        f"robodepth: interrupted; {out / output} was written (complete) before the interrupt", err
    assert (out / output).exists() and not no_temporaries(out)


def test_sigterm_while_the_command_starts_exits_130_as_later():
    # The group's handler comes after the imports; a scheduler's SIGTERM before it (export
    # was seen exiting 143 there) gets the same line and status as one during the work.
    code = ("import os, signal, sys, time; sys.argv = ['robodepth']; import robodepth_cli.cli; "
            "os.kill(os.getpid(), signal.SIGTERM); time.sleep(30)")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 130, (proc.returncode, proc.stderr)
    assert proc.stderr == "robodepth: interrupted; nothing was written\n"


AT_THE_END = """
import signal, sys, time
sys.argv = ["robodepth", *sys.argv[1:]]  # as the console script starts it
real_exit = sys.exit

def waiting(code=0):
    # After the command's last line, where click ends the process.
    sys.stderr.write("READY\\n")
    sys.stderr.flush()
    time.sleep(60)
    real_exit(code)

sys.exit = waiting
from robodepth_cli.cli import main
main()
"""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_a_signal_after_the_last_line_exits_130_too(tmp_path, sig):
    # SIGTERM there used to find the default handler back and exit 143 (issue 42).
    stopped = signal_when_ready(AT_THE_END, ["list"], sig, cwd=tmp_path)
    assert stopped.returncode == 130, stopped
    assert stopped.after.strip().splitlines()[-1] == \
        "robodepth: interrupted as the command ended; what it wrote is complete", stopped


def test_an_interrupt_wrapped_in_another_exception_is_still_an_interrupt(cli, monkeypatch,
                                                                         fixtures_dir, tmp_path):
    # A KeyboardInterrupt raised as a compiled kernel returns reaches its caller as
    # SystemError; a command it escapes from stops as an interrupt, not with a traceback
    # (issue 42).
    from robodepth_cli.corruptions import _engine

    def kernel_returning(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("CPUDispatcher(...) returned a result with an exception set") from exc

    monkeypatch.setattr(_engine, "render", kernel_returning)
    frame = fixtures_dir / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"
    res = cli("corrupt", frame, "-c", "brightness", "-l", "1", "--out", f"{tmp_path}/shots/")
    assert res.exit_code == 130, res.output
    assert res.output.strip().splitlines()[-1].startswith("robodepth: interrupted;"), res.output
