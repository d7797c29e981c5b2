"""Benchmark: ``robodepth export`` of a KITTI-C build, both formats: time, peak memory, size
against the tree, extrapolated to the full KITTI-C (697 sources, 63,427 PNGs).

A KITTI-C build of N sources (copies of the two fixture frames, 192 x 640, all 18
corruptions x 5 levels plus clean: 91 PNGs a source) is made once, then exported as a user
runs it (``python -m robodepth_cli.cli export OUT --format F --to DIR``, a fresh
interpreter each), with the default shard size (500 MB) and with 1 MB shards (many shards,
more per-shard work). Peak memory is the export process's own maximum RSS (``wait4``).
The straightforward alternative measured in the same run is ``tar cf`` of the tree (what
one does to ship a folder: no hashing, no per-split files).

Memory is bounded by one row group (64 images) of a parquet shard and one file of a tar
shard, not by the dataset or the shard: the peak barely moves between 1 MB and 500 MB
shards, nor with N (``--sources``).

    python -m bench.export [--sources N] [--shard-sizes 500MB,1MB] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.build import KITTI_PER_SOURCE, kitti_tree

KITTI_FULL = 697
FORMATS = ("parquet", "webdataset")


def tree_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def timed(cmd: list[str]) -> tuple[float, int]:
    """(wall seconds, peak RSS bytes) of a child process; exits on its failure."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr.read().decode()}")
    return wall, usage.ru_maxrss * 1024


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=16, help="KITTI-C source images")
    ap.add_argument("--shard-sizes", default="500MB,1MB", help="the --shard-size values timed")
    ap.add_argument("--keep", type=Path, help="work under this directory and keep it")
    args = ap.parse_args(argv)
    base = Path(args.keep or tempfile.mkdtemp(prefix="robodepth-bench-export-"))
    base.mkdir(parents=True, exist_ok=True)
    py = [sys.executable, "-m", "robodepth_cli.cli"]
    try:
        root, split = kitti_tree(base, args.sources)
        out = base / "KITTI_C"
        t0 = time.perf_counter()
        subprocess.run([*py, "build", "kitti-c", "--root", str(root), "--split", str(split),
                        "--out", str(out), "--jobs", "2", "--no-gt", "--no-progress"],
                       check=True, stderr=subprocess.DEVNULL)
        images = args.sources * (KITTI_PER_SOURCE + 1)
        size = tree_bytes(out)
        print(f"build: {args.sources} sources, {images} PNGs, {size / 1e6:.1f} MB "
              f"({time.perf_counter() - t0:.1f} s)")
        scale = KITTI_FULL / args.sources
        tar_wall, tar_rss = timed(["tar", "cf", str(base / "tree.tar"), "-C", str(base), "KITTI_C"])
        (base / "tree.tar").unlink()
        print(f"tar cf of the tree (the alternative): {tar_wall:.2f} s, {tar_rss / 2**20:.0f} MiB "
              f"peak; full KITTI-C ~{tar_wall * scale:.0f} s")
        for fmt in FORMATS:
            for shard in args.shard_sizes.split(","):
                to = base / f"{fmt}-{shard}"
                shutil.rmtree(to, ignore_errors=True)
                wall, rss = timed([*py, "export", str(out), "--format", fmt, "--to", str(to),
                                   "--shard-size", shard, "--no-progress"])
                shards = len(list((to / "data").rglob("*.*")))
                exported = tree_bytes(to)
                print(f"export {fmt:10s} --shard-size {shard:5s}: {wall:6.2f} s "
                      f"({images / wall:.0f} images/s, {size / wall / 1e6:.0f} MB/s), peak "
                      f"{rss / 2**20:.0f} MiB RSS, {shards} shards, {exported / 1e6:.1f} MB = "
                      f"{exported / size:.3f} x the tree; {wall / tar_wall:.1f} x tar's time; "
                      f"full KITTI-C ~{wall * scale:.0f} s")
                t = time.perf_counter()
                subprocess.run([*py, "verify", str(to), "--no-progress"], check=True,
                               stdout=subprocess.DEVNULL)
                print(f"  verify: {time.perf_counter() - t:.2f} s")
                shutil.rmtree(to)
    finally:
        if not args.keep:
            shutil.rmtree(base, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
