"""Benchmark: the numba compile wait of a fresh install, without and with the warm-up that
``make install`` runs.

Wall time of the first and the second ``robodepth corrupt FRAME -c all -l all --size 192x640``
(90 images of the KITTI frame), each in its own interpreter, in a fresh copy of the package
with an empty cache (its own home and temporary folders): without the warm-up (the first run
compiles every kernel it calls) and after ``python -m robodepth_cli.warmup`` (timed too), then
after the warm-up with the package mounted read-only (as root, where a mount is allowed), and
with ``NUMBA_CPU_NAME=generic`` for the warm-up and the runs (a cache valid on any x86-64 CPU,
for workers on other machines: the same bytes, code for no particular CPU).
The goal: after the warm-up, the first run at most 3 s slower than the second.

    python -m bench.compile
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

from bench import cpu_name
from tests.helpers.fresh_install import cache_files, corrupt_all, isolated_env, package_copy, warm_up
from tests.helpers.readonly import read_only_tree

GOAL_S = 3.0


def first_and_second(env, out: Path) -> tuple[float, float]:
    return corrupt_all(env, out / "first"), corrupt_all(env, out / "second")


def main() -> int:
    load = os.getloadavg()
    print(f"CPU: {cpu_name()}; load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on {os.cpu_count()} CPUs")
    print("robodepth corrupt FRAME -c all -l all --size 192x640 (90 images), wall s, fresh install:")
    ok = True
    with tempfile.TemporaryDirectory(prefix="robodepth-bench-compile-") as tmp:
        cold = Path(tmp, "cold")
        package_copy(cold)
        first, second = first_and_second(isolated_env(cold), cold)
        print(f"  without warm-up: first {first:5.1f}  second {second:5.1f}  first - second {first - second:5.1f}")
        warm = Path(tmp, "warm")
        package_copy(warm)
        env = isolated_env(warm)
        seconds = warm_up(env)
        files = len(cache_files(warm))
        first, second = first_and_second(env, warm)
        ok = first - second <= GOAL_S
        print(f"  after warm-up:   first {first:5.1f}  second {second:5.1f}  first - second {first - second:5.1f}"
              f"  (warm-up {seconds:.1f} s, {files} cache files; goal: at most {GOAL_S:.0f} s)")
        try:
            with read_only_tree(warm / "pkg"):
                first, second = first_and_second(env, Path(tmp, "ro"))
            ok = ok and first - second <= GOAL_S
            print(f"  read-only, warm: first {first:5.1f}  second {second:5.1f}  first - second {first - second:5.1f}")
        except pytest.skip.Exception as exc:
            print(f"  read-only: not measured ({exc})")
        generic = Path(tmp, "generic")
        package_copy(generic)
        env = {**isolated_env(generic), "NUMBA_CPU_NAME": "generic"}
        seconds = warm_up(env)
        first, second = first_and_second(env, generic)
        print(f"  generic CPU:     first {first:5.1f}  second {second:5.1f}  first - second {first - second:5.1f}"
              f"  (warm-up {seconds:.1f} s)")
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}; "
          + ("goal met" if ok else "goal NOT met"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
