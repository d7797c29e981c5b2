"""Benchmark: ``robodepth gt kitti`` on the 697 Eigen test frames, speed and memory.

A temporary KITTI-raw tree holds, for every line of the Eigen test split (the copy in
tests/data/splits), a synthetic velodyne scan of realistic size (``--points``, default
120,000 points: 64 rings of an HDL-64E-like sensor, ground and walls at 2..80 m), and for
each of its five dates calibration files: the real 2011_09_26 files, and for the other dates
the same files with that date's image size (1224x370, 1238x374, 1226x370, 1241x376) and a
shifted principal point. Scans are written once and read back from the page cache, as on a
machine that has just unpacked KITTI.

Then ``python -m robodepth_cli.cli gt kitti`` runs as a user runs it (a fresh interpreter);
its wall time, CPU time and peak RSS (``wait4``) are printed with the size of the npz. On a
busy machine the CPU time is the better guide to what an idle one takes (the export runs on
one core). Goal (issue 12): the 697 frames in under a minute, memory one frame plus the
output maps (~1.3 GB).

For the ratio, the per-frame time of the depth rule alone is measured in this process, ours
against the plain formulation (a Python loop over duplicate pixel groups, as the reference
script does it) on the first ``--compare`` frames, interleaved, best of 3 rounds; the maps
are checked equal on the way.

It runs with ``--jobs 1`` and then ``--jobs 2`` (the ratio is printed).

    python -m bench.gt [--frames N] [--points N] [--compare N] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

from tests.helpers.paths import FIXTURES, SPLITS  # tests/data, inside the repository

CALIB = FIXTURES / "kitti_raw" / "2011_09_26"
EIGEN = SPLITS / "eigen_test_files.txt"
SIZES = {"2011_09_26": (1242, 375), "2011_09_28": (1224, 370), "2011_09_29": (1238, 374),
         "2011_09_30": (1226, 370), "2011_10_03": (1241, 376)}


def write_calibration(root: Path) -> None:
    for k, (date, (w, h)) in enumerate(SIZES.items()):
        (root / date).mkdir(parents=True, exist_ok=True)
        shutil.copy(CALIB / "calib_velo_to_cam.txt", root / date / "calib_velo_to_cam.txt")
        lines = []
        for line in (CALIB / "calib_cam_to_cam.txt").read_text().splitlines():
            key, value = line.split(":", 1)
            if key == "S_rect_02":
                line = f"S_rect_02: {w:e} {h:e}"
            elif key == "P_rect_02":
                p = [float(x) for x in value.split()]
                p[2] -= 4 * k  # another principal point per date
                line = "P_rect_02: " + " ".join(f"{x:e}" for x in p)
            lines.append(line)
        (root / date / "calib_cam_to_cam.txt").write_text("\n".join(lines) + "\n")


def velodyne_scan(rng: np.random.Generator, n: int) -> np.ndarray:
    """An HDL-64E-like scan: 64 rings from +2 to -24.8 degrees, full turn of azimuth; the
    lower rings hit the ground (sensor 1.73 m up), the others walls at 5..80 m."""
    rings = 64
    per_ring = n // rings
    el = np.repeat(np.radians(np.linspace(2, -24.8, rings)), per_ring)
    az = np.tile(np.linspace(-np.pi, np.pi, per_ring, endpoint=False), rings)
    az = az + rng.normal(0, 1e-3, az.size)
    wall = np.repeat(rng.uniform(5, 80, 360), per_ring * rings // 360 + 1)[: az.size]
    ground = np.where(el < -0.02, 1.73 / np.sin(-np.minimum(el, -0.02)), np.inf)
    r = np.minimum(wall, ground) * rng.uniform(0.98, 1.02, az.size)
    pts = np.stack([r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el),
                    rng.uniform(0, 1, az.size)], axis=1)
    return pts.astype(np.float32)


def write_tree(root: Path, lines: list[str], points: int) -> None:
    write_calibration(root)
    rng = np.random.default_rng(0)
    bases = [velodyne_scan(rng, points) for _ in range(8)]
    for i, line in enumerate(lines):
        folder, frame, _ = line.split()
        path = root / folder / "velodyne_points" / "data" / f"{int(frame):010d}.bin"
        path.parent.mkdir(parents=True, exist_ok=True)
        scan = bases[i % len(bases)].copy()
        scan[:, :3] += rng.normal(0, 0.02, (len(scan), 3)).astype(np.float32)
        scan.tofile(path)


def plain_depth(calib, velo: np.ndarray) -> np.ndarray:
    """The depth rule as the reference script runs it: a Python loop over duplicate groups."""
    h, w = calib.shape
    velo = velo[velo[:, 0] >= 0, :]
    im = np.dot(calib.projection, velo.T).T
    with np.errstate(divide="ignore", invalid="ignore"):
        im[:, :2] = im[:, :2] / im[:, 2][..., np.newaxis]
    im[:, 2] = velo[:, 0]
    im[:, 0] = np.round(im[:, 0]) - 1
    im[:, 1] = np.round(im[:, 1]) - 1
    ok = (im[:, 0] >= 0) & (im[:, 1] >= 0) & (im[:, 0] < w) & (im[:, 1] < h)
    im = im[ok, :]
    depth = np.zeros((h, w))
    depth[im[:, 1].astype(int), im[:, 0].astype(int)] = im[:, 2]
    index = im[:, 1] * (w - 1) + im[:, 0] - 1
    for value in [v for v, c in Counter(index).items() if c > 1]:
        members = np.where(index == value)[0]
        depth[int(im[members[0], 1]), int(im[members[0], 0])] = im[members, 2].min()
    depth[depth < 0] = 0
    return depth.astype(np.float32)


def run_cli(root: Path, split: Path, out: Path, jobs: int = 1) -> tuple[float, float, float]:
    """Wall seconds, CPU seconds (user + system, its workers included) and peak RSS (MB:
    the largest of the process and its workers) of one ``robodepth gt kitti --jobs N``."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "robodepth_cli.cli", "gt", "kitti", "--root", str(root),
                             "--split", str(split), "--out", str(out), "--no-progress", "--jobs", str(jobs)],
                            env=env, stderr=subprocess.PIPE, text=True)
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"gt kitti failed ({proc.returncode}): {err}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def compare(root: Path, lines: list[str], n: int) -> tuple[float, float]:
    """Best-of-3 per-frame seconds of the depth rule: ours, the plain loop."""
    from robodepth_cli.groundtruth.kitti import Calibration, depth_map, load_velodyne

    work = []
    for line in lines[:n]:
        folder, frame, _ = line.split()
        date = folder.split("/")[0]
        work.append((Calibration.load(root / date),
                     load_velodyne(root / folder / "velodyne_points" / "data" / f"{int(frame):010d}.bin")))
    from threadpoolctl import threadpool_limits

    best = {"ours": np.inf, "plain": np.inf}
    limit = threadpool_limits(1, user_api="blas")  # as the export runs (one BLAS thread)
    for _ in range(3):
        for name, fn in (("ours", depth_map), ("plain", plain_depth)):
            t0 = time.perf_counter()
            maps = [fn(c, v) for c, v in work]
            best[name] = min(best[name], (time.perf_counter() - t0) / len(work))
            if name == "ours":
                ours = maps
        for a, b in zip(ours, maps):
            assert np.array_equal(a.view(np.uint32), b.view(np.uint32)), "maps differ"
    limit.restore_original_limits()
    return best["ours"], best["plain"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=697, help="first N lines of the Eigen split")
    ap.add_argument("--points", type=int, default=120_000, help="points per scan")
    ap.add_argument("--compare", type=int, default=30, help="frames for the ours/plain ratio")
    ap.add_argument("--keep", type=Path, help="build the tree here and keep it")
    args = ap.parse_args()

    lines = [ln for ln in EIGEN.read_text().splitlines() if ln.strip()][: args.frames]
    tmp = Path(tempfile.mkdtemp(prefix="robodepth-bench-gt-")) if args.keep is None else args.keep
    try:
        root, split, out = tmp / "kitti_raw", tmp / "split.txt", tmp / "gt_depths.npz"
        split.write_text("\n".join(lines) + "\n")
        t0 = time.perf_counter()
        write_tree(root, lines, args.points)
        print(f"tree: {len(lines)} scans of {args.points} points ({args.points * 16 / 1e6:.2f} MB each) "
              f"written in {time.perf_counter() - t0:.1f} s")
        maps_mb = sum(SIZES[ln.split("/")[0]][0] * SIZES[ln.split("/")[0]][1] * 4 for ln in lines) / 2**20
        walls = {}
        for jobs in (1, 2):  # the previous way (one process) and workers, in the same run
            wall, cpu, rss = walls[jobs] = run_cli(root, split, out, jobs)
            print(f"robodepth gt kitti --jobs {jobs}: {len(lines)} frames in {wall:.1f} s "
                  f"({wall / len(lines) * 1000:.1f} ms/frame, interpreter and imports included), CPU "
                  f"{cpu:.1f} s; peak RSS {rss:.0f} MB (the maps alone: {maps_mb:.0f} MB); npz "
                  f"{out.stat().st_size / 2**20:.1f} MB; load {os.getloadavg()[0]:.1f}", flush=True)
        print(f"--jobs 2 against --jobs 1: {walls[1][0] / walls[2][0]:.2f}x wall time")
        ours, plain = compare(root, lines, min(args.compare, len(lines)))
        print(f"depth rule per frame (best of 3, {min(args.compare, len(lines))} frames): ours {ours * 1000:.1f} ms, "
              f"plain loop {plain * 1000:.1f} ms: {plain / ours:.1f}x; maps identical")
        print(f"load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())} (2 cores)")
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
