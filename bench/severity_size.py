"""Benchmark: the severity size at a large size. An ETH3D-sized frame (4032 x 6048) at
level 5 of every corruption whose parameters the severity size scales, with
``--severity-size none`` (the parameters as tabulated) and with 192x640 (scaled by about
14x), side by side in one process on one core.

Goal (issue 37): each scaled one within 3x the time of none (long kernels split or boxed:
corruptions/_large.py). The depth-aware ones only with --depth (minutes at this size).

    python -m bench.severity_size [--names defocus_blur,motion_blur] [--depth] [--size 4032x6048]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from robodepth_cli.corruptions import REGISTRY, corrupt  # noqa: E402

REFERENCE = (192, 640)
GOAL = 3.0


def frame(size: tuple[int, int]) -> np.ndarray:
    """A photograph (scikit-image's astronaut) resized to ``size``."""
    from skimage import data

    return cv2.resize(data.astronaut(), (size[1], size[0]), interpolation=cv2.INTER_CUBIC)


def timed(x, name, depth, severity_size) -> float:
    t = time.perf_counter()
    corrupt(x, name, 5, np.random.default_rng(0), depth, severity_size=severity_size)
    return time.perf_counter() - t


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--names", help="comma-separated corruptions (default: every scaled one without depth)")
    p.add_argument("--depth", action="store_true", help="also the depth-aware ones (slow at this size)")
    p.add_argument("--size", default="4032x6048")
    args = p.parse_args(argv)
    size = tuple(int(v) for v in args.size.split("x"))
    names = (args.names.split(",") if args.names else
             [n for n, c in REGISTRY.items() if c.scaled and (args.depth or not c.needs_depth)])
    x = frame(size)
    depth = np.linspace(2.0, 80.0, size[0], dtype=np.float32)[:, None].repeat(size[1], axis=1)
    small = cv2.resize(x, (REFERENCE[1], REFERENCE[0]), interpolation=cv2.INTER_AREA)
    worst = 0.0
    print(f"{size[0]}x{size[1]}, level 5, severity size {REFERENCE[0]}x{REFERENCE[1]} "
          f"(s = {np.sqrt(size[0] * size[1] / (REFERENCE[0] * REFERENCE[1])):.1f}) against none; one core")
    for name in names:
        # Warm-up at the small size: numba compilation and per-size tables are not what is measured.
        timed(small, name, depth[:REFERENCE[0], :REFERENCE[1]], None)
        plain = timed(x, name, depth, None)
        scaled = timed(x, name, depth, REFERENCE)
        worst = max(worst, scaled / plain)
        print(f"  {name:18s} none {plain:6.2f} s   scaled {scaled:6.2f} s   x{scaled / plain:4.2f}", flush=True)
    print(f"worst ratio x{worst:.2f} (goal: under x{GOAL:.0f})")
    return 0 if worst < GOAL else 1


if __name__ == "__main__":
    sys.exit(main())
