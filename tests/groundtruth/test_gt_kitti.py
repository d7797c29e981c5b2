"""`robodepth gt kitti` against a plain reference written here from the rules: the real KITTI
calibration of 2011_09_26 (plus a second date with another image size) and synthetic
velodyne scans that reach every branch of the projection and of the duplicate rule."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from tests.helpers.gt_trees import DATE1, DATE2, aim, projection, write_tree
from tests.helpers.messages import one_line_error


# --- the reference, step by step as the rules say it -------------------------------------------

def ref_calib(path):
    data = {}
    for line in open(path).read().splitlines():
        key, value = line.split(":", 1)
        try:
            data[key] = np.array([float(x) for x in value.strip().split(" ")])
        except ValueError:
            data[key] = value.strip()
    return data


def ref_depth(root, folder, frame):
    date = folder.split("/")[0]
    cam2cam = ref_calib(root / date / "calib_cam_to_cam.txt")
    velo2cam = ref_calib(root / date / "calib_velo_to_cam.txt")
    velo2cam = np.hstack((velo2cam["R"].reshape(3, 3), velo2cam["T"][..., np.newaxis]))
    velo2cam = np.vstack((velo2cam, np.array([0, 0, 0, 1.0])))
    height, width = cam2cam["S_rect_02"][::-1].astype(np.int32)
    rect = np.eye(4)
    rect[:3, :3] = cam2cam["R_rect_00"].reshape(3, 3)
    proj = np.dot(np.dot(cam2cam["P_rect_02"].reshape(3, 4), rect), velo2cam)

    velo = np.fromfile(root / folder / "velodyne_points" / "data" / f"{frame:010d}.bin", dtype=np.float32)
    velo = velo.reshape(-1, 4)
    velo[:, 3] = 1.0
    velo = velo[velo[:, 0] >= 0, :]
    im = np.dot(proj, velo.T).T
    with np.errstate(divide="ignore", invalid="ignore"):
        im[:, :2] = im[:, :2] / im[:, 2][..., np.newaxis]
    im[:, 2] = velo[:, 0]
    im[:, 0] = np.round(im[:, 0]) - 1
    im[:, 1] = np.round(im[:, 1]) - 1
    ok = (im[:, 0] >= 0) & (im[:, 1] >= 0) & (im[:, 0] < width) & (im[:, 1] < height)
    im = im[ok, :]

    depth = np.zeros((height, width))
    for x, y, d in im:  # one point after the other: the last one on a pixel stays
        depth[int(y), int(x)] = d
    index = im[:, 1] * (width - 1) + im[:, 0] - 1
    for value, count in Counter(index).items():
        if count > 1:
            members = np.where(index == value)[0]
            depth[int(im[members[0], 1]), int(im[members[0], 0])] = im[members, 2].min()
    depth[depth < 0] = 0
    return depth.astype(np.float32), im, index


@pytest.fixture
def run(cli):
    """``robodepth gt kitti ARGS...``"""
    return lambda *args: cli("gt", "kitti", *args)


@pytest.fixture
def kitti(tmp_path, fixtures_dir):
    return write_tree(tmp_path, fixtures_dir)


def test_export_equals_reference(kitti, tmp_path, run):
    root, split_file, lines = kitti
    out = tmp_path / "gt" / "gt_depths.npz"
    res = run("--root", root, "--split", split_file, "--out", out)
    assert res.exit_code == 0, res.output
    # As monodepth2's evaluate_depth.py loads it.
    data = np.load(out, fix_imports=True, encoding="latin1", allow_pickle=True)["data"]
    assert data.dtype == object and data.shape == (len(lines),)
    shapes = set()
    seen = Counter()
    for got, line in zip(data, lines):
        folder, frame, _ = line.split()
        want, im, index = ref_depth(root, folder, int(frame))
        assert got.dtype == np.float32 and got.shape == want.shape
        assert np.array_equal(got.view(np.uint32), want.view(np.uint32)), line  # bit for bit
        shapes.add(got.shape)
        # The scan reached every branch of the rules (else this test proves little).
        w = want.shape[1]
        counts = Counter(index)
        groups = [np.where(index == value)[0] for value, c in counts.items() if c > 1]
        seen["shared pixel"] += sum(len({(im[i, 1], im[i, 0]) for i in g}) == 1 for g in groups)
        seen["merged rows"] += sum(len({(im[i, 1], im[i, 0]) for i in g}) == 2 for g in groups)
        last = {}
        for x, y, d in im:
            last[int(y), int(x)] = d
        seen["min is not the last"] += sum(im[g, 2].min() != last[int(im[g[0], 1]), int(im[g[0], 0])]
                                           for g in groups)
        seen["first column"] += int((im[:, 0] == 0).sum())
        seen["last column"] += int((im[:, 0] == w - 1).sum())
        seen["behind the camera"] += int(((im[:, 2] < 1) & (im[:, 2] >= 0)).sum())
    assert shapes == {(375, 1242), (370, 1226), (376, 1241)}
    exact = data[-1]  # EXACT_POINTS, worked out by hand
    assert exact[3, 1] == 1 and exact[5, 3] == 1 and exact[1, 3] == 3  # ties round to even
    assert exact[2, 2] == 0 and exact[375, 1240] == 1 and exact[9, 1240] == 2
    assert np.count_nonzero(exact) == 5
    assert exact[19, 19] == 0 and np.signbit(exact[19, 19])
    assert all(seen[k] > 0 for k in ("shared pixel", "merged rows", "min is not the last", "first column",
                                     "last column")), seen


def test_depth_map_drops_points_outside(tmp_path, fixtures_dir):
    """Points behind the sensor or outside the image leave no trace; one in the frame does."""
    from robodepth_cli.groundtruth.kitti import Calibration, depth_map

    calib = Calibration.load(fixtures_dir / "kitti_raw" / DATE1)
    proj, (h, w) = projection(fixtures_dir / "kitti_raw", DATE1)
    outside = aim(proj, [0.4, w + 0.6, w / 2, w / 2], [h / 2, h / 2, 0.4, h + 0.6], 10.0)
    outside[:, 3] = 1  # as load_velodyne leaves it
    behind = np.array([[-10, 0, 0, 1], [-1, 2, 0, 1]], dtype=np.float32)
    assert not depth_map(calib, np.concatenate([outside, behind])).any()
    inside = aim(proj, [1, w], [1, h], [7.0, 9.0])  # the top-left and bottom-right pixels
    inside[:, 3] = 1
    got = depth_map(calib, inside)
    assert got[0, 0] == 7.0 and got[h - 1, w - 1] == 9.0 and np.count_nonzero(got) == 2


@pytest.mark.parametrize("edit, needles", [
    (lambda t: t.replace("R_rect_00:", "R_rect_0:"), ("calib_cam_to_cam.txt", "'R_rect_00'")),
    (lambda t: t.replace("S_rect_02: 1.242000e+03 ", "S_rect_02: "), ("calib_cam_to_cam.txt", "'S_rect_02'", "1 values")),
    (lambda t: t.replace("P_rect_02: 7.215377e+02", "P_rect_02: 7.2x"), ("calib_cam_to_cam.txt", "'P_rect_02'")),
    (lambda t: t + "no colon here\n", ("calib_cam_to_cam.txt:", "KEY: values")),
])
def test_bad_calibration(kitti, tmp_path, edit, needles, run):
    root, split_file, _ = kitti
    path = root / DATE1 / "calib_cam_to_cam.txt"
    path.write_text(edit(path.read_text()))
    out = tmp_path / "gt_depths.npz"
    one_line_error(run("--root", root, "--split", split_file, "--out", out), str(split_file) + ":1:", *needles)
    assert not out.exists() and not list(tmp_path.glob(".gt_depths.npz*"))


def test_bad_velodyne_calibration(kitti, tmp_path, run):
    root, split_file, _ = kitti
    path = root / DATE2 / "calib_velo_to_cam.txt"
    path.write_text(path.read_text().replace("T: -4.069766e-03 ", "T: "))
    one_line_error(run("--root", root, "--split", split_file, "--out", tmp_path / "o.npz"),
          "calib_velo_to_cam.txt", "'T' has 2 values, expected 3", ":3:")
    path.unlink()
    one_line_error(run("--root", root, "--split", split_file, "--out", tmp_path / "o.npz"),
          "calib_velo_to_cam.txt: no such calibration file")


def test_missing_and_truncated_scans(kitti, tmp_path, run):
    root, split_file, lines = kitti
    folder, frame, _ = lines[3].split()
    scan_file = root / folder / "velodyne_points" / "data" / f"{frame}.bin"
    data = scan_file.read_bytes()
    scan_file.write_bytes(data[:-5])
    out = tmp_path / "o.npz"
    one_line_error(run("--root", root, "--split", split_file, "--out", out), f"{split_file}:4:", str(scan_file),
          f"{len(data) - 5} bytes", "16")
    scan_file.unlink()
    one_line_error(run("--root", root, "--split", split_file, "--out", out), f"{split_file}:4:", str(scan_file),
          "no such velodyne file")
    assert not out.exists()


def test_bad_arguments(kitti, tmp_path, run):
    root, split_file, _ = kitti
    one_line_error(run("--root", root, "--split", "nyu_test", "--out", tmp_path / "o.npz"), "nyu_test", "eigen")
    one_line_error(run("--root", tmp_path / "nowhere", "--split", split_file, "--out", tmp_path / "o.npz"), "--root")
    one_line_error(run("--root", root, "--split", split_file, "--out", tmp_path), "--out", "is a directory")


def test_split_with_a_byte_order_mark_gives_the_same_maps(kitti, tmp_path, run):
    """A split saved with a UTF-8 byte-order mark (as Windows editors do) names the same
    first frame: the mark is not part of its folder."""
    root, split_file, lines = kitti
    marked = tmp_path / "marked.txt"
    marked.write_bytes(b"\xef\xbb\xbf" + split_file.read_bytes())
    assert run("--root", root, "--split", split_file, "--out", tmp_path / "plain.npz").exit_code == 0
    res = run("--root", root, "--split", marked, "--out", tmp_path / "marked.npz")
    assert res.exit_code == 0, res.output
    plain = np.load(tmp_path / "plain.npz", allow_pickle=True)["data"]
    got = np.load(tmp_path / "marked.npz", allow_pickle=True)["data"]
    assert len(got) == len(lines) and all(np.array_equal(a, b) for a, b in zip(plain, got))


def test_jobs_give_the_same_file_and_errors(kitti, tmp_path, run, monkeypatch):
    from robodepth_cli.groundtruth import kitti as kitti_raw

    root, split_file, lines = kitti
    monkeypatch.setattr(kitti_raw, "FRAMES_PER_TASK", 2)  # several tasks even for a few frames
    pools, real = [], kitti_raw._depth_maps_in_workers
    monkeypatch.setattr(kitti_raw, "_depth_maps_in_workers", lambda *a: pools.append(a[-1]) or real(*a))
    assert run("--root", root, "--split", split_file, "--out", tmp_path / "one.npz", "--jobs", "1").exit_code == 0
    res = run("--root", root, "--split", split_file, "--out", tmp_path / "two.npz", "--jobs", "2")
    assert res.exit_code == 0, res.output
    assert pools == [2] and len(lines) > 2 * kitti_raw.FRAMES_PER_TASK
    one = np.load(tmp_path / "one.npz", allow_pickle=True)["data"]
    two = np.load(tmp_path / "two.npz", allow_pickle=True)["data"]
    assert len(one) == len(two) == len(lines)
    assert all(np.array_equal(a.view(np.uint32), b.view(np.uint32)) for a, b in zip(one, two))
    assert (tmp_path / "one.npz").read_bytes() == (tmp_path / "two.npz").read_bytes()
    # A truncated scan late in the split: the message of one job, no file.
    folder, frame, _ = lines[-2].split()
    scan_file = root / folder / "velodyne_points" / "data" / f"{frame}.bin"
    scan_file.write_bytes(scan_file.read_bytes()[:-3])
    messages = []
    for jobs in ("1", "2"):
        res = run("--root", root, "--split", split_file, "--out", tmp_path / f"bad{jobs}.npz", "--jobs", jobs)
        assert res.exit_code == 2 and not (tmp_path / f"bad{jobs}.npz").exists()
        messages.append(res.output)
    assert messages[0] == messages[1] and f"{split_file}:{len(lines) - 1}:" in messages[0]
