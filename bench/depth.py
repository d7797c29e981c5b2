"""Benchmark: the depth-aware corruptions against the 2D corruption each extends, one core.

fog_3d against fog, near_focus and far_focus against defocus_blur, motion_3d against
motion_blur, zoom_3d against zoom_blur, rain_3d against snow: median wall time per call (after a warm-up call
that absorbs numba compilation) at every level, on a 192 x 640 KITTI-like frame with a
street's depth (a road plane seen from 1.65 m, a car-sized box at 7 m, the rest 300 m) and
a 480 x 640 NYU frame with a room's (a floor seen from 1.4 m, a back wall at 4 m, a box at
2 m). The depth-aware call includes preparing the depth (filling, clipping).

    python -m bench.depth [--repeats N] [--only NAME,NAME]
"""

from __future__ import annotations

import os

# One core: set before numpy / OpenCV / numba are imported.
for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from tests.helpers.paths import FIXTURES  # noqa: E402
from robodepth_cli.corruptions import DEPTH_NAMES, corrupt  # noqa: E402
from robodepth_cli.imageio import load_clean  # noqa: E402

EXTENDS = {"fog_3d": "fog", "near_focus": "defocus_blur", "far_focus": "defocus_blur",
           "motion_3d": "motion_blur", "zoom_3d": "zoom_blur", "rain_3d": "snow"}
KITTI = FIXTURES / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"
NYU = FIXTURES / "nyu/bedroom/rgb_00119.jpg"


def ground_plane(h: int, w: int, fy: float, height: float, horizon: float, far: float) -> np.ndarray:
    y = np.arange(h, dtype=np.float64)[:, None] + np.zeros((1, w))
    with np.errstate(divide="ignore"):
        return np.minimum(np.where(y > horizon, fy * height / (y - horizon), np.inf), far)


def frames():
    street = ground_plane(192, 640, 369.0, 1.65, 74.0, 300.0)
    street[80:160, 140:340] = 7.0
    room = ground_plane(480, 640, 519.0, 1.4, 175.0, 4.0)
    room[150:470, 40:480] = 2.0
    return [("192x640 KITTI-like", load_clean(KITTI, (192, 640)), street),
            ("480x640 NYU", load_clean(NYU, None), room)]


def median_ms(fn, repeats: int) -> float:
    fn()
    runs = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t)
    return 1000 * statistics.median(runs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed calls per level (median)")
    ap.add_argument("--only", default="", help="comma-separated depth-aware corruption names")
    args = ap.parse_args(argv)
    names = [n for n in args.only.split(",") if n] or list(DEPTH_NAMES)
    unknown = sorted(set(names) - set(DEPTH_NAMES))
    if unknown:
        ap.error(f"not depth-aware: {', '.join(unknown)}")
    cv2.setNumThreads(1)
    rng = np.random.default_rng(0)
    for label, x, depth in frames():
        print(f"ms per call on one {label} image, one core (mean over levels 1-5)")
        print(f"{'corruption':<12} {'ms':>8}   {'extends':<14} {'ms':>8} {'ratio':>7}")
        for name in names:
            ours = np.mean([median_ms(lambda: corrupt(x, name, lv, rng, depth=depth), args.repeats)
                            for lv in range(1, 6)])
            base = EXTENDS[name]
            theirs = np.mean([median_ms(lambda: corrupt(x, base, lv, rng), args.repeats) for lv in range(1, 6)])
            print(f"{name:<12} {ours:8.1f}   {base:<14} {theirs:8.1f} {ours / theirs:6.2f}x")
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
