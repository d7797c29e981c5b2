"""The loop `make demo` shows, on the shipped fixtures: a build from KITTI frames with
velodyne scans carries its ground truth, `gt kitti` makes the same maps on their own, and
the sample predictions evaluate and score (tests/data/README.md says where they come from)."""

from __future__ import annotations


import numpy as np

from tests.helpers.paths import DATA, FIXTURES
from tests.helpers.trees import fixture_kitti_with_scans


def test_build_gt_evaluate_score_on_the_fixtures(tmp_path, cli):
    root = fixture_kitti_with_scans(tmp_path)
    split = FIXTURES / "kitti_split.txt"
    out = tmp_path / "kitti-c"
    res = cli("build", "kitti-c", "--root", root, "--split", split, "--out", out,
              "--corruptions", "fog,gaussian_noise", "--jobs", "1")
    assert res.exit_code == 0 and "note:" not in res.output, res.output
    assert cli("verify", out).exit_code == 0
    res = cli("gt", "kitti", "--root", root, "--split", split, "--out", tmp_path / "gt.npz")
    assert res.exit_code == 0, res.output
    built = np.load(out / "gt_depths.npz", allow_pickle=True)["data"]
    alone = np.load(tmp_path / "gt.npz", allow_pickle=True)["data"]
    assert len(built) == 2 and all(np.array_equal(a, b) for a, b in zip(built, alone))
    assert all((m > 0).sum() > 1000 for m in built)  # scans that reach the evaluated crop

    res = cli("evaluate", out, "--pred", DATA / "predictions" / "kitti-c", "--out", tmp_path / "r.csv",
              "--score", "--json")
    assert res.exit_code == 0, res.output
    import json

    doc = json.loads(res.stdout)
    rows = {(r["corruption"], r["level"]): r for r in doc["results"]}
    assert len(rows) == 11 and rows["clean", 0]["abs_rel"] < 0.1
    # The stand-in model gets worse with the level, as a real one does.
    assert rows["fog", 5]["abs_rel"] > rows["fog", 1]["abs_rel"] > rows["clean", 0]["abs_rel"]
    res = cli("score", tmp_path / "r.csv", "-b", "kitti-c", "--allow-partial", "--plot", tmp_path / "ce.png")
    assert res.exit_code == 0 and (tmp_path / "ce.png").is_file(), res.output
