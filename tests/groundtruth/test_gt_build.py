"""A built dataset carries its ground truth: KITTI's gt_depths.npz from the velodyne scans,
NYU's gt/<scene>/sync_depth_N.png; both in the manifest (variant gt), checked by verify,
skipped on resume, left out with --no-gt. NYUDepth2-C builds from the official labeled file
give the same dataset as a build from BTS's extracted test folder."""

from __future__ import annotations


import numpy as np
import pytest
from PIL import Image

from tests.helpers.gt_trees import DATE2, SCENES, bts_files, write_labeled, write_split, write_tree
from tests.helpers.manifest import manifest_by_output
from tests.helpers.trees import random_image, save, tree

KITTI_FLAGS = ("--corruptions", "brightness", "--levels", "1", "--size", "32x96", "--jobs", "1")
NYU_FLAGS = ("--corruptions", "brightness,gaussian_noise", "--levels", "1", "--jobs", "1")


@pytest.fixture
def kitti(tmp_path, fixtures_dir):
    """Velodyne scans and calibration for three dates (tests/helpers/gt_trees.py), plus the images."""
    root, split, lines = write_tree(tmp_path, fixtures_dir, frames_per_drive=1)
    for i, line in enumerate(lines):
        folder, frame, side = line.split()
        cam = {"l": "image_02", "r": "image_03"}[side]
        save(root / folder / cam / "data" / f"{frame}.png", random_image(40, 120, seed=i))
    return root, split, lines


def test_a_limited_look_into_a_finished_build_keeps_its_extent(kitti, tmp_path, build_kitti):
    """A `--limit 1` rerun into a complete build neither shrinks the ground truth to one map
    nor the split order that evaluation and the Python API read from the record."""
    from robodepth_cli import open_dataset

    root, split, lines = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *KITTI_FLAGS).exit_code == 0
    stamp = (out / "gt_depths.npz").stat().st_mtime_ns
    res = build_kitti(root, split, out, *KITTI_FLAGS, "--limit", "1")
    assert res.exit_code == 0 and "0 written" in res.output, res.output
    assert (out / "gt_depths.npz").stat().st_mtime_ns == stamp
    assert len(np.load(out / "gt_depths.npz", allow_pickle=True)["data"]) == len(lines)
    ds = open_dataset(out)
    assert len(ds.keys) == len(lines)
    assert all(len(v.images()) == len(lines) for v in ds.variants())


def test_kitti_build_writes_checks_and_resumes_gt(kitti, tmp_path, cli, build_kitti):
    root, split, lines = kitti
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *KITTI_FLAGS)
    assert res.exit_code == 0, res.output
    gt_row = manifest_by_output(out)["gt_depths.npz"]
    assert gt_row["variant"] == "gt" and not gt_row["error"]
    built = np.load(out / "gt_depths.npz", allow_pickle=True)["data"]
    assert cli("gt", "kitti", "--root", root, "--split", split, "--out", tmp_path / "alone.npz").exit_code == 0
    alone = np.load(tmp_path / "alone.npz", allow_pickle=True)["data"]
    assert len(built) == len(lines) == len(alone)
    assert all(np.array_equal(a, b) and a.any() for a, b in zip(built, alone))
    assert cli("verify", out).exit_code == 0

    stamp = (out / "gt_depths.npz").stat().st_mtime_ns
    res = build_kitti(root, split, out, *KITTI_FLAGS)
    assert res.exit_code == 0 and "0 written" in res.output, res.output
    assert (out / "gt_depths.npz").stat().st_mtime_ns == stamp

    # A changed scan makes the ground truth again (and only it).
    folder, frame, _ = lines[1].split()
    scan = root / folder / "velodyne_points" / "data" / f"{frame}.bin"
    points = np.fromfile(scan, dtype=np.float32).reshape(-1, 4)
    points[:, 0] *= 1.5
    points.tofile(scan)
    res = build_kitti(root, split, out, *KITTI_FLAGS)
    assert res.exit_code == 0 and "1 written" in res.output, res.output
    again = np.load(out / "gt_depths.npz", allow_pickle=True)["data"]
    assert np.array_equal(again[0], built[0]) and not np.array_equal(again[1], built[1])

    data = bytearray((out / "gt_depths.npz").read_bytes())
    data[len(data) // 2] ^= 1
    (out / "gt_depths.npz").write_bytes(bytes(data))
    res = cli("verify", out)
    assert res.exit_code == 1 and "changed: 1" in res.output and "gt_depths.npz" in res.output


def test_kitti_build_without_a_scan_notes_it_and_the_note_works(kitti, tmp_path, cli, build_kitti):
    """The note names the missing scan and the command that adds the ground truth, with the
    paths as typed; following it leaves a build that verify passes."""
    import shlex

    root, split, lines = kitti
    folder, frame, _ = lines[2].split()
    scan = root / folder / "velodyne_points" / "data" / f"{frame}.bin"
    kept = scan.read_bytes()
    scan.unlink()
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *KITTI_FLAGS)
    assert res.exit_code == 0, res.output
    note = [ln for ln in res.output.splitlines() if ln.startswith("note:")]
    assert len(note) == 1 and str(scan) in note[0], res.output
    assert "KITTI_RAW" not in note[0] and "SPLIT" not in note[0]
    assert not (out / "gt_depths.npz").exists()
    assert not [r for r in manifest_by_output(out).values() if r["variant"] == "gt"]
    assert len(manifest_by_output(out)) == 2 * len(lines)  # the images are all there

    command = shlex.split(note[0].rsplit(": ", 1)[1])
    assert command[:2] == ["robodepth", "build"] and str(root) in command and str(out) in command
    scan.write_bytes(kept)
    res = cli(*command[1:])
    assert res.exit_code == 0, res.output
    assert "1 written" in res.output and (out / "gt_depths.npz").is_file()
    assert cli("verify", out).exit_code == 0


def test_kitti_build_with_bad_calibration_fails_only_gt(kitti, tmp_path, build_kitti):
    root, split, lines = kitti
    calib = root / DATE2 / "calib_cam_to_cam.txt"
    calib.write_text(calib.read_text().replace("P_rect_02:", "P_rect_2:"))
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *KITTI_FLAGS)
    assert res.exit_code == 1, res.output
    manifest = manifest_by_output(out)
    assert "P_rect_02" in manifest["gt_depths.npz"]["error"] and str(calib) in manifest["gt_depths.npz"]["error"]
    assert not (out / "gt_depths.npz").exists()
    assert all(not r["error"] for k, r in manifest.items() if k != "gt_depths.npz")


def test_no_gt(kitti, tmp_path, build_kitti):
    root, split, _ = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *KITTI_FLAGS, "--no-gt").exit_code == 0
    assert not (out / "gt_depths.npz").exists() and "gt_depths.npz" not in manifest_by_output(out)


def test_nyu_build_from_labeled_file_equals_build_from_bts_folder(tmp_path, cli):
    mat = tmp_path / "nyu_depth_v2_labeled.mat"
    rgb, depth = write_labeled(mat)
    indices = [0, 1, 3, 4]
    split = write_split(tmp_path / "split.txt", indices)
    bts = tmp_path / "bts"
    for i in indices:
        bts_files(rgb[i], depth[i], bts, i, SCENES[i])

    from_mat, from_bts = tmp_path / "from_mat", tmp_path / "from_bts"
    for root, out in ((mat, from_mat), (bts, from_bts)):
        res = cli("build", "nyudepth2-c", "--root", root, "--split", split, "--out", out, *NYU_FLAGS)
        assert res.exit_code == 0, res.output
    a, b = tree(from_mat), tree(from_bts)
    assert set(a) == set(b)
    gt = sorted(p for p in a if p.startswith("gt/"))
    assert gt == sorted(f"gt/{SCENES[i]}/sync_depth_{i:05d}.png" for i in indices)
    for path in a:
        if path.startswith("gt/"):  # BTS's own sync_depth file, and ours from the .mat
            got = np.asarray(Image.open(from_mat / path))
            assert np.array_equal(got, np.asarray(Image.open(bts / path[3:]))), path
            assert b[path] == (bts / path[3:]).read_bytes()  # copied as it is
        else:  # the clean images and their corruptions: the same pixels, so the same PNG bytes
            assert a[path] == b[path], path
    manifest = manifest_by_output(from_mat)
    assert {manifest[p]["variant"] for p in gt} == {"gt"}
    assert manifest["clean/living_room/rgb_00003.png"]["source"] == "nyu_depth_v2_labeled.mat#3"
    assert cli("verify", from_mat).exit_code == 0

    res = cli("build", "nyudepth2-c", "--root", mat, "--split", split, "--out", from_mat, *NYU_FLAGS)
    assert res.exit_code == 0 and "0 written" in res.output, res.output


def test_nyu_build_line_of_another_scene_fails_that_image(tmp_path, cli):
    mat = tmp_path / "labeled.mat"
    write_labeled(mat)
    split = tmp_path / "split.txt"
    split.write_text("bathroom/rgb_00000.jpg bathroom/sync_depth_00000.png 518.8579\n"
                     "bathroom/rgb_00001.jpg bathroom/sync_depth_00001.png 518.8579\n")
    out = tmp_path / "out"
    res = cli("build", "nyudepth2-c", "--root", mat, "--split", split, "--out", out, *NYU_FLAGS)
    assert res.exit_code == 1, res.output
    assert f"{split}:2:" in res.output and "'kitchen'" in res.output
    manifest = manifest_by_output(out)
    assert not manifest["clean/bathroom/rgb_00000.png"]["error"]
    assert "'kitchen'" in manifest["clean/bathroom/rgb_00001.png"]["error"]
    assert not manifest["gt/bathroom/sync_depth_00000.png"]["error"]
    assert "'kitchen'" in manifest["gt/bathroom/sync_depth_00001.png"]["error"]


def test_nyu_build_root_file_not_hdf5(tmp_path, cli):
    mat = tmp_path / "labeled.mat"
    mat.write_bytes(b"not a mat file")
    split = write_split(tmp_path / "split.txt", [0])
    res = cli("build", "nyudepth2-c", "--root", mat, "--split", split, "--out", tmp_path / "out", *NYU_FLAGS)
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [res.output.strip()] and "not an HDF5 file" in res.output
    assert not (tmp_path / "out").exists()


def test_kitti_split_line_of_a_frame_not_there_says_the_image_failed(kitti, tmp_path, build_kitti):
    """A line for a frame the drive does not have (issue 42): the note says the image failed
    and why no gt_depths.npz (one map per split line) is made, never that the images are
    built and putting the scans in place would do."""
    root, split, lines = kitti
    folder = lines[0].split()[0]
    bad = tmp_path / "with_a_wrong_line.txt"
    bad.write_text("\n".join([*lines, f"{folder} 0000000099 l"]) + "\n")
    out = tmp_path / "out"
    res = build_kitti(root, bad, out, *KITTI_FLAGS)
    assert res.exit_code == 1, res.output  # the image of the last line failed
    note = [ln for ln in res.output.splitlines() if ln.startswith("note:")]
    assert len(note) == 1, res.output
    assert note[0].startswith(f"note: no ground truth: split line {len(lines) + 1} names a frame "
                              "not in the root"), note
    assert "its image failed" in note[0] and "one map per split line" in note[0], note
    assert "correct or remove that line" in note[0], note
    assert "the images are built" not in note[0] and "put the velodyne" not in note[0], note
    assert not (out / "gt_depths.npz").exists()
