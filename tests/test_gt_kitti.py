"""`robodepth gt kitti` against a plain reference written here from the rules: the real KITTI
calibration of 2011_09_26 (plus a second date with another image size) and synthetic
velodyne scans that reach every branch of the projection and of the duplicate rule."""

from __future__ import annotations

import shutil
from collections import Counter

import numpy as np
import pytest


DATE1, DATE2, DATE3 = "2011_09_26", "2011_09_30", "2011_10_03"
DRIVE1, DRIVE2 = f"{DATE1}/{DATE1}_drive_0002_sync", f"{DATE2}/{DATE2}_drive_0016_sync"
DRIVE3 = f"{DATE3}/{DATE3}_drive_0027_sync"
# Another date's camera 2: its size and a projection that differs from 2011_09_26's.
S_RECT_2 = "1.226000e+03 3.700000e+02"
P_RECT_2 = ("7.070912e+02 0.000000e+00 6.018873e+02 4.688783e+01 0.000000e+00 7.070912e+02 "
            "1.831104e+02 1.178601e-01 0.000000e+00 0.000000e+00 1.000000e+00 6.203223e-03")


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


# A made-up date whose projection is exact in floating point: camera = (y, z, x + 1), so
# u = y / (x + 1) and v = z / (x + 1). Its points hit rounding ties (2.5 rounds to 2) and
# the x = 0 edge of the "x >= 0" rule.
EXACT_CAM = {"S_rect_02": "1.241000e+03 3.760000e+02", "R_rect_00": "1 0 0 0 1 0 0 0 1",
             "P_rect_02": "1 0 0 0 0 1 0 0 0 0 1 0"}
EXACT_VELO = "R: 0 1 0 0 0 1 1 0 0\nT: 0 0 1\n"
EXACT_POINTS = np.array([
    [1, 5, 9, 0], [1, 7, 11, 0], [3, 18, 10, 0],  # ties: u, v = (2.5, 4.5), (3.5, 5.5), (4.5, 2.5)
    [0, 3, 3, 0], [1, 6, 6, 0],  # x = 0 and x = 1 on pixel (2, 2): the minimum is 0
    [-0.0, 20, 20, 0],  # x = -0.0 is kept (and stays -0.0)
    [1, 1241 * 2, 376 * 2, 0], [2, 1241 * 3 + 1.4, 30, 0],  # the last row and column
    [2, 1241 * 3 + 1.6, 60, 0], [1, 40, 376 * 2 + 1.2, 0],  # just beyond them
], dtype=np.float32)


# --- synthetic scans ---------------------------------------------------------------------------

def projection(root, date):
    c = ref_calib(root / date / "calib_cam_to_cam.txt")
    v = ref_calib(root / date / "calib_velo_to_cam.txt")
    v2c = np.vstack((np.hstack((v["R"].reshape(3, 3), v["T"][:, None])), [0, 0, 0, 1.0]))
    rect = np.eye(4)
    rect[:3, :3] = c["R_rect_00"].reshape(3, 3)
    return c["P_rect_02"].reshape(3, 4) @ rect @ v2c, c["S_rect_02"][::-1].astype(int)


def aim(proj, col, row, x):
    """Velodyne points at forward distance ``x`` that project to image column ``col`` and
    row ``row`` (before the -1 of the pixel rule), solving the two projection equations."""
    col, row, x = np.broadcast_arrays(np.asarray(col, float), np.asarray(row, float), np.asarray(x, float))
    pts = []
    for c, r, xx in zip(col.ravel(), row.ravel(), x.ravel()):
        a = np.array([proj[0] - c * proj[2], proj[1] - r * proj[2]])  # a @ (x, y, z, 1) = 0
        yz = np.linalg.solve(a[:, 1:3], -(a[:, 0] * xx + a[:, 3]))
        pts.append([xx, yz[0], yz[1], 0.5])
    return np.array(pts, dtype=np.float32)


def scan(proj, shape, seed):
    """A scan with points of every kind, in shuffled order: a velodyne-like cloud, points
    behind the sensor, outside the image on all four sides, many on a few pixels (with
    different depths), on the last column of a row and the first of the next, and a few
    just in front of the sensor (x >= 0 but behind the camera plane)."""
    rng = np.random.default_rng(seed)
    h, w = shape
    az = rng.uniform(-np.pi, np.pi, 6000)
    el = rng.uniform(np.radians(-24.8), np.radians(2), 6000)
    r = rng.uniform(2, 80, 6000)
    cloud = np.stack([r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el),
                      rng.uniform(0, 1, 6000)], 1).astype(np.float32)
    parts = [cloud]
    # Several points on one pixel: the pixel centre plus less than half a pixel.
    for _ in range(40):
        c, rr = rng.integers(2, w - 2), rng.integers(2, h - 2)
        k = rng.integers(2, 6)
        parts.append(aim(proj, c + rng.uniform(-0.3, 0.3, k), rr + rng.uniform(-0.3, 0.3, k),
                         rng.uniform(3, 60, k)))
    # The last and first columns of consecutive rows (one group by the reference's index).
    for _ in range(30):
        rr = rng.integers(1, h - 2)
        parts.append(aim(proj, [w, 1, w, 1], [rr + 1, rr + 2, rr + 1, rr + 2], rng.uniform(3, 60, 4)))
    # Just outside every side, and on the edge rows and columns.
    parts.append(aim(proj, [0, w + 1, 0.6, w + 0.4, w / 2, w / 2, 1, w, w / 2, w / 2],
                     [h / 2, h / 2, h / 2, h / 2, 0, h + 1, h / 2, h / 2, 1, h], 20.0))
    parts.append(np.array([[-5, 1, 0, 1], [-0.0, 0.1, 0.1, 1], [0.1, 0.02, -0.3, 1], [0.2, 0.1, 0.1, 1],
                           [0, 0, 0, 1]], dtype=np.float32))
    pts = np.concatenate(parts)
    return pts[rng.permutation(len(pts))]


def write_tree(tmp_path, fixtures_dir, frames_per_drive=2):
    root = tmp_path / "kitti_raw"
    calib = fixtures_dir / "kitti_raw" / DATE1
    (root / DATE1).mkdir(parents=True)
    (root / DATE2).mkdir(parents=True)
    for name in ("calib_cam_to_cam.txt", "calib_velo_to_cam.txt"):
        shutil.copy(calib / name, root / DATE1 / name)
    shutil.copy(calib / "calib_velo_to_cam.txt", root / DATE2 / "calib_velo_to_cam.txt")
    lines = []
    for line in (calib / "calib_cam_to_cam.txt").read_text().splitlines():
        key = line.split(":", 1)[0]
        lines.append({"S_rect_02": f"S_rect_02: {S_RECT_2}", "P_rect_02": f"P_rect_02: {P_RECT_2}"}.get(key, line))
    (root / DATE2 / "calib_cam_to_cam.txt").write_text("\n".join(lines) + "\n")
    (root / DATE3).mkdir()
    (root / DATE3 / "calib_cam_to_cam.txt").write_text("".join(f"{k}: {v}\n" for k, v in EXACT_CAM.items()))
    (root / DATE3 / "calib_velo_to_cam.txt").write_text(EXACT_VELO)
    split = []
    for d, (date, drive) in enumerate(((DATE1, DRIVE1), (DATE2, DRIVE2), (DATE1, DRIVE1))):
        proj, shape = projection(root, date)
        for k in range(frames_per_drive):
            frame = 10 * d + k + 3
            path = root / drive / "velodyne_points" / "data" / f"{frame:010d}.bin"
            path.parent.mkdir(parents=True, exist_ok=True)
            scan(proj, shape, seed=frame).tofile(path)
            split.append(f"{drive} {frame:010d} {'lr'[k % 2]}")
    path = root / DRIVE3 / "velodyne_points" / "data" / f"{7:010d}.bin"
    path.parent.mkdir(parents=True)
    EXACT_POINTS.tofile(path)
    split.append(f"{DRIVE3} {7:010d} l")
    split_file = tmp_path / "split.txt"
    split_file.write_text("\n".join(split) + "\n")
    return root, split_file, split


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
    from robodepth_cli.gt_kitti import Calibration, depth_map

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


def _fail(res, *needles):
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robodepth: error: "), res.output
    for n in needles:
        assert n in lines[0], lines[0]
    assert "Traceback" not in res.output


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
    _fail(run("--root", root, "--split", split_file, "--out", out), str(split_file) + ":1:", *needles)
    assert not out.exists() and not list(tmp_path.glob(".gt_depths.npz*"))


def test_bad_velodyne_calibration(kitti, tmp_path, run):
    root, split_file, _ = kitti
    path = root / DATE2 / "calib_velo_to_cam.txt"
    path.write_text(path.read_text().replace("T: -4.069766e-03 ", "T: "))
    _fail(run("--root", root, "--split", split_file, "--out", tmp_path / "o.npz"),
          "calib_velo_to_cam.txt", "'T' has 2 values, expected 3", ":3:")
    path.unlink()
    _fail(run("--root", root, "--split", split_file, "--out", tmp_path / "o.npz"),
          "calib_velo_to_cam.txt: no such calibration file")


def test_missing_and_truncated_scans(kitti, tmp_path, run):
    root, split_file, lines = kitti
    folder, frame, _ = lines[3].split()
    scan_file = root / folder / "velodyne_points" / "data" / f"{frame}.bin"
    data = scan_file.read_bytes()
    scan_file.write_bytes(data[:-5])
    out = tmp_path / "o.npz"
    _fail(run("--root", root, "--split", split_file, "--out", out), f"{split_file}:4:", str(scan_file),
          f"{len(data) - 5} bytes", "16")
    scan_file.unlink()
    _fail(run("--root", root, "--split", split_file, "--out", out), f"{split_file}:4:", str(scan_file),
          "no such velodyne file")
    assert not out.exists()


def test_bad_arguments(kitti, tmp_path, run):
    root, split_file, _ = kitti
    _fail(run("--root", root, "--split", "nyu_test", "--out", tmp_path / "o.npz"), "nyu_test", "eigen")
    _fail(run("--root", tmp_path / "nowhere", "--split", split_file, "--out", tmp_path / "o.npz"), "--root")
    _fail(run("--root", root, "--split", split_file, "--out", tmp_path), "--out", "is a directory")
