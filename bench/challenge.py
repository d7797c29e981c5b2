"""`robodepth challenge score` on a Track-1 submission against the official evaluator.

Synthetic data of the real sizes: N ground-truth maps of 375 x 1242 with ~7% of the pixels
set (as lidar leaves them) and an N x 192 x 640 float32 disparity array (the official
``disp.npy``), ``--unique`` distinct maps of each repeated (the work per image does not
depend on the values). Both run on one core (thread limits set before numpy is imported),
in this process, on the same arrays:

- the official evaluator's loop (``competition/evaluator_npy.py`` of the RoboDepth toolkit,
  written out in tests/helpers/challenge.py: scikit-image's ``resize`` per map, masks of
  the whole map), given the disparities loaded with ``np.load`` and the ground truth in
  memory, as it holds them (its loading is not timed);
- robodepth: the submission opened from ``disp.npy`` and, separately, from a deflated
  ``disp.zip`` holding it, each map read from the stream, its ground truth from the
  reference's deflated ``gt.npz``, as ``challenge build`` writes it (timed), resized only at the valid pixels.

Prints both times, the ratio, the largest difference of the seven numbers, and robodepth's
peak traced memory (tracemalloc, a second run) with the size of one map and of the whole array beside it.

    python -m bench.challenge [--images 500] [--unique 20]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
import zipfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from bench import cpu_name  # noqa: E402
from robodepth_cli.challenge.layout import gt_members  # noqa: E402
from robodepth_cli.challenge.npzfile import write_npz  # noqa: E402
from robodepth_cli.challenge.scoring import open_reference, score  # noqa: E402
from robodepth_cli.challenge.submission import open_submission  # noqa: E402
from tests.helpers.challenge import official_evaluate, write_reference  # noqa: E402
from tests.helpers.evaluation import fake_disp, lidar_gt  # noqa: E402

METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3")


def _score(submission: Path, ref):
    with open_submission(str(submission), ref.ids, 10 ** 10) as sub:
        return score(sub, ref)


def ours(submission: Path, ref) -> tuple[float, np.ndarray, float]:
    """Seconds, the seven numbers and the peak traced memory (MB) of robodepth's scoring:
    timed untraced, then run again under tracemalloc (which slows allocations) for memory."""
    t0 = time.perf_counter()
    s = _score(submission, ref)
    seconds = time.perf_counter() - t0
    tracemalloc.start()
    _score(submission, ref)
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    flat = s.flat()
    return seconds, np.array([flat[m] for m in METRICS]), peak


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--images", type=int, default=500)
    ap.add_argument("--unique", type=int, default=20)
    args = ap.parse_args(argv)
    n = args.images
    load = os.getloadavg()
    print(f"CPU: {cpu_name()}; load average {load[0]:.2f}; {n} images, one core")
    gts_u = [lidar_gt((375, 1242) if k % 2 else (370, 1226), k) for k in range(args.unique)]
    disps_u = [fake_disp((192, 640), k, 0.1) for k in range(args.unique)]
    gts = [gts_u[k % args.unique] for k in range(n)]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        ids = [f"{k:010x}" for k in range(n)]
        folder = write_reference(tmp / "ref", ids, gts, corruptions=["fog", "dark"] * (n // 2) + ["fog"] * (n % 2))
        with open(folder / "gt.npz", "wb") as fh:  # as challenge build writes it
            write_npz(fh, (m for i, g in zip(ids, gts) for m in gt_members(i, g)))
        ref = open_reference(str(folder))
        disps = np.lib.format.open_memmap(tmp / "disp.npy", "w+", np.float32, (n, 192, 640))
        for k in range(n):
            disps[k] = disps_u[k % args.unique]
        disps.flush()
        del disps
        with zipfile.ZipFile(tmp / "disp.zip", "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            zf.write(tmp / "disp.npy", "disp.npy")

        t0 = time.perf_counter()
        want = official_evaluate(np.load(tmp / "disp.npy"), gts)
        official = time.perf_counter() - t0
        t_npy, got_npy, peak_npy = ours(tmp / "disp.npy", ref)
        t_zip, got_zip, peak_zip = ours(tmp / "disp.zip", ref)
    diff = max(np.abs(got_npy - want).max(), np.abs(got_zip - want).max())
    print(f"official evaluator (skimage resize loop): {official:7.2f} s  ({official / n * 1e3:.1f} ms/image)")
    print(f"robodepth, disp.npy:                      {t_npy:7.2f} s  ({t_npy / n * 1e3:.1f} ms/image)  "
          f"{official / t_npy:.1f}x")
    print(f"robodepth, disp.zip (deflated):           {t_zip:7.2f} s  ({t_zip / n * 1e3:.1f} ms/image)  "
          f"{official / t_zip:.1f}x")
    print(f"largest difference of the seven numbers: {diff:.2e}")
    print(f"robodepth peak traced memory: {peak_npy:.1f} MB (npy), {peak_zip:.1f} MB (zip); one "
          f"disparity map {192 * 640 * 4 / 1e6:.2f} MB, one ground-truth map {375 * 1242 * 4 / 1e6:.2f} MB, "
          f"the whole array {n * 192 * 640 * 4 / 1e6:.0f} MB")
    return 0 if diff < 1e-6 else 1


if __name__ == "__main__":
    sys.exit(main())
