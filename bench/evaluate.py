"""`robodepth evaluate` at full size: this tree against the code before its fast paths,
side by side in one run, and ``--jobs 2`` against ``--jobs 1``.

Synthetic data of the real sizes: KITTI, 697 ground-truth maps of 375 x 1242 with ~5% of
the pixels set (as lidar leaves them) in a gt_depths.npz, and N x 192 x 640 float32
disparities per variant; NYU, 654 16-bit 480 x 640 ground-truth PNGs and N x 480 x 640
depths per variant. The dataset directory is a minimal one (build.json + manifest.csv), so
no image is built. Each protocol is evaluated, each time in a fresh process, by the
reference commit's code (``--reference``, taken with ``git archive``; default the commit
before the sampled resize and the one-pass metrics) with ``--jobs 1``, then by this tree:
once with an empty ground-truth cache (the first evaluation of a ground truth, which
reads it and keeps it there), then with each ``--jobs`` value, mapping it from the cache; the ratios are printed, with the largest relative difference
between the two codes' metrics. Peak memory: the evaluating process's peak resident set
size, the largest of its workers', and the peak sums of RSS and PSS over all of them,
sampled every 0.2 s in a second, untimed evaluation (a worker's RSS counts the memory-mapped ground truth, whose pages
exist once; PSS splits them). The full-benchmark estimate is the ground truth's reading
time plus the time until each worker's first result plus the remaining maps of the
benchmark (KITTI-C 91 x 697, NYUDepth2-C 61 x 654) at the steady rate measured after those
first results (``--variants all``: the whole benchmark, timed); CPU time per map is
printed beside it (the machine is shared: wall time
moves with the load, CPU time much less). A ``--jobs 1`` run, the reference's included, is
held to one core (its affinity), so OpenCV's threads take no second one.

    python -m bench.evaluate [--variants 6|all] [--images 697] [--protocol kitti|nyu|both]
                             [--jobs 1,2] [--reference COMMIT]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tests.helpers.builds import minimal_build  # evaluate's minimal build folder

REPO = Path(__file__).resolve().parent.parent
# The commit before evaluation sampled the prediction at the valid pixels only (the
# whole map resized with cv2.resize, numpy masks and metrics).
REFERENCE = "f3c8936"


def rss_mb() -> float:
    """Peak resident set size of this process (VmHWM: unlike ru_maxrss, not inherited
    from the parent across exec)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


DISTINCT = 6  # prediction arrays written; further variants are hard links to them


def bench_variants(name: str, count: int) -> list[tuple[str, int | None]]:
    """The first ``count`` variants of the dataset ``name``: clean, then each corruption at
    each level (all of them: KITTI-C's 91, NYUDepth2-C's 61)."""
    from robodepth_cli.sources.datasets import DATASETS

    spec = DATASETS[name]
    every = [("clean", None)] + [(c, lv) for c in spec.corruptions for lv in range(1, spec.n_levels + 1)]
    if count > len(every):
        raise SystemExit(f"--variants {count}: {name} has {len(every)}")
    return every[:count]


def write_predictions(pred: Path, variants, shape, draw) -> None:
    """One N x H x W float32 array per variant (``draw()`` a map): the first :data:`DISTINCT`
    written, the others hard links to them in turn (the page cache holds those few; the
    evaluation reads every variant's file as it would). Written in 16 MiB writes, as
    ``np.save`` of a whole array and ``robodepth predict`` write: the page cache then holds
    the file in large folios, which a mapping takes in about a tenth of the time that
    the small ones of 480 KiB writes cost (4 against 37 us a 192 x 640 map, Linux 6.18)."""
    written = []
    for k, (v, lv) in enumerate(variants):
        path = pred / (f"{v}/{lv}.npy" if lv else f"{v}.npy")
        path.parent.mkdir(parents=True, exist_ok=True)
        if k >= DISTINCT:
            os.link(written[k % DISTINCT], path)
            continue
        with open(path, "wb", buffering=16 << 20) as f:
            np.lib.format.write_array_header_1_0(f, {"descr": "<f4", "fortran_order": False, "shape": shape})
            for _ in range(shape[0]):
                f.write(np.asarray(draw(), np.float32).tobytes())
        written.append(path)


def make_kitti(tmp: Path, n: int, n_variants: int) -> None:
    rng = np.random.default_rng(0)
    keys = [f"kitti_data/d/image_02/data/{i:010d}.png" for i in range(n)]
    variants = bench_variants("kitti-c", n_variants)
    ds_dir = tmp / "KITTI_C"
    minimal_build(ds_dir, "kitti-c", keys, variants)
    gts = np.empty(n, object)
    for i in range(n):
        g = rng.uniform(2, 85, (375, 1242)).astype(np.float32)
        g[rng.random(g.shape) > 0.05] = 0
        gts[i] = g
    np.savez_compressed(ds_dir / "gt_depths.npz", data=gts)
    del gts
    write_predictions(tmp / "PRED", variants, (n, 192, 640), lambda: rng.uniform(0.01, 0.3, (192, 640)))


def make_nyu(tmp: Path, n: int, n_variants: int) -> None:
    import cv2

    rng = np.random.default_rng(0)
    keys = [f"scene/rgb_{i:05d}.png" for i in range(n)]
    variants = bench_variants("nyudepth2-c", n_variants)
    ds_dir = tmp / "NYU_C"
    minimal_build(ds_dir, "nyudepth2-c", keys, variants)
    for i in range(n):
        path = ds_dir / "gt" / f"scene/sync_depth_{i:05d}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), rng.integers(0, 10000, (480, 640)).astype(np.uint16))
    write_predictions(tmp / "PRED_NYU", variants, (n, 480, 640), lambda: rng.uniform(0.5, 9, (480, 640)))


FULL_MAPS = {"kitti": 91 * 697, "nyu": 61 * 654}


def measure(tmp: Path, protocol: str, jobs: int, tag: str) -> None:
    """Evaluate in a fresh process, so its peak RSS is the evaluation's alone; the metrics
    go to ``tmp/metrics-TAG.json``; the last line printed is the full-benchmark estimate in
    seconds, for the parent."""
    import robodepth_cli
    import robodepth_cli.evaluation.evaluate as E
    from robodepth_cli.api import open_dataset
    from robodepth_cli.evaluation.protocols import make_setup

    ds_dir, pred = (tmp / "KITTI_C", tmp / "PRED") if protocol == "kitti" else (tmp / "NYU_C", tmp / "PRED_NYU")
    if jobs == 1 and hasattr(os, "sched_setaffinity"):
        # one core, as the goals are stated: else OpenCV's threads in the reference's
        # resize take a second core that --jobs 1 of this tree leaves idle
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    E.MAPS_PER_WORKER = 1  # a subset: let every job run, as on the full benchmark
    from bench.build import TreeSampler  # sums RSS and PSS over a process tree

    marks, done = [], []  # when the ground truth was read; (time, maps) as variants finish
    t0 = time.perf_counter()
    res = E.evaluate(open_dataset(ds_dir), pred, make_setup(protocol), jobs=jobs,
                     on_total=lambda n: marks.append((time.perf_counter(), time.process_time())),
                     progress=lambda k: done.append((time.perf_counter(), k, time.process_time())))
    dt = time.perf_counter() - t0
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    sampler = None
    if jobs > 1:
        # Memory over all the processes in a second evaluation, not the timed one: reading
        # their PSS walks their page tables and holds up their page faults.
        sampler = TreeSampler(os.getpid(), interval=0.2, pss_every=5)
        sampler.start()
        E.evaluate(open_dataset(ds_dir), pred, make_setup(protocol), jobs=jobs)
        sampler.stop()
    t_gt = marks[0][0] - t0  # reading the ground truth: once, whatever the number of maps
    n, images = res.images, res.images * len(res.results)
    # The first results pay for starting (workers' imports, first reads); the steady rate
    # is that of the maps finished after them. A worker reports whole variants, so "first"
    # is the first result of each worker.
    times = [t for t, _, _ in done]
    counts = np.cumsum([k for _, k, _ in done])
    first = min(jobs, len(done) - 1)
    t_first = times[first - 1] - marks[0][0]
    rate = (counts[-1] - counts[first - 1]) / (times[-1] - times[first - 1])
    # CPU per map after the first results, this process's (--jobs 1; with workers, theirs
    # in all, start-up included, as they report it when they end)
    cpu = ((done[-1][2] - done[first - 1][2]) / (counts[-1] - counts[first - 1]) if jobs == 1
           else (children.ru_utime + children.ru_stime) / images)
    full = t_gt + t_first + (FULL_MAPS[protocol] - counts[first - 1]) / rate
    if images >= FULL_MAPS[protocol]:
        full = dt  # the whole benchmark: measured, not estimated
    worker_mb = children.ru_maxrss / 1024
    # A worker's RSS counts the ground truth it maps, whose pages exist once (the page
    # cache); the PSS sum splits them between the processes that map them.
    workers = (f", largest worker {worker_mb:.0f} MB; all processes: PSS sum "
               f"{sampler.peak_pss / 2 ** 20:.0f} MB, RSS sum {sampler.peak_rss / 2 ** 20:.0f} MB"
               if jobs > 1 else "")
    load = os.getloadavg()
    where = {"reference": "reference", "new-cold": "this tree, ground truth not yet cached"}.get(
        tag, "this tree, ground truth cached")
    print(f"{protocol} {where} --jobs {jobs}: {images} maps ({len(res.results)} variants x {n}) in {dt:.1f} s "
          f"(ground truth {t_gt:.1f} s, first {counts[first - 1]} maps {t_first:.1f} s, then "
          f"{rate:.0f} maps/s, CPU {cpu * 1e3:.2f} ms per map); peak RSS {rss_mb():.0f} MB{workers}; "
          f"full benchmark ({FULL_MAPS[protocol]:,} maps) ~{full:.0f} s; load {load[0]:.1f} "
          f"[{Path(robodepth_cli.__file__).parent.parent}]", flush=True)
    (tmp / f"metrics-{tag}.json").write_text(json.dumps({r.variant.label: r.metrics for r in res.results}))
    print(f"{full:.3f} {cpu:.6f}")


def extract(commit: str, dest: Path) -> Path:
    """The package as it was at ``commit``, under ``dest`` (``git archive``)."""
    import io
    import subprocess
    import tarfile

    data = subprocess.run(["git", "-C", str(REPO), "archive", commit, "robodepth_cli"], check=True,
                          capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(dest, filter="data")
    return dest


def largest_difference(tmp: Path) -> float:
    """The largest relative difference between the reference's and this tree's metrics."""
    ref = json.loads((tmp / "metrics-reference.json").read_text())
    new = json.loads((tmp / "metrics-new-1.json").read_text())
    return max(abs(new[v][m] - ref[v][m]) / max(abs(ref[v][m]), 1e-300) for v in ref for m in ref[v])


def main() -> int:
    import subprocess

    from bench import cpu_name

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="6", help="variants per dataset (clean, then each corruption's "
                    "levels), or 'all' (91 KITTI-C, 61 NYUDepth2-C: the whole benchmark, measured)")
    ap.add_argument("--jobs", default="1,2", help="--jobs values of this tree, the first is the baseline")
    ap.add_argument("--images", type=int, default=0, help="images per variant (default: the real split)")
    ap.add_argument("--protocol", choices=["kitti", "nyu", "both"], default="both")
    ap.add_argument("--reference", default=REFERENCE, help="the commit whose code is the reference "
                    "('' for none)")
    ap.add_argument("--_make", help=argparse.SUPPRESS)
    ap.add_argument("--_measure", help=argparse.SUPPRESS)
    ap.add_argument("--_tag", default="new", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._make:
        proto, tmp = args.protocol, Path(args._make)
        count = {"kitti": 91, "nyu": 61}[proto] if args.variants == "all" else int(args.variants)
        (make_kitti if proto == "kitti" else make_nyu)(tmp, args.images or (697 if proto == "kitti" else 654),
                                                         count)
        return 0
    jobs = [int(j) for j in args.jobs.split(",")]
    if args._measure:
        measure(Path(args._measure), args.protocol, jobs[0], args._tag)
        return 0
    protocols = ["kitti", "nyu"] if args.protocol == "both" else [args.protocol]
    load = os.getloadavg()
    print(f"{os.cpu_count()} CPUs ({cpu_name()}), load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")
    with tempfile.TemporaryDirectory(prefix="robodepth-bench-eval-") as tmp:
        tmp = Path(tmp)
        ref = None
        if args.reference:
            try:
                ref = extract(args.reference, tmp / "reference")
            except (subprocess.CalledProcessError, OSError) as exc:
                print(f"no reference: cannot take {args.reference} from git ({exc}); this tree only")
        script = str(REPO / "bench" / "evaluate.py")
        for proto in protocols:
            common = [script, "--protocol", proto, "--variants", str(args.variants), "--images", str(args.images)]
            subprocess.run([sys.executable] + common + ["--_make", str(tmp)], check=True,
                           env={**os.environ, "PYTHONPATH": str(REPO)})
            # The first evaluation of a ground truth reads it and keeps it in the cache (an
            # empty one here); the later ones map it from there.
            cache = tmp / f"cache-{proto}"
            runs = (([("reference", ref, 1)] if ref else []) + [("new-cold", REPO, jobs[0])]
                    + [(f"new-{j}", REPO, j) for j in jobs])
            got = {}
            for tag, root, j in runs:
                path = str(root) if root == REPO else f"{root}{os.pathsep}{REPO}"
                env = {**os.environ, "PYTHONPATH": path, "ROBODEPTH_CACHE_DIR": str(cache)}
                env.pop("ROBODEPTH_GT_CACHE", None)
                out = subprocess.run([sys.executable] + common + ["--_measure", str(tmp), "--jobs", str(j),
                                                                  "--_tag", tag],
                                     check=True, capture_output=True, text=True, env=env).stdout.splitlines()
                print("\n".join(out[:-1]), flush=True)
                got[tag] = tuple(float(x) for x in out[-1].split())
            base, cold = got[f"new-{jobs[0]}"], got["new-cold"]
            if ref:
                r = got["reference"]
                print(f"{proto}: this tree against {args.reference}, --jobs {jobs[0]}: {r[0] / base[0]:.1f}x on the full "
                      f"benchmark ({r[0]:.0f} s -> {base[0]:.0f} s; the first evaluation of the ground truth, "
                      f"before it is cached: {r[0] / cold[0]:.1f}x, {cold[0]:.0f} s), {r[1] / base[1]:.1f}x in "
                      f"CPU per map; metrics differ by at most {largest_difference(tmp):.1e} relative", flush=True)
            for j in jobs[1:]:
                full = got[f"new-{j}"][0]
                print(f"{proto}: --jobs {j} against --jobs {jobs[0]}: {base[0] / full:.2f}x on the full "
                      f"benchmark ({base[0]:.0f} s -> {full:.0f} s)", flush=True)
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
