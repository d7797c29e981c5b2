"""Benchmark: whole-dataset build speed and memory, ``robodepth build`` against the
straightforward alternative, extrapolated to the full datasets.

KITTI-C: a temporary KITTI-layout tree of N source frames (the two fixture frames copied
under different frame numbers) and a split file listing them is built twice, all 18
corruptions x 5 levels plus the clean image (91 PNGs per source) at 192 x 640:

- ours: ``python -m robodepth_cli.cli build kitti-c --root R --split S --out O --jobs 2``,
  run exactly as a user runs it (a fresh interpreter, numba's on-disk cache as it is),
  with the default fast PNG writer (fpng);
- ours with ``--png compact``: the libpng writer every build used before, for the ratio
  of the new way against the previous one in the same run;
- the alternative: what one writes with the test oracle in an afternoon: a joblib pool of
  2 workers (loky, default batching) over (image, corruption, level) jobs; each job opens
  its source with Pillow, resizes it with Lanczos, applies ``imagecorruptions.corrupt``
  (its 15 corruptions) or the published formula written plainly (dark, color_quant,
  iso_noise; the ones in bench/corruptions.py), and saves the PNG with Pillow's defaults.

NYUDepth2-C: N fixture frames (480 x 640, not resized), 15 corruptions x 4 levels + clean,
ours only.

Each build runs as a child process. Its whole process tree (the build and its pool
workers) is sampled every 0.1 s: CPU time (user + system, summed over the tree), the sum
of RSS over the tree (an upper bound of its memory: shared library pages count once per
process) and, every 2 s, the sum of PSS (shared pages split between the processes
that map them); peak memory is the largest sum seen. Progress is read afterwards from the
modification times of the PNGs, so measuring costs the build almost nothing. The
full-dataset time is extrapolated as the time to the first PNG (interpreter, imports, pool
start) plus all images at the steady rate, measured between 10% and 90% of the subset's
images; the subset's wall time scaled linearly (start-up counted again for every subset)
is printed too. Other processes on the machine slow the wall times down: the load average
is printed, and what an idle machine would take is estimated from what load does not
change: the steady CPU time per image (all processes) spread over the 2 cores, stretched by
the share of time the workers were blocked rather than computing or waiting for a core (the
kernel's per-process accounting, /proc/PID/schedstat), plus the CPU the main process spends
alone before the first PNG and after the last one (scaled to the full dataset) and the
workers' start-up. It is an estimate, not a measurement; the figures it is made from are
printed beside it.

Goals (2-core machine): full KITTI-C at 192 x 640 in <= 100 s and >= 5x the
alternative; full NYUDepth2-C in <= 150 s; peak memory of a whole build <= 1.5 GB.

    python -m bench.build [--sources N] [--nyu-sources N] [--no-alternative] [--no-compact]
                          [--keep DIR]
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

from tests.helpers import trees as _trees  # the test suite's tree builders
from tests.helpers.paths import FIXTURES  # tests/data/fixtures, inside the repository

KITTI_FRAMES = FIXTURES / "kitti_raw" / "2011_09_26" / "2011_09_26_drive_0002_sync" / "image_02" / "data"
NYU_FRAMES = FIXTURES / "nyu" / "bedroom"

KITTI_FULL = 697  # Eigen test split
FIRST_FRAME = f"{0:010d}.png"  # the output name of kitti_tree's first source
NYU_FIRST_FRAME = f"rgb_{0:05d}.png"  # and of nyu_tree's
NYU_FULL = 654
KITTI_PER_SOURCE = 18 * 5  # corruption images per source (+1 clean)
NYU_PER_SOURCE = 15 * 4
KITTI_SIZE = (192, 640)
WORKERS = 2

GOAL_KITTI_S = 100
GOAL_NYU_S = 150
GOAL_SPEEDUP = 5.0
GOAL_MEMORY = 1.5 * 1024 ** 3

# Thread-limit variables a user would not normally have set: removed from the children's
# environment so the builder's own settings are what is measured.
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")


# --- inputs --------------------------------------------------------------------------------

def kitti_tree(base: Path, n: int) -> tuple[Path, Path]:
    """A KITTI raw root with ``n`` left frames, copies of the two fixture frames in turn, and
    an Eigen-format split listing them."""
    root = base / "kitti_raw"
    split = _trees.kitti_tree(root, [(i, "l", ".png") for i in range(n)],
                              copies_of=sorted(KITTI_FRAMES.glob("*.png")))
    return root, split


def nyu_tree(base: Path, n: int) -> tuple[Path, Path]:
    """An NYU test root with ``n`` frames in one scene, copies of the two fixture frames in
    turn, and a split listing them."""
    root = base / "nyu"
    split = _trees.nyu_tree(root, [f"bedroom/rgb_{i:05d}.jpg" for i in range(n)],
                            copies_of=sorted(NYU_FRAMES.glob("rgb_*.jpg")))
    return root, split


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


_PAGE = os.sysconf("SC_PAGE_SIZE")


def _rss(pid: int) -> int:
    """Resident set size in bytes (0 for a process that has gone); cheap to read."""
    try:
        with open(f"/proc/{pid}/statm") as fh:
            return int(fh.read().split()[1]) * _PAGE
    except OSError:
        return 0


def _pss(pid: int) -> int:
    """Proportional set size in bytes (0 for a process that has gone). The kernel walks every
    mapping for this (a few ms per process), so it is read less often than the RSS."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as fh:
            for line in fh:
                if line.startswith("Pss:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _schedstat(pid: int) -> tuple[float, float] | None:
    """(CPU seconds, seconds spent runnable but waiting for a core) of the main thread of
    ``pid``, from the scheduler's own accounting; None for a process that has gone."""
    try:
        with open(f"/proc/{pid}/schedstat") as fh:
            cpu, wait = fh.read().split()[:2]
    except (OSError, ValueError):
        return None
    return int(cpu) / 1e9, int(wait) / 1e9


_BOOT = time.time() - time.clock_gettime(time.CLOCK_BOOTTIME)


def _started(pid: int) -> float | None:
    """When ``pid`` started (time.time() scale), None if it has gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            stat = fh.read().decode()
    except OSError:
        return None
    return _BOOT + int(stat[stat.rindex(")") + 2:].split()[19]) / _TICK


def png_times(out: Path) -> list[float]:
    """Modification times of the finished PNGs under ``out``, sorted: when each was
    written (the builder renames a finished temporary file, which keeps its time)."""
    times = []
    for dirpath, _, files in os.walk(out):
        times += [os.stat(os.path.join(dirpath, f)).st_mtime for f in files
                  if f.endswith(".png") and not f.startswith(".")]
    return sorted(times)


class TreeSampler(threading.Thread):
    """Samples the process tree under ``root`` until :meth:`stop`: ``samples`` holds
    (time.time(), CPU seconds of the tree so far). Kept light (about 1.5 ms per sample) so
    as not to slow down what it measures: output progress is read afterwards from the
    files' times, not counted while the build runs."""

    def __init__(self, root: int, interval: float = 0.1, pss_every: int = 20):
        super().__init__(daemon=True)
        self.root, self.interval, self.pss_every = root, interval, pss_every
        self.cpu: dict[int, float] = {}  # last CPU seconds seen per process
        self.samples: list[tuple[float, float]] = []
        self.peak_rss = self.peak_pss = 0
        self.peak_procs = 0
        # pid -> [(time.time(), CPU s, run-queue wait s), ...] from the scheduler's accounting
        self.sched: dict[int, list[tuple[float, float, float]]] = {}
        self.root_cpu: list[tuple[float, float]] = []  # (time.time(), CPU of the root process)
        self._halt = threading.Event()

    def sample(self) -> None:
        table = _proc_table()
        children: dict[int, list[int]] = {}
        for pid, (ppid, _) in table.items():
            children.setdefault(ppid, []).append(pid)
        tree, frontier = set(), [self.root]
        while frontier:
            pid = frontier.pop()
            if pid in table and pid not in tree:
                tree.add(pid)
                frontier += children.get(pid, [])
        now = time.time()
        for pid in tree:
            self.cpu[pid] = table[pid][1]
            stat = _schedstat(pid)
            if stat is not None:
                if pid not in self.sched:
                    self.sched[pid] = [(_started(pid) or now, 0.0, 0.0)]
                self.sched[pid].append((now, *stat))
        self.root_cpu.append((now, self.cpu.get(self.root, 0.0)))
        self.peak_rss = max(self.peak_rss, sum(_rss(pid) for pid in tree))
        if len(self.samples) % self.pss_every == 0:
            self.peak_pss = max(self.peak_pss, sum(_pss(pid) for pid in tree))
        self.peak_procs = max(self.peak_procs, len(tree))
        self.samples.append((time.time(), sum(self.cpu.values())))

    def run(self) -> None:
        while not self._halt.is_set():
            self.sample()
            self._halt.wait(self.interval)

    def stop(self) -> None:
        self._halt.set()
        self.join()


def steady(times: list[float], samples: list[tuple[float, float]], start: float):
    """(seconds from ``start`` to the first PNG, PNGs per second and CPU seconds per PNG
    between the 10% and the 90% marks of the outputs): start-up and the tail where one
    worker idles are left out. ``times`` are the PNGs' times, ``samples`` the CPU samples."""
    ia, ib = len(times) // 10, (9 * len(times)) // 10
    ta, tb = times[ia], times[ib]
    ts, cpu = zip(*samples)

    def cpu_at(t: float) -> float:
        import numpy as np

        return float(np.interp(t, ts, cpu))

    return times[0] - start, (ib - ia) / (tb - ta), (cpu_at(tb) - cpu_at(ta)) / (ib - ia)


def measure(cmd: list[str], out: Path, total: int, log: Path) -> dict:
    """Run ``cmd`` (output to ``log``), which writes ``total`` PNGs under ``out``, and
    measure its process tree."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    with open(log, "wb") as fh:
        start, t0 = time.time(), time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env)
        sampler = TreeSampler(proc.pid)
        sampler.start()
        rc = proc.wait()
        wall = time.perf_counter() - t0
        sampler.stop()
    if rc != 0:
        sys.exit(f"{' '.join(cmd)} failed with exit status {rc}:\n{log.read_text()[-3000:]}")
    times = png_times(out)
    if len(times) != total:
        sys.exit(f"{' '.join(cmd)} wrote {len(times)} PNGs, expected {total}")
    first, rate, cpu_per_png = steady(times, sampler.samples, start)
    return {**idle_structure(sampler, proc.pid, times),
            "wall": wall, "cpu": sum(sampler.cpu.values()), "rss": sampler.peak_rss,
            "pss": sampler.peak_pss, "procs": sampler.peak_procs, "first": first, "rate": rate,
            "cpu_per_png": cpu_per_png, "bytes": sum(f.stat().st_size for f in out.rglob("*.png"))}


def idle_structure(sampler: TreeSampler, root: int, times: list[float]) -> dict:
    """What keeps cores idle on an idle machine, measured so that the load of a shared one
    does not count: the scheduler splits each process's time into CPU, waiting for a core
    (other processes' doing) and the rest, blocked (waiting for a task, a file, a lock).
    ``blocked``: the workers' blocked time as a fraction of their CPU + blocked time between
    the 10% and 90% marks of the outputs (the steady state; ``blocked_all``: over their
    whole lives, start-up and the tail where one worker waits for the other included);
    ``serial_start`` and ``serial_end``: the CPU the main process spends alone before the
    first PNG and after the last one (start-up and planning; merging and sorting the
    manifest)."""
    import numpy as np

    others = {pid: v for pid, v in sampler.sched.items() if pid != root and len(v) > 1}
    workers = sorted(others, key=lambda pid: others[pid][-1][1], reverse=True)[:WORKERS]

    def split(pid: int, t0: float, t1: float) -> tuple[float, float]:
        """(CPU, blocked) seconds of ``pid`` between t0 and t1."""
        ts, cpu, wait = (np.array(c) for c in zip(*others[pid]))
        (c0, c1), (w0, w1) = np.interp([t0, t1], ts, cpu), np.interp([t0, t1], ts, wait)
        return c1 - c0, max(0.0, (t1 - t0) - (c1 - c0) - (w1 - w0))

    def fraction(t0: float | None, t1: float | None) -> float:
        parts = [split(p, others[p][0][0] if t0 is None else t0, others[p][-1][0] if t1 is None else t1)
                 for p in workers]
        cpu, blocked = sum(c for c, _ in parts), sum(b for _, b in parts)
        return blocked / (cpu + blocked) if cpu + blocked else 0.0

    ts, rc = zip(*sampler.root_cpu)
    main_total = sampler.cpu.get(root, rc[-1])
    return {"blocked": fraction(times[len(times) // 10], times[(9 * len(times)) // 10]),
            "blocked_all": fraction(None, None),
            "serial_start": float(np.interp(times[0], ts, rc)),
            "serial_end": main_total - float(np.interp(times[-1], ts, rc)),
            "main_cpu": main_total, "worker_cpu": sum(others[p][-1][1] for p in workers)}


# --- the straightforward alternative (runs in its own process: python -m bench.build --alternative) ---

def _alternative_job(src: str, dst: str, name: str, level: int, size: tuple[int, int]) -> None:
    import zlib

    import numpy as np
    from PIL import Image

    from bench.corruptions import oracle

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

def _seconds(seconds: float) -> str:
    return f"{seconds:.0f} s"


def _gb(n: int) -> str:
    return f"{n / 1024 ** 3:.2f} GB"


def show(label: str, m: dict, n: int, full: int, per_source: int) -> tuple[float, float]:
    """Print one build's figures; return its extrapolated full-dataset time (wall, and on
    an idle machine)."""
    images = per_source + 1  # + the clean image
    full_s = m["first"] + full * images / m["rate"]
    # An idle machine: the main process's lone start-up, the workers' start-up (their CPU
    # beyond the steady rate, shared by the cores), every image at the steady CPU per image
    # over the cores, stretched by the share of time the workers were blocked, and the
    # main process's lone work after the last image (it grows with the rows: scaled).
    startup = max(0.0, m["worker_cpu"] - n * images * m["cpu_per_png"]) / WORKERS
    idle_s = (m["serial_start"] + startup
              + full * images * m["cpu_per_png"] / WORKERS / (1 - m["blocked"])
              + m["serial_end"] * full / n)
    linear_s = m["wall"] * full / n
    print(f"{label}:")
    print(f"  {n} sources x {images} images in {m['wall']:.1f} s wall ({n / m['wall']:.2f} sources/s), "
          f"{m['cpu']:.1f} s CPU; first PNG after {m['first']:.1f} s")
    print(f"  steady state: {m['rate'] / images:.2f} sources/s ({m['rate']:.0f} images/s), "
          f"{1000 * m['cpu_per_png']:.2f} ms CPU per image (all processes)")
    print(f"  idle structure: workers blocked {100 * m['blocked']:.1f}% of their CPU + blocked time in the "
          f"steady state ({100 * m['blocked_all']:.1f}% over their lives); "
          f"main process alone {m['serial_start']:.2f} s CPU before the first PNG and "
          f"{m['serial_end']:.2f} s after the last ({m['main_cpu']:.2f} s in all); worker start-up "
          f"{startup:.2f} s per core")
    print(f"  peak memory ({m['procs']} processes): RSS sum {_gb(m['rss'])}, PSS sum {_gb(m['pss'])}; "
          f"output {m['bytes'] / (n * images) / 1024:.0f} KiB per image")
    print(f"  full dataset ({full} sources, {full * per_source:,} images + {full} clean): "
          f"{_seconds(full_s)} (start-up + steady rate); {_seconds(idle_s)} estimated on {WORKERS} idle "
          f"cores (steady CPU per image over the cores, the blocked share, the lone start and end); "
          f"{_seconds(linear_s)} scaling the subset's wall time")
    return full_s, idle_s


def png_size_cost(tree: Path, name: str) -> float:
    """Bytes of our PNGs named ``name`` (all the outputs of one source) over the bytes of
    the same pixels saved with Pillow's defaults (zlib level 6, adaptive filters), minus 1."""
    import io

    import numpy as np
    from PIL import Image

    ours = pillow = 0
    for path in tree.rglob(name):
        data = path.read_bytes()
        with Image.open(io.BytesIO(data)) as im:
            pixels = np.asarray(im)
        buf = io.BytesIO()
        Image.fromarray(pixels).save(buf, format="PNG")
        ours, pillow = ours + len(data), pillow + buf.tell()
    return ours / pillow - 1


def decode_resize_cpu(path: Path, repeats: int = 10) -> float:
    """CPU seconds to open ``path`` with Pillow and Lanczos-resize it to the KITTI-C size."""
    from PIL import Image

    h, w = KITTI_SIZE
    t = time.process_time()
    for _ in range(repeats):
        with Image.open(path) as im:
            im.convert("RGB").resize((w, h), Image.LANCZOS)
    return (time.process_time() - t) / repeats


def goal(text: str, limit: float, measured: float, idle: float, fmt, at_most: bool = True) -> None:
    """Judged on the measured wall-clock figure; the idle-machine estimate beside it."""
    def met(v: float) -> str:
        return "met" if (v <= limit if at_most else v >= limit) else "NOT met"

    print(f"goal: {text}: {fmt(measured)} -> {met(measured)} "
          f"(idle-machine estimate {fmt(idle)} -> {met(idle)})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=8, help="KITTI-C source images (>= 8)")
    ap.add_argument("--nyu-sources", type=int, default=8, help="NYUDepth2-C source images")
    ap.add_argument("--no-alternative", action="store_true", help="do not time the alternative")
    ap.add_argument("--no-compact", action="store_true", help="do not time ours with --png compact")
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
        ap.error(f"fixtures not found under {FIXTURES} (tests/data is part of the repository)")

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
    total = n * (KITTI_PER_SOURCE + 1)
    root, split = kitti_tree(base / "in", n)
    cli = [py, "-m", "robodepth_cli.cli", "build"]
    ours = measure(cli + ["kitti-c", "--root", str(root), "--split", str(split), "--out",
                          str(base / "ours"), "--jobs", str(WORKERS), "--no-progress"],
                   base / "ours", total, base / "ours.log")
    print(f"KITTI-C subset at {KITTI_SIZE[0]} x {KITTI_SIZE[1]}, {WORKERS} workers")
    ours_full = show("ours (robodepth build)", ours, n, KITTI_FULL, KITTI_PER_SOURCE)
    print(f"  PNG size vs Pillow's default encoder on the same pixels: "
          f"{100 * png_size_cost(base / 'ours', FIRST_FRAME):+.1f}% (one source's {KITTI_PER_SOURCE + 1} images)")
    shutil.rmtree(base / "ours", ignore_errors=True)

    if not args.no_compact:
        compact = measure(cli + ["kitti-c", "--root", str(root), "--split", str(split), "--out",
                                 str(base / "compact"), "--jobs", str(WORKERS), "--no-progress",
                                 "--png", "compact"],
                          base / "compact", total, base / "compact.log")
        compact_full = show("ours with --png compact (the PNG writer before)", compact, n,
                            KITTI_FULL, KITTI_PER_SOURCE)
        shutil.rmtree(base / "compact", ignore_errors=True)
        print(f"fast PNG vs compact: {compact_full[0] / ours_full[0]:.2f}x on the full dataset "
              f"({compact_full[1] / ours_full[1]:.2f}x idle-machine estimate), "
              f"{compact['cpu_per_png'] / ours['cpu_per_png']:.2f}x less CPU per image, "
              f"{ours['bytes'] / compact['bytes']:.2f}x the bytes")

    if not args.no_alternative:
        alt = measure([py, "-m", "bench.build", "--alternative", str(root), str(split), str(base / "alt")],
                      base / "alt", total, base / "alt.log")
        alt_full = show("alternative (imagecorruptions + SPEC formulas, joblib, Pillow)", alt, n,
                        KITTI_FULL, KITTI_PER_SOURCE)
        shutil.rmtree(base / "alt", ignore_errors=True)
        print(f"ours vs the alternative: {alt_full[0] / ours_full[0]:.1f}x on the full dataset "
              f"({ours['rate'] / alt['rate']:.1f}x steady sources/s, {alt['wall'] / ours['wall']:.1f}x "
              f"on the subset's wall time, {alt['cpu_per_png'] / ours['cpu_per_png']:.1f}x less CPU per image)")
        reread = decode_resize_cpu(root / _trees.KITTI_DRIVE / "image_02" / "data" / FIRST_FRAME)
        print(f"  (the alternative re-reads and resizes its source in every job: {1000 * reread:.0f} ms CPU "
              f"of its {1000 * alt['cpu_per_png']:.0f} ms per image; a variant that read each source once "
              f"would still take {(alt['cpu_per_png'] - reread) / ours['cpu_per_png']:.1f}x our CPU per image)")

    m = args.nyu_sources
    nroot, nsplit = nyu_tree(base / "in", m)
    nyu = measure(cli + ["nyudepth2-c", "--root", str(nroot), "--split", str(nsplit), "--out",
                         str(base / "nyu"), "--jobs", str(WORKERS), "--no-progress"],
                  base / "nyu", m * (NYU_PER_SOURCE + 1), base / "nyu.log")
    print(f"NYUDepth2-C subset at 480 x 640, {WORKERS} workers")
    nyu_full = show("ours (robodepth build)", nyu, m, NYU_FULL, NYU_PER_SOURCE)
    print(f"  PNG size vs Pillow's default encoder on the same pixels: "
          f"{100 * png_size_cost(base / 'nyu', NYU_FIRST_FRAME):+.1f}% (one source's {NYU_PER_SOURCE + 1} images)")

    goal(f"full KITTI-C <= {GOAL_KITTI_S} s", GOAL_KITTI_S, *ours_full, _seconds)
    if not args.no_alternative:
        goal(f"ours >= {GOAL_SPEEDUP:.0f}x the alternative on the full dataset", GOAL_SPEEDUP,
             alt_full[0] / ours_full[0], alt_full[1] / ours_full[1], lambda v: f"{v:.1f}x", at_most=False)
    goal(f"full NYUDepth2-C <= {GOAL_NYU_S} s", GOAL_NYU_S, *nyu_full, _seconds)
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")
    peak = max(ours["rss"], nyu["rss"])
    print(f"goal: peak memory <= {_gb(GOAL_MEMORY)}: {_gb(peak)} (RSS sum over the processes of "
          f"ours) -> {'met' if peak <= GOAL_MEMORY else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
