"""`robodepth run`: the results CSV of build -> predict -> evaluate, from images made in memory.

The fixtures go through both paths (the KITTI frames with their velodyne scans copied in, as
`make demo` does) and the two CSVs must be the same bytes; a run killed after its first
variant resumes from its state and ends with the same CSV.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest

from tests.helpers.paths import FIXTURES, REPO

KITTI_FLAGS = ("--size", "64x96", "--corruptions", "fog,gaussian_noise", "--levels", "1,3",
               "--compose", "fog:3+gaussian_noise:2.5")
NYU_FLAGS = ("--size", "48x64", "--corruptions", "brightness,motion_blur", "--levels", "2,4")

# A python: model whose maps follow the image; RUN_TEST_KILL_AT=N kills its process at call N.
MODEL = '''
import os, signal
import numpy as np
calls = 0
def predict(images):
    global calls
    calls += 1
    if calls == int(os.environ.get("RUN_TEST_KILL_AT", "0")):
        os.kill(os.getpid(), signal.SIGKILL)
    return 1.0 + images.astype(np.float32).mean(-1) / 32.0
'''


@pytest.fixture(scope="module")
def py_model(tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "depth_model.py"
    path.write_text(MODEL)
    return f"python:{path}:predict"


def build_predict_evaluate(cli, tmp_path, build, predict, evaluate=()):
    """The three commands a run replaces, as a user types them: ``build *build`` into
    tmp_path/B, ``predict -m ...`` into P, ``evaluate *evaluate`` into e.csv; evaluate's
    result."""
    res = cli("build", *build, "--out", tmp_path / "B", "--jobs", "1")
    assert res.exit_code == 0, res.output
    res = cli("predict", tmp_path / "B", *predict, "--out", tmp_path / "P", "--no-progress")
    assert res.exit_code == 0, res.output
    res = cli("evaluate", tmp_path / "B", "--pred", tmp_path / "P", "--out", tmp_path / "e.csv",
              *evaluate, "--no-progress")
    assert res.exit_code == 0, res.output
    return res


@pytest.mark.slow
def test_kitti_run_writes_the_csv_of_build_predict_evaluate(tmp_path, cli, kitti_scans_root):
    import torch

    from tests.helpers.models import random_monodepth2

    torch.manual_seed(0)
    random_monodepth2(tmp_path / "m", 18)
    model = f"monodepth2:{tmp_path / 'm'}"
    split = FIXTURES / "kitti_split.txt"
    res = build_predict_evaluate(cli, tmp_path, ("kitti-c", "--root", kitti_scans_root, "--split", split,
                                                 *KITTI_FLAGS), ("-m", model, "--device", "cpu"), ("--score",))
    scores = res.stdout[res.stdout.index("mCE"):]

    res = cli("run", "kitti-c", "--root", kitti_scans_root, "--split", split, "-m", model, "--device",
              "cpu", "--out", tmp_path / "r.csv", *KITTI_FLAGS, "--keep-predictions",
              tmp_path / "K", "--no-progress")
    assert res.exit_code == 0, res.output
    expected = (tmp_path / "e.csv").read_bytes()
    assert (tmp_path / "r.csv").read_bytes() == expected
    assert expected.count(b"\n") == 7  # header, clean, 2 x 2 levels, the chain
    assert scores in res.stdout  # the scores, as evaluate --score prints them
    assert not (tmp_path / "r.csv.state.json").exists()
    # The kept predictions are predict's, file for file.
    kept = sorted(p.relative_to(tmp_path / "K") for p in (tmp_path / "K").rglob("*.npy"))
    assert kept == sorted(p.relative_to(tmp_path / "P") for p in (tmp_path / "P").rglob("*.npy"))
    assert len(kept) == 6
    for rel in kept:
        assert np.array_equal(np.load(tmp_path / "K" / rel), np.load(tmp_path / "P" / rel))


def test_nyu_run_writes_the_csv_of_build_predict_evaluate(tmp_path, cli, py_model):
    split = FIXTURES / "nyu_split.txt"
    model = (py_model, "--kind", "depth", "--metric")
    build_predict_evaluate(cli, tmp_path, ("nyudepth2-c", "--root", FIXTURES / "nyu", "--split", split,
                                           *NYU_FLAGS), ("-m", *model))
    res = cli("run", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", split, "-m", *model,
              "--out", tmp_path / "r.csv", *NYU_FLAGS, "--no-progress")
    assert res.exit_code == 0, res.output
    expected = (tmp_path / "e.csv").read_bytes()
    assert (tmp_path / "r.csv").read_bytes() == expected and expected.count(b"\n") == 6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["B", "P", "e.csv", "e.csv.json", "r.csv", "r.csv.json"]


def test_a_weak_model_gets_warnings_and_its_csv_not_a_refusal(tmp_path, cli):
    # Every depth 50 m (capped at NYU's 10 m) in rooms 1 to 5 m deep: clean DEE above 1.
    # The work done, the CSV is written and the exit is 0; the warning comes twice: when the
    # clean variant is done (a mixed-up --kind can be stopped there) and at the end.
    model = tmp_path / "far.py"
    model.write_text("import numpy as np\ndef predict(images):\n"
                     "    return np.full(images.shape[:3], 50.0, np.float32)\n")
    res = cli("run", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", FIXTURES / "nyu_split.txt",
              "-m", f"python:{model}:predict", "--kind", "depth", "--metric", "--align", "none",
              "--out", tmp_path / "r.csv", *NYU_FLAGS, "--no-progress")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "r.csv").read_text().count("\n") == 6
    warnings = [ln for ln in res.stderr.splitlines() if "is implausible" in ln]
    assert len(warnings) == 2 and all(w.startswith("robodepth: warning: clean DEE ") for w in warnings)
    assert "Ctrl-C now" in warnings[0] and "written, not scored" in warnings[1]


def test_nyu_run_from_the_labeled_file(tmp_path, cli, py_model):
    from tests.helpers.gt_trees import write_labeled, write_split

    mat = tmp_path / "nyu_depth_v2_labeled.mat"
    write_labeled(mat)
    split = write_split(tmp_path / "split.txt", [0, 3])
    flags = ("--split", split, "--size", "48x64", "--corruptions", "contrast", "--levels", "3")
    model = (py_model, "--kind", "depth", "--metric")
    build_predict_evaluate(cli, tmp_path, ("nyudepth2-c", "--root", mat, *flags), ("-m", *model))
    res = cli("run", "nyudepth2-c", "--root", mat, "-m", *model, "--out", tmp_path / "r.csv",
              *flags, "--no-progress")
    # The file's depths are noise, so no model scores: the CSV is written, with a warning.
    assert res.exit_code == 0 and "robodepth: warning: clean DEE" in res.output, res.output
    assert (tmp_path / "r.csv").read_bytes() == (tmp_path / "e.csv").read_bytes()


def test_a_run_killed_after_one_variant_resumes(tmp_path, cli, py_model):
    split = FIXTURES / "nyu_split.txt"
    args = ["run", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", split, "-m", py_model,
            "--kind", "depth", "--metric", *NYU_FLAGS, "--no-progress"]
    res = cli(*args, "--out", tmp_path / "whole.csv")
    assert res.exit_code == 0, res.output

    out = tmp_path / "r.csv"
    # Two images, batches of 8: one call per variant; the second call (brightness 2) kills.
    env = {**os.environ, "PYTHONPATH": str(REPO), "RUN_TEST_KILL_AT": "2"}
    proc = subprocess.run([sys.executable, "-m", "robodepth_cli.cli", *map(str, args), "--out", out],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert not out.exists()
    import json

    state = json.loads((tmp_path / "r.csv.state.json").read_text())
    assert list(state["variants"]) == ["clean"]

    res = cli(*args, "--out", out)
    assert res.exit_code == 0, res.output
    assert "1 of 5 variants taken from" in res.output
    assert out.read_bytes() == (tmp_path / "whole.csv").read_bytes()
    assert not (tmp_path / "r.csv.state.json").exists()

    # A state made with other settings is not taken.
    (tmp_path / "r.csv.state.json").write_text(json.dumps(state))
    res = cli(*[a if a != "48x64" else "40x56" for a in args], "--out", out)
    assert res.exit_code == 0, res.output
    assert "other settings (size differs); starting afresh" in res.output
    assert "variants taken from" not in res.output


def test_run_refusals(tmp_path, cli, kitti_scans_root, py_model, monkeypatch):

    split = FIXTURES / "kitti_split.txt"
    base = ["run", "kitti-c", "--root", kitti_scans_root, "--split", split, "-m", py_model, "--kind",
            "depth", "--metric", "--corruptions", "fog", "--levels", "1", "--size", "32x48",
            "--no-progress"]
    (tmp_path / "file").write_text("")
    res = cli(*base, "--out", tmp_path / "file" / "r.csv")
    assert res.exit_code == 2 and "robodepth: error: --out" in res.output
    res = cli("run", "custom", "--root", kitti_scans_root, "-m", py_model, "--kind", "depth",
              "--out", tmp_path / "r.csv", "--no-progress")
    assert res.exit_code == 2 and "run judges a model on the corruption benchmarks" in res.output
    bare = tmp_path / "no_scans"
    shutil.copytree(FIXTURES / "kitti_raw", bare)
    res = cli(*[bare if a == kitti_scans_root else a for a in base], "--out", tmp_path / "r.csv")
    assert res.exit_code == 2 and "no ground truth:" in res.output and "velodyne" in res.output
    assert not (tmp_path / "r.csv").exists() and not (tmp_path / "r.csv.state.json").exists()


def test_run_on_the_torch_engine_gives_the_numpy_engines_csv(tmp_path, cli, kitti_scans_root, py_model):
    """contrast and gaussian_noise are byte-identical on CPU torch, so the results are too."""
    split = FIXTURES / "kitti_split.txt"
    args = ["run", "kitti-c", "--root", kitti_scans_root, "--split", split, "-m", py_model, "--kind",
            "depth", "--metric", "--corruptions", "contrast,gaussian_noise", "--levels", "2",
            "--size", "32x48", "--no-progress"]
    for engine in ("numpy", "torch"):
        res = cli(*args, "--engine", engine, "--device", "cpu", "--out", tmp_path / f"{engine}.csv")
        assert res.exit_code == 0, res.output
    assert (tmp_path / "torch.csv").read_bytes() == (tmp_path / "numpy.csv").read_bytes()
