"""Write the synthetic inputs of the evaluation half of `make demo` (see README.md here):

- ``fixtures/kitti_velodyne/2011_09_26/2011_09_26_drive_0002_sync/velodyne_points/data/
  0000000054.bin`` and ``0000000069.bin``: velodyne scans (float32 N x 4: x forward,
  y left, z up, reflectance) of a made-up street, for the two fixture frames of
  ``fixtures/kitti_raw``;
- ``predictions/kitti-c/clean.npy`` and ``<corruption>/<level>.npy``: what a mono model
  might predict for that street (scaled disparities, 2 x 48 x 160 float16, split order
  0000000069 then 0000000054), worse as the corruption gets stronger.

Both come from one ray-cast scene: a road 1.73 m below the sensor, house fronts 7 m to
either side, a wall 60 m ahead, and a box (a parked car) per frame. Nothing here is KITTI
data. Deterministic: rerunning it rewrites the same bytes.

    python tests/data/make_demo_data.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DRIVE = "2011_09_26/2011_09_26_drive_0002_sync"
FRAMES = ("0000000069", "0000000054")  # the order of fixtures/kitti_split.txt
GROUND, SIDES, FAR = -1.73, 7.0, 60.0
CARS = {"0000000069": (9.0, 3.0), "0000000054": (14.0, -3.5)}  # (x, y) of each frame's box
# The fixture calibration's camera 2, near enough for a stand-in model: focal length and
# principal point of P_rect_02 on the 375 x 1242 image.
FOCAL, CX, CY, HEIGHT, WIDTH = 721.5377, 609.5593, 172.854, 375, 1242
PRED_SHAPE = (48, 160)
CORRUPTIONS = ("fog", "gaussian_noise")


def cast(dirs: np.ndarray, car: tuple[float, float]) -> np.ndarray:
    """Distance along each ray (rows of ``dirs``, from the sensor) to the first surface."""
    t = np.full(len(dirs), np.inf)
    x, y, z = dirs.T
    with np.errstate(divide="ignore", invalid="ignore"):
        for hit in (GROUND / z, SIDES / y, -SIDES / y, FAR / x):
            t = np.where((hit > 0) & (hit < t), hit, t)
        # The car: a 4 x 1.8 x 1.5 m box on the road.
        cx, cy = car
        lo = np.array([cx - 2, cy - 0.9, GROUND])
        hi = np.array([cx + 2, cy + 0.9, GROUND + 1.5])
        t1, t2 = (lo - 0) / dirs, (hi - 0) / dirs
        near = np.nanmax(np.minimum(t1, t2), axis=1)
        far = np.nanmin(np.maximum(t1, t2), axis=1)
        box = (near <= far) & (near > 0)
    return np.where(box & (near < t), near, t)


def scan(frame: str) -> np.ndarray:
    """A 32-beam sweep of the front half (the camera sees only that)."""
    el = np.radians(np.linspace(-24.8, 2.0, 32))
    az = np.radians(np.linspace(-55, 55, 220))
    e, a = np.meshgrid(el, az, indexing="ij")
    dirs = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], -1).reshape(-1, 3)
    t = cast(dirs, CARS[frame])
    keep = np.isfinite(t) & (t < 80)
    rng = np.random.default_rng(int(frame))
    pts = dirs[keep] * (t[keep] + rng.normal(0, 0.02, keep.sum()))[:, None]
    reflect = rng.uniform(0, 1, (len(pts), 1))
    return np.hstack([pts, reflect]).astype(np.float32)


def depth_image(frame: str) -> np.ndarray:
    """Forward distance at every pixel of a PRED_SHAPE view of camera 2."""
    h, w = PRED_SHAPE
    v = (np.arange(h) + 0.5) * HEIGHT / h
    u = (np.arange(w) + 0.5) * WIDTH / w
    uu, vv = np.meshgrid(u, v)
    dirs = np.stack([np.ones_like(uu), -(uu - CX) / FOCAL, -(vv - CY) / FOCAL], -1).reshape(-1, 3)
    t = cast(dirs, CARS[frame]).reshape(h, w)  # x of the direction is 1: t is the depth
    return np.minimum(t, 80.0)


def predictions(depths: list[np.ndarray], name: str, level: int) -> np.ndarray:
    """A model's scaled disparities: right up to scale and a little noise on clean images;
    fog flattens the far half of the scene, noise makes the map noisy."""
    rng = np.random.default_rng(1000 * level + len(name))
    out = []
    for d in depths:
        d = d.copy()
        if name == "fog":
            d = np.where(d > 12, 12 + (d - 12) * (1 - 0.15 * level), d)
        noise = 0.03 + (0.05 * level if name == "gaussian_noise" else 0.01 * level)
        out.append(0.1 / d * (1 + noise * rng.standard_normal(d.shape)).clip(0.5, 1.5))
    return np.stack(out).astype(np.float16)


def main() -> None:
    scans = HERE / "fixtures" / "kitti_velodyne" / DRIVE / "velodyne_points" / "data"
    scans.mkdir(parents=True, exist_ok=True)
    for frame in FRAMES:
        scan(frame).tofile(scans / f"{frame}.bin")
    preds = HERE / "predictions" / "kitti-c"
    depths = [depth_image(f) for f in FRAMES]
    (preds).mkdir(parents=True, exist_ok=True)
    np.save(preds / "clean.npy", predictions(depths, "clean", 0))
    for name in CORRUPTIONS:
        (preds / name).mkdir(exist_ok=True)
        for level in range(1, 6):
            np.save(preds / name / f"{level}.npy", predictions(depths, name, level))


if __name__ == "__main__":
    main()
