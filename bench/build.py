"""Benchmark: whole-dataset build speed and memory, ``robodepth build`` against the
straightforward alternative, extrapolated to the full datasets.

KITTI-C: a temporary KITTI-layout tree of N source frames (the two fixture frames copied
under different frame numbers) and a split file listing them is built twice, all 18
corruptions x 5 levels plus the clean image (91 PNGs per source) at 192 x 640:

- ours: ``python -m robodepth_cli.cli build kitti-c --root R --split S --out O --jobs 2``,
  run exactly as a user runs it (a fresh interpreter, numba's on-disk cache as it is);
- the alternative: what one writes with the test oracle in an afternoon: a joblib pool of
  2 workers (loky, default batching) over (image, corruption, level) jobs; each job opens
  its source with Pillow, resizes it with Lanczos, applies ``imagecorruptions.corrupt``
  (its 15 corruptions) or the SPEC section 2 formula written plainly (dark, color_quant,
  iso_noise; the ones in bench/corruptions.py), and saves the PNG with Pillow's defaults.

NYUDepth2-C: N fixture frames (480 x 640, not resized), 15 corruptions x 4 levels + clean,
ours only.

Each build runs as a child process; its whole process tree (the build and its pool
workers) is sampled from /proc every 50 ms: wall time, CPU time (user + system, summed
over the tree), and peak memory as the largest sum over the tree of RSS (an upper bound:
shared pages of the libraries count once per process) and of PSS (shared pages split
between the processes that map them). Extrapolations to the full datasets are linear in
the number of sources from the whole wall time, start-up included, so they slightly
overstate. Other processes on the machine slow the wall time down: the load average is
printed, and the CPU time divided by the 2 cores shows what an idle machine would give.

Goals (issue 6, 2-core machine): full KITTI-C at 192 x 640 in <= 6 min and >= 5x the
alternative; full NYUDepth2-C in <= 8 min; peak memory of a whole build <= 1.5 GB.

    python bench/build.py [--sources N] [--nyu-sources N] [--no-alternative] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("ROBODEPTH_SHARED", REPO.parent / "shared")).resolve()
FIXTURES = SHARED / "fixtures"
KITTI_DRIVE = "2011_09_26/2011_09_26_drive_0002_sync"
KITTI_FRAMES = FIXTURES / "kitti_raw" / KITTI_DRIVE / "image_02" / "data"
NYU_FRAMES = FIXTURES / "nyu" / "bedroom"

KITTI_FULL = 697  # Eigen test split
NYU_FULL = 654
KITTI_PER_SOURCE = 18 * 5  # corruption images per source (+1 clean)
NYU_PER_SOURCE = 15 * 4
KITTI_SIZE = (192, 640)
WORKERS = 2

GOAL_KITTI_S = 6 * 60
GOAL_NYU_S = 8 * 60
GOAL_SPEEDUP = 5.0
GOAL_MEMORY = 1.5 * 1024 ** 3

# Thread-limit variables a user would not normally have set: removed from the children's
# environment so the builder's own settings are what is measured.
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")


# --- inputs --------------------------------------------------------------------------------

def kitti_tree(base: Path, n: int) -> tuple[Path, Path]:
    """A KITTI raw root with ``n`` frames (copies of the two fixture frames; the builder
    refuses symlinks leading outside the root) and an Eigen-format split listing them."""
    frames = sorted(KITTI_FRAMES.glob("*.png"))
    data = base / "kitti_raw" / KITTI_DRIVE / "image_02" / "data"
    data.mkdir(parents=True)
    lines = []
    for i in range(n):
        shutil.copyfile(frames[i % len(frames)], data / f"{i:010d}.png")
        lines.append(f"{KITTI_DRIVE} {i:010d} l\n")
    split = base / "kitti_split.txt"
    split.write_text("".join(lines))
    return base / "kitti_raw", split


def nyu_tree(base: Path, n: int) -> tuple[Path, Path]:
    frames = sorted(NYU_FRAMES.glob("rgb_*.jpg"))
    scene = base / "nyu" / "bedroom"
    scene.mkdir(parents=True)
    lines = []
    for i in range(n):
        shutil.copyfile(frames[i % len(frames)], scene / f"rgb_{i:05d}.jpg")
        lines.append(f"bedroom/rgb_{i:05d}.jpg bedroom/sync_depth_{i:05d}.png 518.8579\n")
    split = base / "nyu_split.txt"
    split.write_text("".join(lines))
    return base / "nyu", split


# --- measuring a process tree --------------------------------------------------------------

_TICK = os.sysconf("SC_CLK_TCK")


def _proc_table() -> dict[int, tuple[int, float]]:
    """pid -> (parent pid, CPU seconds) of every process."""
    table = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/stat", "rb") as fh:
                stat = fh.read().decode()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()  # the name in parentheses may hold spaces
        table[int(entry.name)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / _TICK)
    return table


def _memory(pid: int) -> tuple[int, int]:
    """(RSS, PSS) in bytes, (0, 0) for a process that has gone."""
    rss = pss = 0
    try:
        with open(f"/proc/{pid}/smaps_rollup") as fh:
            for line in fh:
                if line.startswith("Rss:"):
                    rss = int(line.split()[1]) * 1024
                elif line.startswith("Pss:"):
                    pss = int(line.split()[1]) * 1024
    except OSError:
        pass
    return rss, pss


class TreeSampler(threading.Thread):
    """Samples the process tree under ``root`` until :meth:`stop`."""

    def __init__(self, root: int, interval: float = 0.05):
        super().__init__(daemon=True)
        self.root, self.interval = root, interval
        self.cpu: dict[int, float] = {}  # last CPU seconds seen per process
        self.peak_rss = self.peak_pss = 0
        self.peak_procs = 0
        self._halt = threading.Event()

    def sample(self) -> None:
        table = _proc_table()
        tree, frontier = set(), [self.root]
        while frontier:
            pid = frontier.pop()
            if pid in table and pid not in tree:
                tree.add(pid)
                frontier += [p for p, (ppid, _) in table.items() if ppid == pid]
        rss = pss = 0
        for pid in tree:
            self.cpu[pid] = table[pid][1]
            r, p = _memory(pid)
            rss, pss = rss + r, pss + p
        self.peak_rss, self.peak_pss = max(self.peak_rss, rss), max(self.peak_pss, pss)
        self.peak_procs = max(self.peak_procs, len(tree))

    def run(self) -> None:
        while not self._halt.is_set():
            self.sample()
            self._halt.wait(self.interval)

    def stop(self) -> None:
        self._halt.set()
        self.join()


def measure(cmd: list[str], log: Path) -> dict:
    """Run ``cmd`` (output to ``log``) and measure its process tree."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    with open(log, "wb") as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env)
        sampler = TreeSampler(proc.pid)
        sampler.start()
        rc = proc.wait()
        wall = time.perf_counter() - t0
        sampler.stop()
    if rc != 0:
        sys.exit(f"{' '.join(cmd)} failed with exit status {rc}:\n{log.read_text()[-3000:]}")
    return {"wall": wall, "cpu": sum(sampler.cpu.values()), "rss": sampler.peak_rss,
            "pss": sampler.peak_pss, "procs": sampler.peak_procs}


def count_pngs(out: Path) -> int:
    return sum(1 for _ in out.rglob("*.png"))


# --- the straightforward alternative (runs in its own process: python bench/build.py --alternative) ---

def _alternative_job(src: str, dst: str, name: str, level: int, size: tuple[int, int]) -> None:
    import zlib

    import numpy as np
    from PIL import Image

    from corruptions import oracle  # bench/corruptions.py

    im = Image.open(src).convert("RGB")
    h, w = size
    if im.size != (w, h):
        im = im.resize((w, h), Image.LANCZOS)
    x = np.asarray(im)
    if name != "clean":
        np.random.seed(zlib.crc32(dst.encode()))  # the oracle draws from NumPy's global state
        x = oracle(x, name, level)
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    Image.fromarray(x).save(dst)


def alternative(root: Path, split: Path, out: Path) -> None:
    from joblib import Parallel, delayed

    from robodepth_cli.corruptions import NAMES

    jobs = []
    for line in split.read_text().splitlines():
        folder, frame, _ = line.split()
        rel = f"{folder}/image_02/data/{frame}.png"
        jobs.append((str(root / rel), str(out / "clean" / "kitti_data" / rel), "clean", 0))
        jobs += [(str(root / rel), str(out / name / str(lv) / "kitti_data" / rel), name, lv)
                 for name in NAMES for lv in range(1, 6)]
    Parallel(n_jobs=WORKERS)(delayed(_alternative_job)(*j, KITTI_SIZE) for j in jobs)


# --- report --------------------------------------------------------------------------------

def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.1f} min"


def _gb(n: int) -> str:
    return f"{n / 1024 ** 3:.2f} GB"


def show(label: str, m: dict, n: int, full: int, per_source: int) -> float:
    """Print one build's figures; return its extrapolated full-dataset wall time."""
    full_s = m["wall"] * full / n
    idle_s = m["cpu"] / WORKERS * full / n
    print(f"{label}: {n} sources x {per_source + 1} images in {m['wall']:.1f} s wall, "
          f"{m['cpu']:.1f} s CPU -> {n / m['wall']:.2f} sources/s, {n * (per_source + 1) / m['wall']:.0f} images/s")
    print(f"  peak memory of the build ({m['procs']} processes): RSS sum {_gb(m['rss'])}, "
          f"PSS sum {_gb(m['pss'])}")
    print(f"  full dataset ({full} sources, {full * per_source:,} images + {full} clean): "
          f"{_minutes(full_s)} (from the wall time), {_minutes(idle_s)} (CPU time / {WORKERS} cores)")
    return full_s


def goal(text: str, ok: bool) -> bool:
    print(f"goal: {text} -> {'met' if ok else 'NOT met'}")
    return ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=16, help="KITTI-C source images (>= 8)")
    ap.add_argument("--nyu-sources", type=int, default=12, help="NYUDepth2-C source images")
    ap.add_argument("--no-alternative", action="store_true", help="time ours only")
    ap.add_argument("--keep", type=Path, help="build under this directory and keep it")
    ap.add_argument("--alternative", nargs=3, type=Path, metavar=("ROOT", "SPLIT", "OUT"),
                    help=argparse.SUPPRESS)  # the child process of the alternative's run
    args = ap.parse_args(argv)
    if args.alternative:
        alternative(*args.alternative)
        return 0
    if args.sources < 8:
        ap.error("--sources must be at least 8")
    if not KITTI_FRAMES.is_dir() or not NYU_FRAMES.is_dir():
        ap.error(f"fixtures not found under {FIXTURES} (set ROBODEPTH_SHARED)")

    base = Path(tempfile.mkdtemp(prefix="robodepth-bench-build-", dir=args.keep))
    try:
        return run(base, args)
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)


def run(base: Path, args) -> int:
    py = sys.executable
    load = os.getloadavg()
    print(f"{os.cpu_count()} CPUs, load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} "
          "(other processes slow the wall times down)")
    n = args.sources
    root, split = kitti_tree(base / "in", n)
    cli = [py, "-m", "robodepth_cli.cli", "build"]
    ours = measure(cli + ["kitti-c", "--root", str(root), "--split", str(split), "--out",
                          str(base / "ours"), "--jobs", str(WORKERS), "--no-progress"],
                   base / "ours.log")
    expected = n * (KITTI_PER_SOURCE + 1)
    if count_pngs(base / "ours") != expected:
        sys.exit(f"ours wrote {count_pngs(base / 'ours')} PNGs, expected {expected}")
    print(f"KITTI-C subset at {KITTI_SIZE[0]} x {KITTI_SIZE[1]}, {WORKERS} workers")
    ours_full = show("ours", ours, n, KITTI_FULL, KITTI_PER_SOURCE)

    ok = True
    if not args.no_alternative:
        alt = measure([py, __file__, "--alternative", str(root), str(split), str(base / "alt")],
                      base / "alt.log")
        if count_pngs(base / "alt") != expected:
            sys.exit(f"the alternative wrote {count_pngs(base / 'alt')} PNGs, expected {expected}")
        show("alternative (imagecorruptions + SPEC formulas, joblib, Pillow)", alt, n, KITTI_FULL,
             KITTI_PER_SOURCE)
        speedup = alt["wall"] / ours["wall"]
        print(f"ours / alternative: {speedup:.1f}x source images/s (CPU time: "
              f"{alt['cpu'] / ours['cpu']:.1f}x less)")
    shutil.rmtree(base / "ours", ignore_errors=True)
    shutil.rmtree(base / "alt", ignore_errors=True)

    m = args.nyu_sources
    nroot, nsplit = nyu_tree(base / "in", m)
    nyu = measure(cli + ["nyudepth2-c", "--root", str(nroot), "--split", str(nsplit), "--out",
                         str(base / "nyu"), "--jobs", str(WORKERS), "--no-progress"],
                  base / "nyu.log")
    if count_pngs(base / "nyu") != m * (NYU_PER_SOURCE + 1):
        sys.exit(f"ours wrote {count_pngs(base / 'nyu')} NYUDepth2-C PNGs, expected {m * (NYU_PER_SOURCE + 1)}")
    print(f"NYUDepth2-C subset at 480 x 640, {WORKERS} workers")
    nyu_full = show("ours", nyu, m, NYU_FULL, NYU_PER_SOURCE)

    ok &= goal(f"full KITTI-C <= {GOAL_KITTI_S // 60} min: {_minutes(ours_full)}", ours_full <= GOAL_KITTI_S)
    if not args.no_alternative:
        ok &= goal(f">= {GOAL_SPEEDUP:.0f}x the alternative: {speedup:.1f}x", speedup >= GOAL_SPEEDUP)
    ok &= goal(f"full NYUDepth2-C <= {GOAL_NYU_S // 60} min: {_minutes(nyu_full)}", nyu_full <= GOAL_NYU_S)
    peak = max(ours["rss"], nyu["rss"])
    ok &= goal(f"peak memory <= {_gb(GOAL_MEMORY)}: {_gb(peak)} (RSS sum, ours)", peak <= GOAL_MEMORY)
    return 0


if __name__ == "__main__":
    sys.exit(main())
