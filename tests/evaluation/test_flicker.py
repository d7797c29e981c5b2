"""`evaluate --flicker`: temporal consistency of predictions over consecutive frames."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from robodepth_cli.evaluation.flicker import consecutive_pairs, measure

from tests.helpers.trees import kitti_drive, kitti_key

GT_SHAPE = (60, 200)


def smooth(shape, seed):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:shape[0], 0:shape[1]] / np.array(shape).reshape(2, 1, 1)
    return (8 + 30 * y + 5 * np.sin(6 * x + rng.uniform(0, 3))).astype(np.float32)


def build_with_gt(tmp_path, build_kitti, frames, gt_map, *flags):
    """A build of ``frames`` of one drive of 6 with ``gt_map`` as every frame's ground truth."""
    root = tmp_path / "raw"
    split = kitti_drive(root, range(6), frames)
    out = tmp_path / "OUT"
    res = build_kitti(root, split, out, "--size", "48x64", "--corruptions", "brightness",
                      "--levels", "1", "--jobs", "1", "--no-gt", *flags)
    assert res.exit_code == 0, res.output
    gts = np.empty(len(frames), object)
    for i in range(len(frames)):
        gts[i] = gt_map
    np.savez_compressed(out / "gt_depths.npz", data=gts)
    return out


@pytest.fixture
def sequence_build(tmp_path, build_kitti):
    """Frames 0, 1, 2, 4, 5 (pairs 0-1, 1-2, 4-5; 2-4 is no pair), the same dense ground
    truth for every frame."""
    frames = [0, 1, 2, 4, 5]
    return build_with_gt(tmp_path, build_kitti, frames, smooth(GT_SHAPE, 0)), frames


def write_preds(pred, frames, drift, base=None):
    """Depth maps ``base`` whose scale grows by ``drift`` per frame number."""
    base = smooth((48, 64), 0) if base is None else base
    maps = np.stack([base * drift ** n for n in frames]).astype(np.float32)
    for rel in ("clean", "brightness/1"):
        (pred / rel).parent.mkdir(parents=True, exist_ok=True)
        np.save(pred / f"{rel}.npy", maps)
    return maps


def rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_consecutive_pairs_follow_frame_numbers():
    keys = [kitti_key(5), kitti_key(3), kitti_key(4), kitti_key(9), "x/a_0001.png", "x/a_0002.png",
            "y/a_0003.png", "x/b_0003.png"]
    assert consecutive_pairs(keys) == [(1, 2), (2, 0), (4, 5)]


def test_measure_by_hand():
    got = measure([1.0, 2.0, 1.0], [0.1, 0.3, 0.2], [(0, 1), (1, 2)])
    assert got["flicker_scale"] == pytest.approx(1.0)  # the scale doubles, then halves
    assert got["flicker_abs_rel"] == pytest.approx(0.15)


@pytest.mark.parametrize("drift, jobs", [(1.05, 1), (0.9, 2)])
def test_a_model_drifting_in_scale_gives_that_drift(sequence_build, tmp_path, cli, drift, jobs,
                                                   monkeypatch):
    from robodepth_cli.evaluation import evaluate as E

    monkeypatch.setattr(E, "MAPS_PER_WORKER", 1)  # two variants: --jobs 2 is a pool of two
    out, frames = sequence_build
    pred = tmp_path / "PRED"
    write_preds(pred, frames, drift)
    res = cli("evaluate", out, "--pred", pred, "--kind", "depth", "--flicker", "--out",
              tmp_path / "r.csv", "--jobs", jobs, "--no-progress")
    assert res.exit_code == 0, res.output
    got = rows(tmp_path / "r.csv")
    assert list(got[0])[-4:] == ["flicker_scale", "flicker_abs_rel", "dataset", "split"]
    for r in got:
        # exp(|log drift|) - 1 per frame, whichever way the scale drifts
        assert float(r["flicker_scale"]) == pytest.approx(max(drift, 1 / drift) - 1, rel=1e-4)
        # Median scaling takes the drift out, so the error does not change between frames.
        assert float(r["flicker_abs_rel"]) < 1e-6
    assert "flicker over 3 pairs of consecutive frames" in res.output
    # the table's header: each column name apart (flicker_abs_rel is wider than a number)
    head = next(ln for ln in res.output.splitlines() if ln.startswith("variant"))
    assert head.split() == ["variant", *list(got[0])[2:-2], "ratio", "med", "std"]
    row = next(ln for ln in res.output.splitlines() if ln.startswith("clean"))
    assert len(row.split()) == len(head.split()) - 1  # "ratio med" is two words, one value


def test_error_change_without_alignment(tmp_path, cli, build_kitti):
    """With --align none the drift reaches the error. Ground truth 10 m everywhere and a
    prediction of 10 k^n m: abs_rel of frame n is k^n - 1, so a pair (n, n + 1) changes it
    by k^n (k - 1)."""
    frames, k = [0, 1, 2, 4, 5], 1.1
    out = build_with_gt(tmp_path, build_kitti, frames, np.full(GT_SHAPE, 10, np.float32))
    pred = tmp_path / "PRED"
    write_preds(pred, frames, k, base=np.full((48, 64), 10, np.float32))
    res = cli("evaluate", out, "--pred", pred, "--kind", "depth", "--align", "none", "--flicker",
              "--json", "--out", tmp_path / "r.csv", "--jobs", "1", "--no-progress")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["flicker_pairs"] == 3
    for r in doc["results"]:
        assert r["flicker_scale"] == pytest.approx(k - 1, rel=1e-5)
        assert r["flicker_abs_rel"] == pytest.approx((k - 1) * (1 + k + k ** 4) / 3, rel=1e-5)


def test_flicker_needs_consecutive_frames(tmp_path, cli, build_kitti):
    out = build_with_gt(tmp_path, build_kitti, [0, 2, 4], smooth(GT_SHAPE, 0))
    pred = tmp_path / "PRED"
    write_preds(pred, [0, 2, 4], 1.0)
    res = cli("evaluate", out, "--pred", pred, "--kind", "depth", "--flicker", "--out",
              tmp_path / "r.csv", "--no-progress")
    assert res.exit_code == 2
    assert "--flicker: the split has no consecutive frames" in res.output
    assert "--split kitti_sequences" in res.output  # the way to a split that has them
    assert not (tmp_path / "r.csv").exists()


def test_flicker_on_a_frames_build_says_what_it_measures_and_where_to_go(tmp_path, cli, build_kitti):
    # Neighbour frames on disk are not the split's frames: flicker is measured on these
    out = build_with_gt(tmp_path, build_kitti, [1, 3], smooth(GT_SHAPE, 0), "--frames", "-1,1")
    pred = tmp_path / "PRED"
    write_preds(pred, [1, 3], 1.0)
    res = cli("evaluate", out, "--pred", pred, "--kind", "depth", "--flicker", "--out",
              tmp_path / "r.csv", "--no-progress")
    assert res.exit_code == 2 and res.output.count("\n") == 1, res.output
    assert "neighbour frames (--frames -1,1) are not evaluated" in res.output
    assert "--split kitti_sequences" in res.output


def test_score_reports_the_flicker_beside_the_scores(tmp_path, cli):
    from robodepth_cli.benchmark_facts import get_benchmark

    bench = get_benchmark("kitti-c")
    lines = ["corruption,level,abs_rel,a1,flicker_scale,flicker_abs_rel", "clean,0,0.1,0.9,0.02,0.001"]
    lines += [f"{c},{lv},0.2,0.8,0.05,0.004" for c in bench.corruptions for lv in bench.levels]
    results = tmp_path / "r.csv"
    results.write_text("\n".join(lines) + "\n")
    res = cli("score", results)
    assert res.exit_code == 0, res.output
    assert "flicker (consecutive frames)" in res.output
    assert "clean                            0.0200    0.0010" in res.output
    doc = json.loads(cli("score", results, "--json").stdout)
    assert doc["flicker"][0] == {"corruption": "clean", "level": "0", "flicker_scale": 0.02,
                                 "flicker_abs_rel": 0.001}
    assert len(doc["flicker"]) == 1 + len(bench.corruptions) * len(bench.levels)
    plain = tmp_path / "plain.csv"
    plain.write_text("\n".join(line.rsplit(",", 2)[0] for line in lines) + "\n")
    assert "flicker (consecutive frames)" not in cli("score", plain).output
