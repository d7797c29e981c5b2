"""Benchmark: the codec corruptions' CPU-independent encoder settings against the CPU's own
SIMD code, side by side in one process.

libx264 runs in its ``cpu-independent`` mode and libx265 with ``asm=none`` so that a stream
does not depend on the instruction set (robodepth_cli/corruptions/codec.py). Each round
encodes a 3-frame sequence (a blurred random texture shifted 4 pixels a frame) at 192 x 640,
480 x 640 and 376 x 1242 at CRF 23 both ways, alternating; printed is the median CPU time
per sequence and the ratio. The goal is at most 10 % more CPU.

    python -m bench.codec [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import cv2
import numpy as np

from bench import cpu_name
from robodepth_cli.corruptions import codec

SIZES = ((192, 640), (480, 640), (376, 1242))
CPU_DEPENDENT = {  # the settings without the CPU-independent options
    "X264_PARAMS": codec.X264_PARAMS.replace(":cpu-independent=1", ""),
    "X265_PARAMS": codec.X265_PARAMS.replace(":asm=none", ""),
}
BUDGET = 1.10


def sequence(h: int, w: int) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    base = cv2.GaussianBlur(rng.integers(0, 256, (h, w + 8, 3), dtype=np.uint8), (9, 9), 3)
    return [np.ascontiguousarray(base[:, 4 * i:4 * i + w]) for i in range(3)]


def cpu_seconds(frames: list[np.ndarray], name: str, params: dict[str, str]) -> float:
    saved = {k: getattr(codec, k) for k in params}
    for k, v in params.items():
        setattr(codec, k, v)
    try:
        t = time.process_time()
        codec.encode(frames, name, 23)
        return time.process_time() - t
    finally:
        for k, v in saved.items():
            setattr(codec, k, v)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    print(f"CPU: {cpu_name()}; load average {os.getloadavg()[0]:.2f}; median of {args.repeats} CPU times per 3-frame sequence, CRF 23")
    worst = 0.0
    for name in ("h264", "h265"):
        codec.encode(sequence(*SIZES[0]), name, 23)  # untimed: the first encode loads the library
        for h, w in SIZES:
            frames = sequence(h, w)
            ours, theirs = [], []
            for _ in range(args.repeats):
                theirs.append(cpu_seconds(frames, name, CPU_DEPENDENT))
                ours.append(cpu_seconds(frames, name, {}))
            ratio = statistics.median(ours) / statistics.median(theirs)
            worst = max(worst, ratio)
            print(f"  {name} {h:4d} x {w:4d}: CPU-independent {statistics.median(ours) * 1e3:6.1f} ms, "
                  f"CPU's SIMD {statistics.median(theirs) * 1e3:6.1f} ms, ratio {ratio:.2f}")
    print(f"worst ratio {worst:.2f} (goal at most {BUDGET:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
