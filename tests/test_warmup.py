"""``python -m robodepth_cli.warmup`` (run by ``make install``): after it, a fresh install's
first commands compile no numba kernel, also once the install is read-only; and the cache's
last resort, the per-user temporary folder, is used only while it is private.

"Compiles nothing" is read from the cache itself: numba writes an index (``.nbi``) and the
code (``.nbc``) of every signature it compiles, so a run that compiled leaves a new or
rewritten file under the copy's package, home or temporary folder."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys

import pytest

from tests.helpers.fresh_install import (
    KITTI_FRAME,
    cache_files,
    corrupt_all,
    isolated_env,
    package_copy,
    run_timed,
)
from tests.helpers.paths import FIXTURES, REPO
from tests.helpers.readonly import read_only_tree

NYU_FRAME = FIXTURES / "nyu/bedroom/rgb_00001.jpg"
NYU_DEPTH = FIXTURES / "nyu/bedroom/sync_depth_00001.png"
DEPTH_AWARE = "fog_3d,near_focus,far_focus,motion_3d,zoom_3d,rain_3d"

# The warm-up as make install runs it, reporting besides the kernels it never called; the
# modules named on the command line are imported first, so their kernels are looked at too.
WARM_UP = """
import importlib, json, sys
from robodepth_cli import warmup
for name in sys.argv[1:]:
    importlib.import_module(name)
warmup.main()
print(json.dumps(sorted(k for k, d in warmup.kernels().items() if not d.signatures)))
"""


def _imported(path) -> set[str]:
    """The modules ``path`` imports (``from x import y``: ``x``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return ({a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
            | {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)})


def _module_name(path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def numba_imports() -> dict[str, set[str]]:
    """The numba modules each module of the package imports, for those that import some."""
    found = {_module_name(p): {m for m in _imported(p) if m == "numba" or m.startswith("numba.")}
             for p in sorted((REPO / "robodepth_cli").rglob("*.py"))}
    return {k: v for k, v in found.items() if v}


def kernel_modules() -> list[str]:
    """Every module of the package whose source imports numba or the package's njit."""
    return sorted(set(numba_imports()) | {_module_name(p) for p in (REPO / "robodepth_cli").rglob("*.py")
                                          if any(m.endswith("_jit") for m in _imported(p))})


@pytest.fixture(scope="module")
def warmed(tmp_path_factory):
    """(root, env) of a fresh copy of the package, warmed up once from an empty cache."""
    root = tmp_path_factory.mktemp("fresh-install")
    package_copy(root)
    env = isolated_env(root)
    res = subprocess.run([sys.executable, "-c", WARM_UP, *kernel_modules()], env=env, cwd=env["HOME"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    line, never = res.stdout.splitlines()
    return root, env, line, json.loads(never)


def test_numba_is_used_through_the_packages_njit_only():
    # Its njit gives every kernel the cache the warm-up fills and a read-only install reads;
    # jit.py and the evaluation's kernels take numba.extending.intrinsic (an LLVM
    # instruction), numba's types and carray (an array over an address), not a kernel
    # decorator; the warm-up only looks the dispatchers up.
    assert numba_imports() == {"robodepth_cli.corruptions._jit": {"numba", "numba.core.caching", "numba.np.linalg",
                                                                  "numba.np.arraymath"},
                               "robodepth_cli.corruptions.jit": {"numba.extending"},
                               "robodepth_cli.evaluation.kernels": {"numba.core", "numba.extending",
                                                                    "numba.np.numpy_support"},
                               "robodepth_cli.warmup": {"numba.core.registry"}}


PROBE = """
import sys
import numpy as np
from robodepth_cli.evaluation import kernels
kernels.median(np.ones(9, np.float32))  # numba's array registry is loaded by then
import numba.np.arraymath as arraymath
print("scipy.linalg" in sys.modules, arraymath._HAVE_BLAS, arraymath.ensure_blas.__module__)
"""


def test_a_kernel_runs_without_importing_scipy_linalg_and_numba_finds_the_same_blas():
    # numba's own probe for a BLAS imports scipy.linalg (0.17 s a process); the package
    # answers it from the files, with the answer numba's probe gives in a process of its own.
    ours = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, cwd=REPO, check=True)
    numbas = subprocess.run([sys.executable, "-c", "import numba.np.arraymath as a; print(a._HAVE_BLAS)"],
                            capture_output=True, text=True, check=True)
    assert ours.stdout.split() == ["False", numbas.stdout.strip(), "numba.np.linalg"]


@pytest.mark.slow
def test_the_warm_up_compiles_every_kernel_of_the_package(warmed):
    _, _, line, never = warmed
    assert never == []
    assert line.startswith("warmup: ") and " 0 already in the cache" in line, line


@pytest.mark.slow
def test_after_the_warm_up_the_first_commands_compile_nothing(warmed, tmp_path):
    root, env, _, _ = warmed
    before = cache_files(root)
    assert len(before) >= 60  # an index and at least one code file per kernel
    corrupt_all(env, tmp_path / "kitti")  # the 18 at levels 1-5 on the 192 x 640 frame
    # Odd sizes (the fog map is then a view), and every scaled path (a severity size).
    corrupt_all(env, tmp_path / "odd", size="97x321")
    run_timed(["-m", "robodepth_cli.cli", "corrupt", str(KITTI_FRAME), "-c", "all", "-l", "2.5",
               "--size", "96x320", "--severity-size", "192x640", "--out", f"{tmp_path}/scaled/"], env)
    run_timed(["-m", "robodepth_cli.cli", "corrupt", str(NYU_FRAME), "-c", DEPTH_AWARE, "-l", "all",
               "--size", "120x160", "--depth", str(NYU_DEPTH), "--depth-scale", "1000",
               "--out", f"{tmp_path}/nyu/"], env)
    # evaluate, twice: the ground truth read, then mapped read-only from the cache
    for dataset, pred in _minimal_datasets(tmp_path / "eval"):
        for _ in range(2):
            run_timed(["-m", "robodepth_cli.cli", "evaluate", str(dataset), "--pred", str(pred), "--out",
                       str(tmp_path / "eval" / "r.csv"), "--jobs", "1"],
                      {**env, "ROBODEPTH_CACHE_DIR": str(tmp_path / "eval" / "cache")})
    assert len(list((tmp_path / "eval" / "cache" / "ground-truth").glob("*.bin"))) == 2
    assert cache_files(root) == before
    # The warm-up again loads every signature and compiles none.
    out = subprocess.run([sys.executable, "-m", "robodepth_cli.warmup"], env=env, cwd=env["HOME"],
                         capture_output=True, text=True, check=True).stdout
    assert ": 0 compiled and cached" in out, out
    assert cache_files(root) == before


def _minimal_datasets(where) -> list:
    """A KITTI-C and a NYUDepth2-C of two images each, as evaluate reads them (build.json,
    manifest.csv, ground truth), with predictions of the networks' sizes for clean and
    brightness 1: ``[(dataset, pred), ...]``."""
    import cv2
    import numpy as np

    from tests.helpers.builds import minimal_build

    rng = np.random.default_rng(0)
    made = []
    for name, keys, shape in (("kitti-c", [f"kitti_data/d/image_02/data/{i:010d}.png" for i in range(2)],
                               (192, 640)),
                              ("nyudepth2-c", [f"scene/rgb_{i:05d}.png" for i in range(2)], (480, 640))):
        dataset = minimal_build(where / name, name, keys, [("clean", None), ("brightness", 1)], shape)
        pred = where / f"{name}-pred"
        if name == "kitti-c":
            gts = np.empty(2, object)
            for i in range(2):
                g = rng.uniform(2, 85, (375, 1242)).astype(np.float32)
                g[rng.random(g.shape) > 0.05] = 0
                gts[i] = g
            np.savez_compressed(dataset / "gt_depths.npz", data=gts)
        else:
            for i in range(2):
                path = dataset / "gt" / f"scene/sync_depth_{i:05d}.png"
                path.parent.mkdir(parents=True, exist_ok=True)
                cv2.imwrite(str(path), rng.integers(1, 10000, (480, 640)).astype(np.uint16))
        low, high = (0.01, 0.3) if name == "kitti-c" else (0.5, 9.0)
        for v in ("clean", "brightness/1"):
            (pred / v).parent.mkdir(parents=True, exist_ok=True)
            np.save(pred / f"{v}.npy", rng.uniform(low, high, (2, *shape)).astype(np.float32))
        made.append((dataset, pred))
    return made


@pytest.mark.slow
def test_a_read_only_install_warmed_before_compiles_nothing(warmed, tmp_path):
    root, env, _, _ = warmed
    before = cache_files(root)
    with read_only_tree(root / "pkg"):
        corrupt_all(env, tmp_path / "out")
    # Nothing in numba's user cache (home/.cache/numba) or the temporary folder either.
    assert cache_files(root) == before


@pytest.mark.slow
def test_a_corruption_that_cannot_run_is_named_and_the_others_warmed(monkeypatch, capsys):
    from robodepth_cli import warmup
    from robodepth_cli.corruptions import frost

    def missing(*args):
        raise frost.FrostTextureError("frost textures: not installed")

    for reader in ("texture_bgr", "scaled_texture"):  # the second caches the first's result
        monkeypatch.setattr(frost, reader, missing)
    assert warmup.main() == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "warmup: frost not compiled: frost textures: not installed"
    assert len(lines) == 2 and lines[1].startswith("warmup: ")
    assert warmup.kernels()["robodepth_cli.corruptions.snow._blend"].signatures


def _brightness(env):
    code = ("import numpy as np; from robodepth_cli.corruptions import corrupt; "
            "corrupt(np.zeros((32, 32, 3), np.uint8), 'brightness', 1, np.random.default_rng(0))")
    subprocess.run([sys.executable, "-c", code], env=env, cwd=env["HOME"], check=True)


def test_with_nothing_else_writable_the_cache_goes_to_a_private_temporary_folder(tmp_path):
    package_copy(tmp_path)
    env = isolated_env(tmp_path)
    private = tmp_path / "tmp" / f"robodepth-numba-{os.getuid()}"
    with read_only_tree(tmp_path / "pkg"), read_only_tree(tmp_path / "home"):
        _brightness(env)
    assert cache_files(private) != {}
    assert private.stat().st_mode & 0o777 == 0o700


def test_a_temporary_folder_others_may_write_is_not_used(tmp_path):
    package_copy(tmp_path)
    env = isolated_env(tmp_path)
    planted = tmp_path / "tmp" / f"robodepth-numba-{os.getuid()}"
    planted.mkdir()
    planted.chmod(0o777)  # as if someone else had made it first: its pickles are not read
    with read_only_tree(tmp_path / "pkg"), read_only_tree(tmp_path / "home"):
        _brightness(env)  # compiled, not cached
    assert cache_files(tmp_path) == {}
