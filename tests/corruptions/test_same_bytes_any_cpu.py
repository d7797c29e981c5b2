"""The same output bytes whichever SIMD code the libraries take: small builds (every
corruption at every level and a decimal one, chains, the depth-aware ones at an odd size,
the corruptions over time, a severity size) in subprocesses with OpenCV's, IPP's, numpy's, numba's and
libjpeg-turbo's CPU-dependent paths switched off, one at a time and all together, stand in
for older or other CPUs; every manifest must equal the plain run's."""

from __future__ import annotations

import csv
import os
import shutil
import subprocess
import sys

import pytest

from tests.helpers.paths import FIXTURES, REPO
from tests.helpers.simd import stand_ins
from tests.helpers.trees import kitti_drive

pytestmark = pytest.mark.slow

EIGHTEEN = ("brightness,dark,fog,frost,snow,contrast,defocus_blur,glass_blur,motion_blur,zoom_blur,"
            "elastic_transform,color_quant,gaussian_noise,impulse_noise,shot_noise,iso_noise,pixelate,"
            "jpeg_compression")
DEPTH_AWARE = "fog_3d,near_focus,far_focus,motion_3d,zoom_3d,rain_3d"
OVER_TIME = "frame_lost,frame_freeze,h264_crf,h265_crf,bit_error"


@pytest.fixture(scope="module")
def roots(tmp_path_factory):
    """The KITTI fixture with its velodyne scans (depth for the depth-aware corruptions),
    and a drive of three consecutive frames (test frame 1) for the corruptions over time."""
    base = tmp_path_factory.mktemp("roots")
    kitti = base / "kitti_raw"
    shutil.copytree(FIXTURES / "kitti_raw", kitti)
    shutil.copytree(FIXTURES / "kitti_velodyne", kitti, dirs_exist_ok=True)
    drive_split = kitti_drive(base / "drive", range(3), [1], size=(32, 48))
    return kitti, drive_split


def builds(roots, out):
    kitti, drive_split = roots
    common = ("--jobs", "1", "--no-progress", "--png", "fast")
    yield ("build", "kitti-c", "--root", kitti, "--split", FIXTURES / "kitti_split.txt", "--limit", "1",
           "--size", "33x47", "--corruptions", f"{EIGHTEEN},{DEPTH_AWARE}", "--levels", "1,2,3,4,5,2.5",
           "--compose", "defocus_blur:2.5+frost:1,elastic_transform:3+glass_blur:2,near_focus:4+snow:1",
           "--out", out / "kitti", *common)
    yield ("build", "kitti-c", "--root", drive_split.parent / "drive", "--split", drive_split,
           "--size", "33x49", "--frames", "-1,1", "--no-gt", "--levels", "1,3,5,2.5",
           "--corruptions", f"{OVER_TIME},defocus_blur,elastic_transform,glass_blur,frost",
           "--out", out / "frames", *common)
    # A severity size far below the image size: the scaled parameters' long kernels and
    # resampled textures and maps (a custom build's default is scaled too).
    yield ("build", "custom", "--root", kitti / "2011_09_26/2011_09_26_drive_0002_sync/image_02/data",
           "--limit", "1", "--size", "200x667", "--severity-size", "48x160", "--corruptions", EIGHTEEN,
           "--levels", "3,5", "--out", out / "scaled", *common)


# A child process: the corruptions whose library calls took CPU-dependent paths, at every
# level, on full-size frames (a tiny build rarely lands a value next to an integer, where a
# different rounding shows), printed as one digest per variant.
_FULL_SIZE = """
import hashlib, sys
import numpy as np
from robodepth_cli.corruptions import corrupt
from robodepth_cli.imageio import load_clean
frames = [load_clean(p, s) for p, s in zip(sys.argv[1:], [(192, 640), (192, 640), None])]
for i, x in enumerate(frames):
    h, w = x.shape[:2]
    depth = np.broadcast_to(np.linspace(60.0, 2.0, h, dtype=np.float32)[:, None], (h, w)).copy()
    for name in ("defocus_blur", "glass_blur", "elastic_transform", "frost", "near_focus", "far_focus"):
        for level in (1, 2, 3, 4, 5, 2.5):
            rng = np.random.default_rng([i, int(level * 10)])
            d = depth if name.endswith("focus") else None
            out = corrupt(x, name, level, rng, depth=d)
            print(i, name, level, hashlib.sha256(out.tobytes()).hexdigest())
"""
FULL_SIZE_FRAMES = (FIXTURES / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png",
                    FIXTURES / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000054.png",
                    FIXTURES / "nyu/bedroom/rgb_00119.jpg")


def manifests(roots, out, extra_env) -> tuple[dict, str]:
    """Digests of every output of the builds and of the full-size child, by key."""
    env = {**os.environ, **extra_env, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    res = subprocess.run([sys.executable, "-c", _FULL_SIZE, *map(str, FULL_SIZE_FRAMES)], env=env,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    found = {" ".join(line.split()[:3]): line.split()[3] for line in res.stdout.splitlines()}
    stderr = res.stderr
    for args in builds(roots, out):
        res = subprocess.run([sys.executable, "-m", "robodepth_cli.cli", *map(str, args)], env=env,
                             capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
        stderr += res.stderr
        with open(args[args.index("--out") + 1] / "manifest.csv", newline="") as fh:
            found.update({f"{args[args.index('--out') + 1].name}:{r['output']}": r["sha256"] for r in csv.DictReader(fh)})
    return found, stderr


@pytest.fixture(scope="module")
def plain(roots, tmp_path_factory):
    return manifests(roots, tmp_path_factory.mktemp("plain"), {})[0]


def test_the_plain_builds_cover_every_kind_of_variant(plain):
    variants = {key.split(":", 1)[1].split("/")[0] for key in plain if ":" in key}
    names = set(f"{EIGHTEEN},{DEPTH_AWARE},{OVER_TIME}".split(","))
    assert names <= variants and {"clean", "defocus_blur-2.5+frost-1"} <= variants
    assert any("/2.5/" in key for key in plain)
    assert sum(key.startswith("scaled:") and "/5/" in key for key in plain) == 18
    assert all(len(h) == 64 for h in plain.values())
    assert sum(":" not in key for key in plain) == 3 * 6 * 6  # the full-size child's variants


@pytest.mark.parametrize("name", list(stand_ins()))
def test_same_manifest_with_simd_switched_off(name, roots, plain, tmp_path):
    env = stand_ins()[name]
    got, stderr = manifests(roots, tmp_path, env)
    assert "unknown CPU feature" not in stderr, stderr  # every name reached OpenCV
    differ = sorted(k for k in plain if got.get(k) != plain[k])
    assert set(got) == set(plain) and not differ, (env, len(differ), differ[:10])
