"""Benchmark: writing a build's PNGs, ``--png fast`` (fpng) against ``--png compact``
(libpng, the encoder before) and Pillow's defaults (what the straightforward loop of
bench/build.py writes with), on one core.

The images are what a KITTI-C build writes for one frame: the clean 192 x 640 image and
its 90 corruptions (18 x 5). Each encoder encodes all 91 a few times; the best round counts
(the least disturbed by other processes). Printed: time and size per image, the ratios
against the two older ways measured in this run, and the CPU time for the whole of
KITTI-C's 63,427 images. Every encoder's output is decoded once and compared with the
input pixels.

    python -m bench.png [--repeats N]
"""

from __future__ import annotations

import os

# One core: set before numpy / OpenCV / numba are imported.
for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import io  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from tests.helpers.paths import FIXTURES  # noqa: E402
from robodepth_cli.corruptions import NAMES, corrupt  # noqa: E402
from robodepth_cli.imageio import encode_png, load_clean  # noqa: E402
from robodepth_cli.seeding import job_rng  # noqa: E402

FRAME = FIXTURES / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"
KITTI_C_IMAGES = 697 * 91
GOAL_SPEEDUP = 5.0  # fast against compact, CPU per image


def pillow_default(img: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")
    return buf.getvalue()


def images() -> list[np.ndarray]:
    clean = load_clean(FRAME, (192, 640))
    return [clean] + [corrupt(clean, name, lv, job_rng(0, "kitti-c", name, lv, FRAME.name))
                      for name in NAMES for lv in range(1, 6)]


def measure(encode, imgs: list[np.ndarray], repeats: int) -> tuple[float, float]:
    """(best seconds per image, bytes per image); checks the pixels come back."""
    for img in imgs:
        back = np.asarray(Image.open(io.BytesIO(encode(img))))
        if not np.array_equal(back, img):
            sys.exit(f"{encode.__name__}: decoded pixels differ from the input")
    best = float("inf")
    for _ in range(repeats):
        t = time.process_time()
        size = sum(len(encode(img)) for img in imgs)
        best = min(best, time.process_time() - t)
    return best / len(imgs), size / len(imgs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    imgs = images()
    load = os.getloadavg()
    print(f"{len(imgs)} images of 192 x 640 (one KITTI-C frame), one core, best of {args.repeats}; "
          f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")

    def fast(img):
        return encode_png(img, method="fast")

    def compact(img):
        return encode_png(img, method="compact")

    results = {name: measure(fn, imgs, args.repeats)
               for name, fn in (("fast (fpng)", fast), ("compact (libpng, before)", compact),
                                ("Pillow defaults (the plain loop)", pillow_default))}
    f_s, f_b = results["fast (fpng)"]
    for name, (s, b) in results.items():
        print(f"  {name:34s} {1000 * s:6.2f} ms CPU/image  {b / 1024:6.1f} KiB/image  "
              f"fast is {s / f_s:4.1f}x faster, {f_b / b:4.2f}x the size; "
              f"KITTI-C's {KITTI_C_IMAGES:,} images: {s * KITTI_C_IMAGES:5.0f} s CPU, "
              f"{b * KITTI_C_IMAGES / 1024 ** 3:4.1f} GiB")
    speedup = results["compact (libpng, before)"][0] / f_s
    print(f"goal: fast >= {GOAL_SPEEDUP:.0f}x less CPU than compact: {speedup:.1f}x -> "
          f"{'met' if speedup >= GOAL_SPEEDUP else 'NOT met'}")
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
