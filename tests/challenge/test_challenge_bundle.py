"""challenge bundle: what Codabench's v2 unpacker requires of competition.yaml, and the
scoring program run as the compute worker runs it, in a virtual environment with numpy alone."""

from __future__ import annotations

import datetime
import io
import json
import os
import subprocess
import sys
import venv
import zipfile

import numpy as np
import pytest
import yaml

from tests.helpers.challenge import official_evaluate, write_reference
from tests.helpers.evaluation import fake_disp, lidar_gt

N = 10
CORRUPTIONS = ["fog", "dark", "snow", "zoom_blur", "pixelate"] * 2


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A challenge folder written by hand (public list, private reference), its bundle and
    a submission."""
    from click.testing import CliRunner

    from robodepth_cli.cli import main

    root = tmp_path_factory.mktemp("bundle")
    ids = [f"{k:x}{k:x}abc" for k in range(N)]
    gts = [lidar_gt((375, 1242), k) for k in range(N)]
    disps = np.stack([fake_disp((192, 640), k, 0.1) for k in range(N)])
    write_reference(root / "C" / "private", ids, gts, corruptions=CORRUPTIONS, levels=[1, 2] * 5)
    (root / "C" / "public").mkdir()
    for name in ("list.txt", "challenge.json"):
        (root / "C" / "public" / name).write_bytes((root / "C" / "private" / name).read_bytes())
    res = CliRunner().invoke(main, ["challenge", "bundle", str(root / "C"), "--out", str(root / "b.zip"),
                                    "--dev-images", "5", "--per-day", "3", "--total", "30",
                                    "--final-total", "2", "--max-size", "100"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    np.save(root / "disp.npy", disps)
    with zipfile.ZipFile(root / "disp.zip", "w", zipfile.ZIP_DEFLATED) as zf:  # results only
        zf.write(root / "disp.npy", "disp.npy")
    return root, ids, gts, disps


def test_competition_yaml_is_what_the_v2_unpacker_reads(case):
    root, ids, _, _ = case
    with zipfile.ZipFile(root / "b.zip") as zf:
        names = set(zf.namelist())
        doc = yaml.safe_load(zf.read("competition.yaml"))

        def has(path):
            return path in names or any(n.startswith(path.rstrip("/") + "/") for n in names)

        def text(path):
            return zf.read(path).decode()

        assert doc["version"] == 2 and doc["title"] and has(doc["image"])
        assert doc["docker_image"] == "codalab/codalab-legacy:py39"
        assert text(doc["terms"]).strip()
        assert [p["title"] for p in doc["pages"]] == ["Overview", "Data", "Evaluation", "Terms"]
        assert all(text(p["file"]).strip() for p in doc["pages"])
        tasks = {t["index"]: t for t in doc["tasks"]}
        assert len(tasks) == len(doc["tasks"])
        for t in tasks.values():
            assert has(t["scoring_program"]) and has(t["reference_data"])
            assert has(t["scoring_program"].rstrip("/") + "/metadata.yaml")
        for s in doc["solutions"]:
            assert set(s["tasks"]) <= set(tasks) and has(s["path"])
        phases = sorted(doc["phases"], key=lambda p: p["index"])
        assert [p["name"] for p in phases] == ["Development", "Final"]
        for a, b in zip(phases, phases[1:]):
            assert a["end"] is not None and b["start"] >= a["end"]
        assert all(isinstance(p["start"], datetime.date) and set(p["tasks"]) <= set(tasks) for p in phases)
        assert (phases[0]["max_submissions_per_day"], phases[0]["max_submissions"]) == (3, 30)
        assert phases[1]["max_submissions"] == 2
        board = doc["leaderboards"][0]
        assert board["columns"][0]["key"] == "abs_rel" and board["columns"][0]["sorting"] == "asc"
        assert [c["index"] for c in board["columns"]] == list(range(len(board["columns"])))
        assert board["primary_index"] == 0
        keys = [c["key"] for c in board["columns"]]
        assert len(set(keys)) == len(keys)  # unique per leaderboard, as Codabench's Column is
        assert all(len(c["key"]) <= 36 and len(c["title"]) <= 36 for c in board["columns"])
        assert {f"dee_{c}" for c in CORRUPTIONS} <= set(keys)
        meta = yaml.safe_load(zf.read("scoring_program/metadata.yaml"))
        assert meta["command"].split()[1:] == ["/app/program/score.py", "/app/input", "/app/output", "100000000"]
        dev_key = [line.split(",") for line in text("reference_dev/key.csv").splitlines()[1:]]
        # each corruption's first image (list positions 0-4), none beyond: K = 5 here
        assert [int(r[1]) for r in dev_key] == [0, 1, 2, 3, 4] and text("reference_dev/list.txt").split() == ids


def _venv_with_numpy_only(where):
    """A fresh virtual environment whose site-packages holds numpy alone (linked from this
    interpreter's: no network, and nothing else of ours)."""
    venv.EnvBuilder(with_pip=False, symlinks=True).create(where)
    py = where / "bin" / "python"
    site = subprocess.check_output([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                   text=True).strip()
    src = os.path.dirname(os.path.dirname(np.__file__))
    for name in os.listdir(src):
        if name == "numpy" or name.startswith("numpy.libs") or (name.startswith("numpy-") and name.endswith("dist-info")):
            os.symlink(os.path.join(src, name), os.path.join(site, name))
    return py


def _worker_run(py, root, bundle, reference, submission_zip, tmp):
    """Codabench's compute worker, scoring step: the program unzipped to program/, the
    reference data to input/ref, the upload to input/res; the metadata command run in
    program/ with /app standing for ``app``."""
    app = tmp / "app"
    for d in ("program", "input/ref", "input/res", "output"):
        (app / d).mkdir(parents=True)
    with zipfile.ZipFile(bundle) as zf:
        for n in zf.namelist():
            for prefix, dest in (("scoring_program/", "program"), (f"{reference}/", "input/ref")):
                if n.startswith(prefix) and not n.endswith("/"):
                    target = app / dest / n[len(prefix):]
                    target.parent.mkdir(parents=True, exist_ok=True)
                    target.write_bytes(zf.read(n))
        meta = yaml.safe_load(zf.read("scoring_program/metadata.yaml"))
    with zipfile.ZipFile(submission_zip) as zf:
        zf.extractall(app / "input" / "res")
    command = meta["command"].replace("/app", str(app)).split()
    command[0] = str(py)
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.run(command, cwd=app / "program", env=env, capture_output=True, text=True, timeout=300)
    return proc, app / "output"


def test_scoring_program_runs_on_numpy_alone(case, tmp_path):
    root, ids, gts, disps = case
    py = _venv_with_numpy_only(tmp_path / "venv")
    probe = subprocess.run([py, "-c", "import numpy\nfor m in ('skimage', 'scipy', 'cv2', 'yaml', 'click'):\n"
                            "    try:\n        __import__(m)\n    except ImportError:\n        pass\n"
                            "    else:\n        raise SystemExit(m)"], capture_output=True, text=True)
    assert probe.returncode == 0, probe.stdout + probe.stderr
    proc, out = _worker_run(py, root, root / "b.zip", "reference_final", root / "disp.zip", tmp_path)
    assert proc.returncode == 0, proc.stderr
    scores = json.loads((out / "scores.json").read_text())
    want = official_evaluate(disps, gts)
    np.testing.assert_allclose([scores[m] for m in ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3")],
                               want, rtol=1e-6)
    assert (out / "detailed_results.html").is_file()
    with zipfile.ZipFile(root / "b.zip") as zf:
        doc = yaml.safe_load(zf.read("competition.yaml"))
    assert {c["key"] for c in doc["leaderboards"][0]["columns"]} <= set(scores)


def test_development_phase_scores_its_images(case, tmp_path):
    root, ids, gts, disps = case
    py = _venv_with_numpy_only(tmp_path / "venv")
    proc, out = _worker_run(py, root, root / "b.zip", "reference_dev", root / "disp.zip", tmp_path)
    assert proc.returncode == 0, proc.stderr
    scores = json.loads((out / "scores.json").read_text())
    assert scores["images"] == 5
    np.testing.assert_allclose(scores["abs_rel"], official_evaluate(disps[:5], gts[:5])[0], rtol=1e-6)
    with zipfile.ZipFile(root / "b.zip") as zf:
        doc = yaml.safe_load(zf.read("competition.yaml"))
    assert {c["key"] for c in doc["leaderboards"][0]["columns"]} <= set(scores)  # every column, this phase too


def test_the_sample_submission_and_the_starting_kit(case, tmp_path):
    root, ids, _, _ = case
    py = _venv_with_numpy_only(tmp_path / "venv")
    with zipfile.ZipFile(root / "b.zip") as zf:
        sample = io.BytesIO()
        with zipfile.ZipFile(sample, "w") as out:  # as Codabench zips the solution folder
            out.writestr("disp.npz", zf.read("solutions/sample/disp.npz"))
        (tmp_path / "sample.zip").write_bytes(sample.getvalue())
        kit = tmp_path / "make_submission.py"
        kit.write_bytes(zf.read("starting_kit/make_submission.py"))
    proc, out = _worker_run(py, root, root / "b.zip", "reference_final", tmp_path / "sample.zip", tmp_path / "a")
    assert proc.returncode == 0, proc.stderr
    pred = tmp_path / "pred"
    pred.mkdir()
    for k, i in enumerate(reversed(ids)):  # written in any order: the kit follows list.txt
        np.save(pred / f"{i}.npy", fake_disp((96, 320), k, 0.1)[None])
    made = subprocess.run([py, kit, root / "C" / "public", pred, tmp_path / "kit.zip", "--half"],
                          capture_output=True, text=True)
    assert made.returncode == 0, made.stderr
    proc, out = _worker_run(py, root, root / "b.zip", "reference_final", tmp_path / "kit.zip", tmp_path / "b")
    assert proc.returncode == 0, proc.stderr


def test_hostile_upload_on_the_server(case, tmp_path):
    root, ids, _, disps = case
    py = _venv_with_numpy_only(tmp_path / "venv")
    arr = np.empty(N, object)
    arr[:] = list(disps)
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=True)
    with zipfile.ZipFile(tmp_path / "evil.zip", "w") as zf:
        zf.writestr("disp.npy", buf.getvalue())
    proc, out = _worker_run(py, root, root / "b.zip", "reference_final", tmp_path / "evil.zip", tmp_path)
    assert proc.returncode == 1
    assert proc.stderr.count("\n") == 1 and "object array" in proc.stderr and "Traceback" not in proc.stderr
    assert list(out.iterdir()) == []


def test_bundle_refusals(cli, case, tmp_path):
    from tests.helpers.messages import one_line_error

    root = case[0]
    one_line_error(cli("challenge", "bundle", tmp_path, "--out", tmp_path / "b.zip"), "missing")
    one_line_error(cli("challenge", "bundle", root / "C", "--out", tmp_path / "b.zip", "--dev-images", "99"),
                   "--dev-images 99", "5..10")
    one_line_error(cli("challenge", "bundle", root / "C", "--out", tmp_path / "b.zip", "--dev-images", "3"),
                   "at least one image per corruption")
    one_line_error(cli("challenge", "bundle", root / "C", "--out", tmp_path / "b.zip", "--final-start",
                       "2025-01-01"), "in that order")
    assert sys.version_info >= (3, 8)


def test_program_files_parse_as_python_3_8():
    """Codabench's images run older Pythons (py39 the default): no newer syntax in the
    files the bundle copies, and annotations stay strings."""
    import ast

    from robodepth_cli.challenge.bundle import PROGRAM_FILES
    from tests.helpers.paths import REPO

    for rel in PROGRAM_FILES:
        src = (REPO / "robodepth_cli" / rel).read_text()
        ast.parse(src, feature_version=(3, 8))
        assert rel.endswith("__init__.py") or "from __future__ import annotations" in src, rel
