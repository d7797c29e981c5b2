"""`robodepth evaluate` at full size: images per second and peak memory.

Synthetic data of the real sizes: KITTI, 697 ground-truth maps of 375 x 1242 with ~5% of
the pixels set (as lidar leaves them) in a gt_depths.npz, and N x 192 x 640 float32
disparities per variant; NYU, 654 16-bit 480 x 640 ground-truth PNGs and N x 480 x 640
depths per variant. The dataset directory is a minimal one (build.json + manifest.csv), so
no image is built. Peak memory is the evaluating process's peak resident set size.

    python bench/evaluate.py [--variants 3] [--images 697] [--protocol kitti|nyu|both]
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robodepth_cli.output import manifest  # noqa: E402
from robodepth_cli.api import open_dataset  # noqa: E402
from robodepth_cli.evaluation.evaluate import evaluate  # noqa: E402
from robodepth_cli.evaluation.protocols import make_setup  # noqa: E402


def fake_dataset(root: Path, name: str, keys: list[str], variants: list[tuple[str, int | None]]):
    root.mkdir(parents=True)
    record = {"dataset": name, "split": {"keys": keys}, "config": {"size": [192, 640]}}
    (root / "build.json").write_text(json.dumps(record))
    rows = [manifest.Row(f"{v}/{lv}/{k}" if lv else f"{v}/{k}", k, v, lv, 0, 1, 1, "0" * 64)
            for v, lv in variants for k in keys]
    (root / "manifest.csv").write_text(manifest.HEADER + manifest.format_rows(rows))


def rss_mb() -> float:
    """Peak resident set size of this process (VmHWM: unlike ru_maxrss, not inherited
    from the parent across exec)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def make_kitti(tmp: Path, n: int, n_variants: int) -> None:
    rng = np.random.default_rng(0)
    keys = [f"kitti_data/d/image_02/data/{i:010d}.png" for i in range(n)]
    variants = [("clean", None)] + [("brightness", lv) for lv in range(1, n_variants)]
    ds_dir = tmp / "KITTI_C"
    fake_dataset(ds_dir, "kitti-c", keys, variants)
    gts = np.empty(n, object)
    for i in range(n):
        g = rng.uniform(2, 85, (375, 1242)).astype(np.float32)
        g[rng.random(g.shape) > 0.05] = 0
        gts[i] = g
    np.savez_compressed(ds_dir / "gt_depths.npz", data=gts)
    del gts
    pred = tmp / "PRED"
    for v, lv in variants:
        path = pred / (f"{v}/{lv}.npy" if lv else f"{v}.npy")
        path.parent.mkdir(parents=True, exist_ok=True)
        arr = np.lib.format.open_memmap(path, "w+", np.float32, (n, 192, 640))
        for i in range(n):
            arr[i] = rng.uniform(0.01, 0.3, (192, 640))
        del arr


def make_nyu(tmp: Path, n: int, n_variants: int) -> None:
    import cv2

    rng = np.random.default_rng(0)
    keys = [f"scene/rgb_{i:05d}.png" for i in range(n)]
    variants = [("clean", None)] + [("brightness", lv) for lv in range(1, n_variants)]
    ds_dir = tmp / "NYU_C"
    fake_dataset(ds_dir, "nyudepth2-c", keys, variants)
    for i in range(n):
        path = ds_dir / "gt" / f"scene/sync_depth_{i:05d}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), rng.integers(0, 10000, (480, 640)).astype(np.uint16))
    pred = tmp / "PRED_NYU"
    for v, lv in variants:
        path = pred / (f"{v}/{lv}.npy" if lv else f"{v}.npy")
        path.parent.mkdir(parents=True, exist_ok=True)
        arr = np.lib.format.open_memmap(path, "w+", np.float32, (n, 480, 640))
        for i in range(n):
            arr[i] = rng.uniform(0.5, 9, (480, 640))
        del arr


def measure(tmp: Path, protocol: str) -> None:
    """Evaluate in a fresh process, so its peak RSS is the evaluation's alone."""
    ds_dir, pred = (tmp / "KITTI_C", tmp / "PRED") if protocol == "kitti" else (tmp / "NYU_C", tmp / "PRED_NYU")
    t0 = time.perf_counter()
    res = evaluate(open_dataset(ds_dir), pred, make_setup(protocol))
    dt = time.perf_counter() - t0
    n, images = res.images, res.images * len(res.results)
    print(f"{protocol}: {images} images ({len(res.results)} variants x {n}) in {dt:.1f} s: "
          f"{images / dt:.0f} images/s, {1000 * dt / images:.2f} ms each; "
          f"peak RSS {rss_mb():.0f} MB", flush=True)


def main() -> int:
    import subprocess

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=3, help="variants per dataset (clean + N-1)")
    ap.add_argument("--images", type=int, default=0, help="images per variant (default: the real split)")
    ap.add_argument("--protocol", choices=["kitti", "nyu", "both"], default="both")
    ap.add_argument("--_make", help=argparse.SUPPRESS)
    ap.add_argument("--_measure", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._make:
        proto, tmp = args.protocol, Path(args._make)
        (make_kitti if proto == "kitti" else make_nyu)(tmp, args.images or (697 if proto == "kitti" else 654),
                                                         args.variants)
        return 0
    if args._measure:
        measure(Path(args._measure), args.protocol)
        return 0
    protocols = ["kitti", "nyu"] if args.protocol == "both" else [args.protocol]
    with tempfile.TemporaryDirectory(prefix="robodepth-bench-eval-") as tmp:
        for proto in protocols:
            common = [sys.executable, __file__, "--protocol", proto, "--variants", str(args.variants),
                      "--images", str(args.images)]
            subprocess.run(common + ["--_make", tmp], check=True)
            subprocess.run(common + ["--_measure", tmp], check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
