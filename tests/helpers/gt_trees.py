"""Generated inputs for the ground-truth tests: KITTI-raw trees with real calibration and
synthetic velodyne scans, and HDF5 files in the layout of NYU's official labeled file (with
what BTS's extraction script makes of them, written from its rules)."""

from __future__ import annotations

import shutil

import cv2
import h5py
import numpy as np

DATE1, DATE2, DATE3 = "2011_09_26", "2011_09_30", "2011_10_03"
DRIVE1, DRIVE2 = f"{DATE1}/{DATE1}_drive_0002_sync", f"{DATE2}/{DATE2}_drive_0016_sync"
DRIVE3 = f"{DATE3}/{DATE3}_drive_0027_sync"
# Another date's camera 2: its size and a projection that differs from 2011_09_26's.
S_RECT_2 = "1.226000e+03 3.700000e+02"
P_RECT_2 = ("7.070912e+02 0.000000e+00 6.018873e+02 4.688783e+01 0.000000e+00 7.070912e+02 "
            "1.831104e+02 1.178601e-01 0.000000e+00 0.000000e+00 1.000000e+00 6.203223e-03")

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
    c = read_calib(root / date / "calib_cam_to_cam.txt")
    v = read_calib(root / date / "calib_velo_to_cam.txt")
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



def read_calib(path):
    """``KEY: numbers`` lines as float64 arrays (other lines skipped)."""
    data = {}
    for line in open(path).read().splitlines():
        key, value = line.split(":", 1)
        try:
            data[key] = np.array([float(x) for x in value.split()])
        except ValueError:
            pass
    return data


# --- NYU ------------------------------------------------------------------------------------------

SCENES = ["bathroom", "kitchen", "bathroom", "living_room", "bedroom"]


def smooth_image(rng, h=480, w=640):
    small = rng.integers(0, 256, (h // 16, w // 16, 3), dtype=np.uint8)
    img = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    return np.clip(img.astype(int) + rng.integers(-8, 9, img.shape), 0, 255).astype(np.uint8)


def write_labeled(path, scenes=SCENES, seed=0, drop=None):
    """An HDF5 file laid out like the official labeled file (MATLAB v7.3: a 512-byte user
    block; arrays stored transposed; scene names as references to uint16 character codes).
    Returns the RGB images (N x 480 x 640 x 3) and depths (N x 480 x 640, float32)."""
    rng = np.random.default_rng(seed)
    n = len(scenes)
    rgb = np.stack([smooth_image(rng) for _ in range(n)])
    depth = rng.uniform(0, 10, (n, 480, 640)).astype(np.float32)
    depth[:, :4, :4] = np.float32(0.7)  # 700 in float32 arithmetic, 699 in float64
    depth[:, 4:8, :4] = 0
    with h5py.File(path, "w", userblock_size=512) as f:
        if drop != "images":
            f.create_dataset("images", data=rgb.transpose(0, 3, 2, 1))  # N x 3 x 640 x 480
        if drop != "rawDepths":
            f.create_dataset("rawDepths", data=depth.transpose(0, 2, 1))  # N x 640 x 480
        refs = f.create_group("#refs#")
        targets = [refs.create_dataset(f"s{i}", data=np.array([[ord(c)] for c in name], dtype=np.uint16)).ref
                   for i, name in enumerate(scenes)]
        if drop != "sceneTypes":
            st = f.create_dataset("sceneTypes", (1, n), dtype=h5py.ref_dtype)
            st[0, :] = targets
    return rgb, depth


def write_split(path, indices, scenes=SCENES):
    path.write_text("\n".join(f"{scenes[i]}/rgb_{i:05d}.jpg {scenes[i]}/sync_depth_{i:05d}.png 518.8579"
                              for i in indices))
    return path


# --- BTS's extraction, from the rules ---------------------------------------------------------

def bts_files(rgb, depth, folder, i, scene):
    """What BTS's extraction script writes for frame i, into ``folder``."""
    (folder / scene).mkdir(parents=True, exist_ok=True)
    scaled = depth * 1000.0  # float32 array times a Python float: float32
    assert scaled.dtype == np.float32
    cv2.imwrite(str(folder / scene / f"sync_depth_{i:05d}.png"), scaled.astype(np.uint16))
    bgr = rgb[:, :, ::-1]
    black = np.zeros((480, 640, 3), dtype=np.uint8)
    black[7:474, 7:632, :] = bgr[7:474, 7:632, :]
    cv2.imwrite(str(folder / scene / f"rgb_{i:05d}.jpg"), black)

