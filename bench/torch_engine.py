"""Benchmark: the torch engine against the numpy engine, per corruption, in images per
second, on two KITTI frames resized to 192 x 640 and 480 x 640 (level 3 by default).

- numpy engine: one image at a time, as a build worker runs it, over ``--numpy-images``
  images (its rate does not depend on a batch size: it has none);
- torch engine on the CPU: batches of 1 and 64 (``--batches``), after a warm-up call;
- torch engine on CUDA, the same batches, when torch sees a GPU; otherwise the table says
  "not measured".

Both CPU engines get ``--threads`` threads (default 1: a build runs one worker per core).
Every image draws from its own generator, as in a build.

    python -m bench.torch_engine [--only NAME,NAME] [--sizes 192x640,480x640] [--batches 1,64]
        [--level 3] [--numpy-images 8] [--threads 1]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

_THREADS = "1"
for _i, _a in enumerate(sys.argv):  # thread limits must be set before numpy/OpenCV load
    if _a == "--threads" and _i + 1 < len(sys.argv):
        _THREADS = sys.argv[_i + 1]
for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = _THREADS

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from robodepth_cli.corruptions import NAMES, corrupt, torch_engine  # noqa: E402
from robodepth_cli.imageio import read_rgb, resize_lanczos  # noqa: E402
from tests.helpers.paths import FIXTURES  # noqa: E402


def frames(size: tuple[int, int]) -> list[np.ndarray]:
    paths = sorted((FIXTURES / "kitti_raw").rglob("image_02/data/*.png"))
    return [resize_lanczos(read_rgb(p), size) for p in paths]


def rngs(n: int) -> list[np.random.Generator]:
    return [np.random.default_rng(i) for i in range(n)]


def numpy_rate(images, name, level, n) -> float:
    corrupt(images[0], name, level, np.random.default_rng(99))  # warm-up: numba, tables
    t = time.perf_counter()
    for i, rng in enumerate(rngs(n)):
        corrupt(images[i % len(images)], name, level, rng)
    return n / (time.perf_counter() - t)


def torch_rate(images, name, level, batch: int, device: torch.device) -> float:
    x = torch_engine.to_batch([images[i % len(images)] for i in range(batch)], device)
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
    torch_engine.corrupt_batch(x[:1], name, level, rngs(1))  # warm-up: tables, kernels
    sync()
    t = time.perf_counter()
    torch_engine.corrupt_batch(x, name, level, rngs(batch))
    sync()
    return batch / (time.perf_counter() - t)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated corruption names")
    ap.add_argument("--sizes", default="192x640,480x640")
    ap.add_argument("--batches", default="1,64")
    ap.add_argument("--level", type=float, default=3)
    ap.add_argument("--numpy-images", type=int, default=8)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args(argv)
    names = [n for n in args.only.split(",") if n] or list(NAMES)
    unknown = sorted(set(names) - set(NAMES))
    if unknown:
        ap.error(f"unknown corruption(s): {', '.join(unknown)}")
    level = int(args.level) if args.level == int(args.level) else args.level
    batches = [int(b) for b in args.batches.split(",")]
    cv2.setNumThreads(args.threads)
    torch.set_num_threads(args.threads)
    cuda = torch.device("cuda") if torch.cuda.is_available() else None
    for text in args.sizes.split(","):
        size = tuple(int(v) for v in text.split("x"))
        images = frames(size)
        print(f"images/s at {size[0]}x{size[1]}, level {level}, {args.threads} CPU thread(s); "
              f"numpy engine over {args.numpy_images} images; torch engine per batch size")
        cols = [f"torch cpu b{b}" for b in batches] + [f"cuda b{b}" for b in batches]
        print(f"{'corruption':<18} {'numpy':>8} " + " ".join(f"{c:>13}" for c in cols)
              + f" {'cpu b' + str(batches[-1]) + '/numpy':>15}")
        for name in names:
            base = numpy_rate(images, name, level, args.numpy_images)
            cpu = [torch_rate(images, name, level, b, torch.device("cpu")) for b in batches]
            gpu = [torch_rate(images, name, level, b, cuda) for b in batches] if cuda else []
            shown = [f"{r:13.1f}" for r in cpu] + ([f"{r:13.1f}" for r in gpu] if gpu
                                                   else [f"{'not measured':>13}"] * len(batches))
            print(f"{name:<18} {base:8.1f} " + " ".join(shown) + f" {cpu[-1] / base:14.2f}x", flush=True)
        if cuda is None:
            print("cuda: not measured (torch sees no CUDA GPU on this machine)")
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
