"""`robodepth evaluate --jobs N`: worker processes give the numbers of one job, to the last
bit, under both protocols and with predictions in every form; errors are the ones one job
reports."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from robodepth_cli.evaluation import evaluate as E

from tests.helpers.builds import copy_build

VARIANTS = ["clean", "brightness/1", "brightness/3", "contrast/1", "contrast/3"]
KEYS69 = "kitti_data/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


@pytest.fixture(autouse=True)
def workers_for_small_work(monkeypatch):
    monkeypatch.setattr(E, "MAPS_PER_WORKER", 1)  # else a few maps get no worker at all


@pytest.fixture(scope="module")
def kitti(kitti_c_build, tmp_path_factory):
    out = copy_build(kitti_c_build, tmp_path_factory)
    rng = np.random.default_rng(0)
    gts = np.empty(2, object)
    for i, shape in enumerate([(375, 1242), (370, 1226)]):
        g = rng.uniform(1, 90, shape).astype(np.float32)
        g[rng.random(shape) > 0.07] = 0
        gts[i] = g
    np.savez_compressed(out / "gt_depths.npz", data=gts)
    pred = out.parent / "PRED"
    for k, v in enumerate(VARIANTS):
        (pred / v).parent.mkdir(parents=True, exist_ok=True)
        np.save(pred / f"{v}.npy", rng.uniform(0.001, 0.2, (2, 64, 96)).astype(np.float32) * (1 + k))
    return out, pred


def _run(cli, out, pred, tmp_path, jobs, *more):
    csv = tmp_path / f"r{jobs}.csv"
    res = cli("evaluate", out, "--pred", pred, "--out", csv, "--jobs", jobs, "--json", *more)
    assert res.exit_code == 0, res.output
    return csv.read_text(), json.loads(res.stdout)


@pytest.mark.parametrize("flags", [(), ("--stereo",)])
def test_kitti_same_bits_with_two_jobs(kitti, tmp_path, cli, flags, monkeypatch):
    out, pred = kitti
    pools, real = [], E._evaluate_in_workers
    monkeypatch.setattr(E, "_evaluate_in_workers", lambda *a: pools.append(a[-1]) or real(*a))
    one, two = _run(cli, out, pred, tmp_path, 1, *flags), _run(cli, out, pred, tmp_path, 2, *flags)
    assert pools == [2]  # one job ran in-process, two in a pool of two
    assert one[0] == two[0]  # the CSV keeps every digit (repr)
    assert one[1]["results"] == two[1]["results"]  # scaling ratios too
    assert len(one[0].splitlines()) == 1 + len(VARIANTS)


def test_nyu_and_png_forms_same_bits_with_two_jobs(fixtures_dir, tmp_path, cli):
    out = tmp_path / "NYU_C"
    res = cli("build", "nyudepth2-c", "--root", fixtures_dir / "nyu", "--split",
              fixtures_dir / "nyu_split.txt", "--out", out, "--corruptions", "brightness,contrast",
              "--levels", "1", "--jobs", "1", "--no-gt")
    assert res.exit_code == 0, res.output
    rng = np.random.default_rng(1)
    keys = ["bedroom/rgb_00001.png", "bedroom/rgb_00119.png"]
    for key in keys:
        mm = rng.uniform(300, 12000, (480, 640)).astype(np.uint16)
        mm[rng.random(mm.shape) < 0.2] = 0
        path = out / "gt" / key.replace("rgb_", "sync_depth_")
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), mm)
    pred = tmp_path / "PRED"
    for v in ("clean", "brightness/1", "contrast/1"):
        for key in keys:  # BTS's form: one 16-bit PNG per image
            p = pred / v / key
            p.parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(p), rng.uniform(100, 11000, (480, 640)).astype(np.uint16))
    one, two = _run(cli, out, pred, tmp_path, 1), _run(cli, out, pred, tmp_path, 2)
    assert one[0] == two[0] and one[1]["results"] == two[1]["results"]
    assert one[1]["protocol"] == "nyu" and len(one[1]["results"]) == 3
    # Another valid-pixel rule reaches the workers too (NYU maps are kept whole and their
    # valid pixels found again on each use).
    one, two = (_run(cli, out, pred, tmp_path, j, "--crop", "none") for j in (1, 2))
    assert one[0] == two[0] and one[1]["results"] != _run(cli, out, pred, tmp_path, 1)[1]["results"]


def test_an_error_is_the_first_one_job_meets(kitti, tmp_path, cli):
    out, good = kitti
    pred = tmp_path / "PRED"
    for v in VARIANTS:
        (pred / v).parent.mkdir(parents=True, exist_ok=True)
        a = np.load(good / f"{v}.npy")
        if v in ("brightness/3", "contrast/3"):
            a[1, 5, 5] = np.nan
        np.save(pred / f"{v}.npy", a)
    outputs = []
    for jobs in (1, 2):
        res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--jobs", jobs)
        assert res.exit_code == 2
        assert res.stderr.count("\n") == 1
        outputs.append(res.stderr)
    assert outputs[0] == outputs[1]
    assert "brightness/3.npy: prediction 1 contains NaN" in outputs[0]
    assert not (tmp_path / "r.csv").exists()


def test_jobs_flag_checked(kitti, tmp_path, cli):
    out, pred = kitti
    res = cli("evaluate", out, "--pred", pred, "--jobs", "0", "--out", tmp_path / "r.csv")
    assert res.exit_code == 2 and "--jobs" in res.output and "0" in res.output


def test_ground_truth_shared_through_a_file_comes_back_equal(tmp_path):
    from robodepth_cli.evaluation.protocols import kitti_valid
    from robodepth_cli.groundtruth.read import GroundTruth

    rng = np.random.default_rng(2)
    gt = GroundTruth("mem", "kitti", kitti_valid)
    sparse = rng.uniform(1, 90, (375, 1242)).astype(np.float32)
    sparse[rng.random(sparse.shape) > 0.05] = 0
    gt.add(sparse)  # kept as its valid pixels
    dense_mm = rng.uniform(500, 9000, (48, 64)).astype(np.uint16)
    gt.add(dense_mm.astype(np.float32) / 1000, dense_mm, 1000.0)  # kept as the raw map
    back = gt.share(tmp_path / "gt.bin").open()
    assert len(back) == 2
    for i in range(2):
        (s1, i1, v1), (s2, i2, v2) = gt.get(i), back.get(i)
        assert s1 == s2 and i1.dtype == i2.dtype and v1.dtype == v2.dtype
        assert np.array_equal(i1, i2) and np.array_equal(v1, v2)
