"""The standard split of consecutive frames (``--split kitti_sequences``): made from the raw
tree by its documented rule, built with its ground truth, and giving flicker its pairs."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from robodepth_cli.evaluation.flicker import consecutive_pairs
from robodepth_cli.sources import sequences, splits

from tests.helpers.gt_trees import DATE1, DATE2, projection, scan
from tests.helpers.trees import random_image, save

D0002 = f"{DATE1}/{DATE1}_drive_0002_sync"
D0036 = f"{DATE1}/{DATE1}_drive_0036_sync"
D0016 = f"{DATE2}/{DATE2}_drive_0016_sync"


@pytest.fixture
def three_frames(monkeypatch, tmp_path):
    """The split with runs of 3 frames (20 in the shipped one), and a private split cache."""
    seq = sequences.SPLITS["kitti_sequences"]
    monkeypatch.setitem(sequences.SPLITS, "kitti_sequences", dataclasses.replace(seq, frames=3))
    monkeypatch.setenv("ROBODEPTH_CACHE_DIR", str(tmp_path / "cache"))


@pytest.fixture
def raw(tmp_path, fixtures_dir):
    """Drive 0002 with frames 0 1 3 4 5 6 (a gap at 2), drive 0036 with 0 1 only (too
    short), drive 0016 with 7 8 9; drive 0047 absent. Left images, velodyne scans and
    calibration, as KITTI raw lays them out."""
    root = tmp_path / "kitti_raw"
    for date in (DATE1, DATE2):
        (root / date).mkdir(parents=True)
        for name in ("calib_cam_to_cam.txt", "calib_velo_to_cam.txt"):
            shutil.copy(fixtures_dir / "kitti_raw" / DATE1 / name, root / date / name)
    for drive, frames in ((D0002, (0, 1, 3, 4, 5, 6)), (D0036, (0, 1)), (D0016, (7, 8, 9))):
        proj, shape = projection(root, drive.split("/")[0])
        for n in frames:
            save(root / drive / "image_02" / "data" / f"{n:010d}.png", random_image(40, 120, seed=n))
            scan_file = root / drive / "velodyne_points" / "data" / f"{n:010d}.bin"
            scan_file.parent.mkdir(parents=True, exist_ok=True)
            scan(proj, shape, seed=n).tofile(scan_file)
    return root


WANT = [f"{D0002} {n:010d} l" for n in (3, 4, 5)] + [f"{D0016} {n:010d} l" for n in (7, 8, 9)]


def test_first_run_of_consecutive_frames():
    assert sequences.first_run([0, 1, 3, 4, 5, 6], 3) == 3
    assert sequences.first_run([0, 1, 2], 3) == 0
    assert sequences.first_run([0, 1, 3, 5], 2) == 0
    assert sequences.first_run([0, 2, 4], 2) is None
    assert sequences.first_run([], 1) is None


def test_the_split_follows_the_rule(three_frames, raw, tmp_path):
    path = splits.split_path(splits.check_choice("kitti_sequences", "eigen", tmp_path), raw)
    assert path.read_text().splitlines() == WANT
    assert path.is_relative_to(tmp_path / "cache" / "splits" / "generated")
    assert splits.split_path("kitti_sequences", raw) == path  # the same tree, the same file


def test_the_shipped_drives_are_eigen_test_drives(splits_dir):
    eigen = {line.split()[0] for line in (splits_dir / "eigen_test_files.txt").read_text().splitlines()}
    seq = sequences.SPLITS["kitti_sequences"]
    assert set(seq.drives) <= eigen and len(seq.drives) == 4 and seq.frames == 20


def test_build_with_ground_truth_and_flicker_pairs(three_frames, raw, tmp_path, cli, build_kitti):
    from robodepth_cli import open_dataset

    out = tmp_path / "OUT"
    res = build_kitti(raw, "kitti_sequences", out, "--size", "32x96", "--corruptions", "brightness",
                      "--levels", "1", "--jobs", "1")
    assert res.exit_code == 0, res.output
    ds = open_dataset(out)
    keys = [f"kitti_data/{line.split()[0]}/image_02/data/{line.split()[1]}.png" for line in WANT]
    assert list(ds.keys) == keys
    # Frames 3-4, 4-5, 7-8, 8-9: the pairs `evaluate --flicker` measures.
    assert consecutive_pairs(ds.keys) == [(0, 1), (1, 2), (3, 4), (4, 5)]
    built = np.load(out / "gt_depths.npz", allow_pickle=True)["data"]
    alone = tmp_path / "alone.npz"
    res = cli("gt", "kitti", "--root", raw, "--split", "kitti_sequences", "--out", alone)
    assert res.exit_code == 0, res.output
    alone = np.load(alone, allow_pickle=True)["data"]
    assert len(built) == len(alone) == len(WANT)
    assert all(np.array_equal(a, b) and a.any() for a, b in zip(built, alone))
    assert cli("verify", out).exit_code == 0


def test_a_tree_without_the_drives_is_refused(three_frames, tmp_path, build_kitti):
    root = tmp_path / "kitti_raw"
    save(root / D0036 / "image_02" / "data" / f"{0:010d}.png", random_image(40, 120, seed=0))
    out = tmp_path / "OUT"
    res = build_kitti(root, "kitti_sequences", out, "--no-gt")
    assert res.exit_code == 2
    assert res.output.startswith("robodepth: error: ") and len(res.output.strip().splitlines()) == 1
    assert "none of the drives of the kitti_sequences split has 3 consecutive" in res.output
    assert not out.exists()


def test_nyu_refuses_the_kitti_sequences(tmp_path):
    with pytest.raises(splits.InvalidValueError, match="not a split of"):
        splits.check_choice("kitti_sequences", "nyu", tmp_path)
