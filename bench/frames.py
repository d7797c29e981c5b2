"""Benchmark: what ``build kitti-c --frames -1,1`` costs against a plain build, in time and
disk, and what the corruptions over time add.

A temporary KITTI drive of 3N consecutive frames (the fixture frames copied in turn) whose
split lists every third frame (1, 4, 7, ...), so each of the N test frames has two
neighbours of its own, is built at 192 x 640 with ``--jobs 2``, each build a fresh
``python -m robodepth_cli.cli build`` as a user runs it:

- plain: the 18 corruptions x 5 levels and the clean image (91 PNGs per test frame);
- frames: the same with ``--frames -1,1`` (3 x 91 PNGs per test frame);
- over time: ``--frames -1,1`` and the 5 corruptions over time x 5 levels alone (each of the
  3 frames of a sequence encodes its whole sequence once per corruption and level).

Printed: wall time, CPU time of the build's process tree, bytes written, and the ratios of
frames to plain (3 is the number of images; more means the neighbours cost more per image).
Other processes slow the wall times: the load average is printed.

    python -m bench.frames [--sources N] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from pathlib import Path

from bench.build import measure  # the process-tree sampler of the build benchmark
from tests.helpers import trees as _trees  # the test suite's tree builders
from tests.helpers.paths import FIXTURES

REPO = Path(__file__).resolve().parents[1]
KITTI_FRAMES = FIXTURES / "kitti_raw" / "2011_09_26" / "2011_09_26_drive_0002_sync" / "image_02" / "data"
OVER_TIME = "frame_lost,frame_freeze,h264_crf,h265_crf,bit_error"


def drive(root: Path, n: int) -> Path:
    """3n consecutive frames; a split of frames 1, 4, 7, ..."""
    copies = sorted(KITTI_FRAMES.glob("*.png"))
    split = _trees.kitti_tree(root, [(k, "l", ".png") for k in range(3 * n)], copies_of=copies)
    split.write_text("".join(f"{_trees.KITTI_DRIVE} {k:010d} l\n" for k in range(1, 3 * n, 3)))
    return split


def build(root: Path, split: Path, out: Path, total: int, *flags: str) -> dict:
    """bench.build's measurement of one build (its process tree sampled) writing ``total``
    PNGs."""
    cmd = [sys.executable, "-m", "robodepth_cli.cli", "build", "kitti-c", "--root", str(root),
           "--split", str(split), "--out", str(out), "--jobs", "2", "--no-progress", "--no-gt", *flags]
    return measure(cmd, out, total, out.parent / f"{out.name}.log")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=6, help="test frames (default 6)")
    ap.add_argument("--keep", type=Path, help="keep the trees and outputs here")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="robodepth-bench-frames-")) if args.keep is None else args.keep
    try:
        root = tmp / "raw"
        split = drive(root, args.sources)
        load = os.getloadavg()
        print(f"{args.sources} test frames at 192 x 640, --jobs 2 (load average {load[0]:.1f})")
        n = args.sources
        runs = {
            "plain": build(root, split, tmp / "plain", n * 91),
            "frames -1,1": build(root, split, tmp / "frames", 3 * n * 91, "--frames", "-1,1"),
            "over time": build(root, split, tmp / "time", 3 * n * 26, "--frames", "-1,1",
                               "--corruptions", OVER_TIME),
        }
        for name, m in runs.items():
            print(f"  {name:<12} {m['wall']:7.1f} s wall {m['cpu']:7.1f} s CPU {m['bytes'] / 1e6:8.1f} MB"
                  f" {m['pss'] / 2 ** 30:5.2f} GB peak PSS ({m['cpu'] / n:.2f} s CPU and "
                  f"{m['bytes'] / 1e6 / n:.2f} MB per test frame)")
        p, f = runs["plain"], runs["frames -1,1"]
        print(f"  frames / plain: {f['wall'] / p['wall']:.2f}x wall, {f['cpu'] / p['cpu']:.2f}x CPU, "
              f"{f['bytes'] / p['bytes']:.2f}x disk (3 images per test frame instead of 1)")
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
