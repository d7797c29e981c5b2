"""Small KITTI-raw and NYU trees for the builder tests and the benchmarks, and tree comparison."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from PIL import Image

from robodepth_cli.output.layout import BOOKKEEPING, JOURNAL

KITTI_DRIVE = "2011_09_26/2011_09_26_drive_0001_sync"


def fixture_kitti_with_scans(where: Path) -> Path:
    """``where/kitti_raw``: the fixtures' two KITTI frames with their velodyne scans (copied in
    from their own tree, so the fixtures' KITTI tree stays without ground truth)."""
    from tests.helpers.paths import FIXTURES

    root = Path(where) / "kitti_raw"
    shutil.copytree(FIXTURES / "kitti_raw", root)
    shutil.copytree(FIXTURES / "kitti_velodyne", root, dirs_exist_ok=True)
    return root


def random_image(h: int, w: int, seed: int) -> np.ndarray:
    """A smooth random RGB image (noise would make every PNG large and slow)."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (max(h // 8, 2), max(w // 8, 2), 3), dtype=np.uint8)
    return np.asarray(Image.fromarray(small).resize((w, h), Image.BILINEAR))


def save(path: Path, img: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).save(path, quality=95) if path.suffix == ".jpg" else Image.fromarray(img).save(path)
    return path


def _source(path: Path, i: int, size, seed: int, copies_of) -> None:
    """Image ``i`` of a tree: a copy of ``copies_of[i % len(copies_of)]`` if given, else a
    generated ``size`` image."""
    if copies_of:
        path.parent.mkdir(parents=True, exist_ok=True)
        # A copy, not a symlink: the builder refuses links that leave the root.
        shutil.copyfile(copies_of[i % len(copies_of)], path)
    else:
        save(path, random_image(*size, seed=seed))


def kitti_tree(root: Path, frames, size=(60, 200), copies_of=()) -> Path:
    """Write KITTI-raw frames under ``root`` and their split file; ``frames`` holds
    (frame number, side, extension). Returns the split file (beside the root).

    The frames are generated ``size`` images, or byte copies of the files ``copies_of``
    taken in turn (real photographs, for a benchmark)."""
    lines = []
    for i, (frame, side, ext) in enumerate(frames):
        cam = {"l": "image_02", "r": "image_03"}[side]
        _source(root / KITTI_DRIVE / cam / "data" / f"{frame:010d}{ext}", i, size, i, copies_of)
        lines.append(f"{KITTI_DRIVE} {frame:010d} {side}")
    split = root.parent / f"{root.name}_split.txt"
    split.write_text("\n".join(lines) + "\n")
    return split


def kitti_drive(root: Path, frames, tests, size=(48, 64), ext: str = ".png") -> Path:
    """A KITTI-raw drive of consecutive left frames ``frames`` (e.g. ``range(6)``) whose
    split lists only ``tests``, so the others are neighbours. Each frame is a smooth image
    shifted a little from the one before, as a moving camera sees. Returns the split file."""
    base = random_image(size[0], size[1] + 4 * max(frames), seed=7)
    for n in frames:
        save(root / KITTI_DRIVE / "image_02" / "data" / f"{n:010d}{ext}",
             np.ascontiguousarray(base[:, 4 * n: 4 * n + size[1]]))
    split = root.parent / f"{root.name}_split.txt"
    split.write_text("".join(f"{KITTI_DRIVE} {n:010d} l\n" for n in tests))
    return split


def kitti_key(frame: int, side: str = "l") -> str:
    cam = {"l": "image_02", "r": "image_03"}[side]
    return f"kitti_data/{KITTI_DRIVE}/{cam}/data/{frame:010d}.png"


def nyu_tree(root: Path, names, size=(48, 64), copies_of=()) -> Path:
    """NYU test frames ``scene/rgb_NNNNN.jpg`` (plus dummy depth entries in the split),
    generated or copied from ``copies_of`` as in :func:`kitti_tree`. Returns the split file."""
    lines = []
    for i, rgb in enumerate(names):
        _source(root / rgb, i, size, 100 + i, copies_of)
        depth = rgb.replace("rgb_", "sync_depth_").rsplit(".", 1)[0] + ".png"
        lines.append(f"{rgb} {depth} 518.8579")
    split = root.parent / f"{root.name}_split.txt"
    split.write_text("\n".join(lines))
    return split


def tree(out: Path) -> dict[str, bytes]:
    """Every image file under ``out`` with its bytes (bookkeeping files left out, and the
    journal a killed build leaves)."""
    return {p.relative_to(out).as_posix(): p.read_bytes()
            for p in sorted(out.rglob("*")) if p.is_file() and p.name not in BOOKKEEPING
            and p.relative_to(out).parts[0] != JOURNAL}


def expected_paths(keys, variants, levels) -> set[str]:
    """The output layout (``clean/KEY`` and ``VARIANT/LEVEL/KEY``), spelled out independently
    of the builder."""
    paths = {f"clean/{k}" for k in keys}
    for v in variants:
        for lv in levels:
            paths |= {f"{v}/{lv}/{k}" for k in keys}
    return paths
