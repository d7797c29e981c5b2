"""`robodepth predict` on CPU: a ResNet-18 monodepth2 model at 192 x 640, images per second.

A minimal dataset (build.json + manifest.csv: tests/helpers/builds.py's minimal_build) of N
KITTI-sized 375 x 1242 PNGs (the fixture frames, shifted so no two are alike), and a
monodepth2-format checkpoint with random weights (the speed does not depend on them).
Measured the same run: `robodepth_cli.models.predict.predict` at --batch-size 1 and the
default 8, against the hand-written loop a user would otherwise write (one image at a
time: open, forward, and `save_predictions` at the end of the variant). The machine's load
(os.getloadavg) is printed before and after: on a shared machine the numbers move with it.

    python -m bench.predict [--images 24] [--rounds 2] [--threads N]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

from tests.helpers.builds import minimal_build


def make(tmp: Path, n: int) -> tuple[Path, Path]:
    import torch
    from PIL import Image

    from tests.test_predict import random_monodepth2  # the tests' random checkpoint writer

    frames = sorted((HERE.parent / "tests/data/fixtures/kitti_raw").rglob("image_02/data/*.png"))
    keys = [f"kitti_data/d/image_02/data/{i:010d}.png" for i in range(n)]
    ds = tmp / "KITTI_C"
    minimal_build(ds, "kitti-c", keys, [("clean", None)])
    for i, key in enumerate(keys):
        img = np.asarray(Image.open(frames[i % len(frames)]).convert("RGB").resize((1242, 375)))
        path = ds / "clean" / key
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(np.roll(img, 7 * i, axis=1)).save(path, compress_level=1)
    torch.manual_seed(0)
    random_monodepth2(tmp / "mono_640x192", 18, height=192, width=640)
    return ds, tmp / "mono_640x192"


def hand_loop(ds, model_dir: Path, pred: Path) -> None:
    """The loop the README showed before `robodepth predict`: one image at a time."""
    from PIL import Image

    from robodepth_cli.models import load_model

    model = load_model(f"monodepth2:{model_dir}", device="cpu")
    for variant in ds.variants():
        disps = [model.predict(np.asarray(Image.open(p).convert("RGB"))[None])[0]
                 for p in variant.images()]
        variant.save_predictions(pred, disps)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=24)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--threads", type=int, default=0, help="torch threads (default: torch's)")
    args = ap.parse_args()
    import torch

    from robodepth_cli.api import open_dataset
    from robodepth_cli.models import load_model
    from robodepth_cli.models.predict import predict

    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"load before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; cpus {os.cpu_count()}, "
          f"torch {torch.__version__} threads {torch.get_num_threads()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="robodepth-bench-predict-") as tmp:
        tmp = Path(tmp)
        ds_dir, model_dir = make(tmp, args.images)
        ds = open_dataset(ds_dir)
        n = len(ds.keys)
        runs = {"hand-written loop, 1 image per forward": None,
                "robodepth predict --batch-size 1": 1, "robodepth predict --batch-size 8": 8}
        best = {name: (float("inf"), float("inf")) for name in runs}
        # Interleaved rounds, best of each: the machine's load moves between runs.
        for r in range(args.rounds):
            for name, bs in runs.items():
                out = tmp / f"P{r}_{bs}"
                t0, c0 = time.perf_counter(), time.process_time()
                if bs is None:
                    hand_loop(ds, model_dir, out)
                else:
                    model = load_model(f"monodepth2:{model_dir}", device="cpu")
                    predict(ds, model, out, ds.variants(), batch_size=bs)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                best[name] = (min(best[name][0], wall), min(best[name][1], cpu))
        diff = np.abs(np.load(tmp / "P0_None/clean.npy") - np.load(tmp / "P0_8/clean.npy")).max()
        base = best["hand-written loop, 1 image per forward"][0]
        for name, (wall, cpu) in best.items():
            print(f"{name}: {n} images of 375 x 1242: {n / wall:.2f} images/s wall "
                  f"({1000 * wall / n:.0f} ms each, {base / wall:.2f}x the hand-written loop), "
                  f"{1000 * cpu / n:.0f} ms CPU each", flush=True)
        print(f"largest difference between the loop's maps and predict's: {diff:.2g}")
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
