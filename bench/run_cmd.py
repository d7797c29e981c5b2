"""`robodepth run` against build -> predict -> evaluate on the CPU, measured in the same run:
the wall time of each step and the disk each leaves behind.

A KITTI raw tree of N frames (the two fixture frames and their velodyne scans, copied
under new frame numbers: the speed does not depend on the pixels) and a monodepth2-format
ResNet-18 at 192 x 640 with random weights (tests/helpers/models.py writes it). Both paths
run as a user runs them, each command in a fresh interpreter, on the same corruptions and
levels (default: all of KITTI-C's, 91 variants), and their results CSVs are compared byte
for byte. The disk is what each path leaves: the build's tree with its ground truth, the
predictions and the CSV, against the CSV alone.
The machine's load average is printed before and after: on a shared machine the times
move with it.

    python -m bench.run_cmd [--sources 2] [--corruptions all] [--levels all]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

from tests.helpers.paths import FIXTURES

DRIVE = "2011_09_26/2011_09_26_drive_0002_sync"


def make_tree(root: Path, n: int) -> Path:
    """``root``: a KITTI raw tree of ``n`` frames with scans; returns its split file."""
    shutil.copytree(FIXTURES / "kitti_raw" / "2011_09_26", root / "2011_09_26",
                    ignore=shutil.ignore_patterns("*.png"))
    frames = sorted((FIXTURES / "kitti_raw" / DRIVE / "image_02" / "data").glob("*.png"))
    lines = []
    for i in range(n):
        src = frames[i % len(frames)]
        for sub, ext, base in (("image_02", ".png", FIXTURES / "kitti_raw"),
                               ("velodyne_points", ".bin", FIXTURES / "kitti_velodyne")):
            target = root / DRIVE / sub / "data" / f"{i:010d}{ext}"
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(base / DRIVE / sub / "data" / f"{src.stem}{ext}", target)
        lines.append(f"{DRIVE} {i:010d} l")
    split = root / "split.txt"
    split.write_text("\n".join(lines) + "\n")
    return split


def write_model(folder: Path) -> None:
    """The tests' random ResNet-18 monodepth2 checkpoint at 192 x 640 (tests/helpers/models.py),
    written by a child process so that this one never imports torch."""
    code = ("import sys, torch; from pathlib import Path; from tests.helpers.models import random_monodepth2; "
            "torch.manual_seed(0); random_monodepth2(Path(sys.argv[1]), 18, height=192, width=640)")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    subprocess.run([sys.executable, "-c", code, str(folder)], cwd=REPO, env=env, check=True)


def disk(path: Path) -> int:
    """Bytes in the files under ``path`` (or of the file)."""
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def timed(args: list) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "robodepth_cli.cli", *map(str, args)], cwd=REPO,
                          env={**os.environ, "PYTHONPATH": str(REPO)}, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, args[:2]))} failed:\n{proc.stderr[-2000:]}")
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=2)
    ap.add_argument("--corruptions", default="all")
    ap.add_argument("--levels", default="all")
    args = ap.parse_args()
    print(f"load before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; cpus {os.cpu_count()}",
          flush=True)
    with tempfile.TemporaryDirectory(prefix="robodepth-bench-run-") as tmp:
        tmp = Path(tmp)
        split = make_tree(tmp / "kitti_raw", args.sources)
        write_model(tmp / "model")
        model = f"monodepth2:{tmp / 'model'}"
        what = ["--split", split, "--corruptions", args.corruptions, "--levels", args.levels]
        common = ["--device", "cpu", "--no-progress"]
        steps = {
            "build": timed(["build", "kitti-c", "--root", tmp / "kitti_raw", "--out", tmp / "B",
                            *what, "--no-progress"]),
            "predict": timed(["predict", tmp / "B", "-m", model, "--out", tmp / "P", *common]),
            "evaluate": timed(["evaluate", tmp / "B", "--pred", tmp / "P", "--out", tmp / "e.csv",
                               "--no-progress"]),
        }
        three = sum(steps.values())
        ran = timed(["run", "kitti-c", "--root", tmp / "kitti_raw", "-m", model, "--out",
                     tmp / "r.csv", *what, *common])
        same = (tmp / "e.csv").read_bytes() == (tmp / "r.csv").read_bytes()
        rows = (tmp / "r.csv").read_text().count("\n") - 1
        images = rows * args.sources
        print(f"KITTI-C subset: {args.sources} sources x {rows} variants = {images} images at "
              f"192 x 640, monodepth2 ResNet-18 on the CPU")
        for name, t in steps.items():
            print(f"  {name}: {t:.1f} s")
        used = {"build": disk(tmp / "B"), "predict": disk(tmp / "P"), "evaluate": disk(tmp / "e.csv")}
        print(f"build -> predict -> evaluate: {three:.1f} s wall ({images / three:.2f} images/s), "
              f"disk {sum(used.values()) / 1e6:.1f} MB (dataset {used['build'] / 1e6:.1f} MB, "
              f"predictions {used['predict'] / 1e6:.1f} MB)")
        print(f"run: {ran:.1f} s wall ({images / ran:.2f} images/s, {three / ran:.2f}x the three "
              f"commands), disk {disk(tmp / 'r.csv') / 1e3:.1f} kB (the CSV; its state is removed "
              f"at the end)")
        print(f"results CSVs identical: {same}")
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
