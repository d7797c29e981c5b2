"""A fresh copy of the package, with none of its numba cache, run in subprocesses: what a new
install is before and after ``python -m robodepth_cli.warmup`` (tests/test_warmup.py and
bench/compile.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from tests.helpers.paths import FIXTURES, REPO

# The frame: a KITTI test frame, resized to 192 x 640 by `corrupt --size`.
KITTI_FRAME = FIXTURES / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


def package_copy(root: Path) -> Path:
    """``root/pkg/robodepth_cli``, a copy of the checkout's package without its
    ``__pycache__`` folders (where numba keeps its cache); returns ``root/pkg``. ``root/home``
    and ``root/tmp`` are made too, for :func:`isolated_env`."""
    pkg = root / "pkg"
    shutil.copytree(REPO / "robodepth_cli", pkg / "robodepth_cli", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("home", "tmp"):
        (root / name).mkdir()
    return pkg


def isolated_env(root: Path, pkg: Path | None = None) -> dict[str, str]:
    """The environment of a run of the copy ``pkg`` (default ``root/pkg``): first on the
    import path, with a home and a temporary folder of its own (so numba's user cache and the
    package's temporary-folder cache start empty) and no ``NUMBA_CACHE_DIR``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(PYTHONPATH=str(pkg or root / "pkg"), HOME=str(root / "home"), TMPDIR=str(root / "tmp"),
               XDG_CACHE_HOME=str(root / "home/.cache"))
    return env


def cache_files(root: Path) -> dict[str, tuple[int, int]]:
    """Every numba cache file (``.nbi`` index, ``.nbc`` code) under ``root``, by path, with
    its size and modification time: a compile writes or rewrites some."""
    return {str(p): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in root.rglob("*") if p.suffix in (".nbi", ".nbc")}


def run_timed(args: list[str], env: dict[str, str]) -> float:
    """Wall seconds of ``python ARGS`` in ``env``, from the copy's home folder (``python -m``
    puts the working folder first on the import path: a checkout's would shadow the copy);
    AssertionError with its output if it fails."""
    start = time.perf_counter()
    res = subprocess.run([sys.executable, *args], env=env, cwd=env["HOME"], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    assert res.returncode == 0, f"{' '.join(args)}: exit {res.returncode}\n{res.stdout}\n{res.stderr}"
    return seconds


def warm_up(env: dict[str, str]) -> float:
    """Wall seconds of ``python -m robodepth_cli.warmup``."""
    return run_timed(["-m", "robodepth_cli.warmup"], env)


def corrupt_all(env: dict[str, str], out: Path, frame: Path = KITTI_FRAME, size: str = "192x640") -> float:
    """Wall seconds of ``robodepth corrupt FRAME -c all -l all --size SIZE --out OUT/``."""
    return run_timed(["-m", "robodepth_cli.cli", "corrupt", str(frame), "-c", "all", "-l", "all",
                      "--size", size, "--out", f"{out}/"], env)
