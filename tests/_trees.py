"""Small synthetic KITTI-raw and NYU trees for the builder tests, and tree comparison."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from robodepth_cli.manifest import BOOKKEEPING

KITTI_DRIVE = "2011_09_26/2011_09_26_drive_0001_sync"


def random_image(h: int, w: int, seed: int) -> np.ndarray:
    """A smooth random RGB image (noise would make every PNG large and slow)."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (max(h // 8, 2), max(w // 8, 2), 3), dtype=np.uint8)
    return np.asarray(Image.fromarray(small).resize((w, h), Image.BILINEAR))


def save(path: Path, img: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).save(path, quality=95) if path.suffix == ".jpg" else Image.fromarray(img).save(path)
    return path


def kitti_tree(root: Path, frames, size=(60, 200)) -> Path:
    """Write KITTI-raw frames under ``root`` and their split file; ``frames`` holds
    (frame number, side, extension). Returns the split file (beside the root)."""
    lines = []
    for i, (frame, side, ext) in enumerate(frames):
        cam = {"l": "image_02", "r": "image_03"}[side]
        save(root / KITTI_DRIVE / cam / "data" / f"{frame:010d}{ext}", random_image(*size, seed=i))
        lines.append(f"{KITTI_DRIVE} {frame:010d} {side}")
    split = root.parent / f"{root.name}_split.txt"
    split.write_text("\n".join(lines) + "\n")
    return split


def kitti_key(frame: int, side: str = "l") -> str:
    cam = {"l": "image_02", "r": "image_03"}[side]
    return f"kitti_data/{KITTI_DRIVE}/{cam}/data/{frame:010d}.png"


def nyu_tree(root: Path, names, size=(48, 64)) -> Path:
    """NYU test frames ``scene/rgb_NNNNN.jpg`` (plus dummy depth entries in the split)."""
    lines = []
    for i, rgb in enumerate(names):
        save(root / rgb, random_image(*size, seed=100 + i))
        depth = rgb.replace("rgb_", "sync_depth_").rsplit(".", 1)[0] + ".png"
        lines.append(f"{rgb} {depth} 518.8579")
    split = root.parent / f"{root.name}_split.txt"
    split.write_text("\n".join(lines))
    return split


def tree(out: Path) -> dict[str, bytes]:
    """Every image file under ``out`` with its bytes (bookkeeping files left out)."""
    return {p.relative_to(out).as_posix(): p.read_bytes()
            for p in sorted(out.rglob("*")) if p.is_file() and p.name not in BOOKKEEPING}


def expected_paths(keys, variants, levels) -> set[str]:
    """The SPEC section 1 layout, spelled out independently of the builder."""
    paths = {f"clean/{k}" for k in keys}
    for v in variants:
        for lv in levels:
            paths |= {f"{v}/{lv}/{k}" for k in keys}
    return paths
