"""Benchmark: ``robodepth stats`` per image and variant, its SSIM (OpenCV's box filter)
against scikit-image's ``structural_similarity`` (the straightforward way), on one core.

A 375 x 1242 KITTI frame of the fixtures and its fog at level 3: the best of a few rounds
of each (the least disturbed by other processes), their ratio, the whole per-variant step
(histogram, squared differences, SSIM), the CPU time that gives for a whole KITTI-C (697
images x 90 variants), and the two SSIMs compared.

    python -m bench.pixels [--repeats N]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from bench import cpu_name  # noqa: E402
from tests.helpers.paths import FIXTURES  # noqa: E402

FRAME = FIXTURES / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


def best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    from skimage.metrics import structural_similarity

    from robodepth_cli.corruptions import corrupt
    from robodepth_cli.report import pixels as X

    clean = cv2.cvtColor(cv2.imread(str(FRAME)), cv2.COLOR_BGR2RGB)
    fog = np.asarray(corrupt(clean, "fog", 3, rng=np.random.default_rng(0)))
    ours = best(lambda: X.ssim(clean, fog), args.repeats)
    theirs = best(lambda: structural_similarity(clean, fog, channel_axis=2, data_range=255), args.repeats)
    step = best(lambda: X.Sums().add(fog, clean), args.repeats)
    diff = abs(X.ssim(clean, fog) - structural_similarity(clean, fog, channel_axis=2, data_range=255))
    load = os.getloadavg()[0]
    print(f"CPU: {cpu_name()}, load {load:.1f}; {clean.shape[1]}x{clean.shape[0]}, one core")
    print(f"SSIM: ours {ours * 1e3:.0f} ms, scikit-image {theirs * 1e3:.0f} ms ({theirs / ours:.1f}x); "
          f"|difference| {diff:.1e}")
    print(f"stats per image and variant: {step * 1e3:.0f} ms; a whole KITTI-C (697 x 90): "
          f"{step * 697 * 90 / 3600:.1f} h CPU")


if __name__ == "__main__":
    main()
