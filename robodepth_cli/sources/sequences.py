"""Standard splits of consecutive frames, for flicker (``evaluate --flicker``) on video.

The number of frames of a KITTI drive varies, and a user's raw tree may hold only some
drives, so such a split is no fixed file: it is made from the tree under ``--root`` by one
rule. ``kitti_sequences``: for each drive of :data:`SPLITS` in order, the first run of
``frames`` consecutive frames whose left image (``image_02/data/FRAME.png`` or ``.jpg``)
is under ROOT, as ``DATE/DRIVE FRAME l`` lines; a drive without such a run is left out, and
a tree with none of them is refused. The drives are drives of the Eigen test split, so no
frame of them is in the Eigen training split. The file is written into the split cache
(``splits/generated/``, its name carries its sha256), and the build records its path and
sha256 as for any split; the ground truth (the build's, or ``gt kitti --split
kitti_sequences --root ROOT``) is made from the same lines.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import RobodepthError, os_reason
from ..files import sha256_bytes, write_atomic


@dataclass(frozen=True)
class Sequences:
    name: str
    drives: tuple[str, ...]  # DATE/DRIVE
    frames: int  # consecutive frames per drive
    description: str


SPLITS = {s.name: s for s in (
    Sequences("kitti_sequences",
              ("2011_09_26/2011_09_26_drive_0002_sync", "2011_09_26/2011_09_26_drive_0036_sync",
               "2011_09_30/2011_09_30_drive_0016_sync", "2011_10_03/2011_10_03_drive_0047_sync"),
              20, "the first 20 consecutive frames of 4 drives of the Eigen test split (KITTI raw)"),
)}
FORMAT = "eigen"
IMAGE_SUFFIXES = (".png", ".jpg")


class SequenceError(RobodepthError):
    """A sequence split that cannot be made from the tree; the message says why."""


def frame_numbers(root: Path, drive: str) -> list[int]:
    """The frame numbers of ``drive``'s left images under ``root``, sorted."""
    folder = root / drive / "image_02" / "data"
    try:
        names = [p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
    except OSError:
        return []
    return sorted({int(p.stem) for p in names if p.stem.isdigit()})


def first_run(numbers: list[int], length: int) -> int | None:
    """The first frame of the first run of ``length`` consecutive numbers; None if none."""
    start, run = None, 0
    for k, n in enumerate(numbers):
        run = run + 1 if k and n == numbers[k - 1] + 1 else 1
        start = n if run == 1 else start
        if run == length:
            return start
    return None


def lines(name: str, root: Path) -> list[str]:
    """The split's lines for the tree under ``root`` (the module's rule)."""
    seq = SPLITS[name]
    out = []
    for drive in seq.drives:
        start = first_run(frame_numbers(root, drive), seq.frames)
        if start is not None:
            out += [f"{drive} {n:010d} l" for n in range(start, start + seq.frames)]
    if not out:
        raise SequenceError(f"{root}: none of the drives of the {name} split has "
                            f"{seq.frames} consecutive left images (image_02/data) there: "
                            f"{', '.join(seq.drives)}; or give a split file (--split FILE)")
    return out


def generate(name: str, root: Path, cache: Path) -> Path:
    """Write the split made from ``root`` under ``cache`` (``splits/generated/``) and
    return its path; the same tree gives the same file."""
    data = ("\n".join(lines(name, root)) + "\n").encode()
    path = cache / "splits" / "generated" / f"{name}-{sha256_bytes(data)[:16]}.txt"
    try:
        if not (path.is_file() and path.read_bytes() == data):
            write_atomic(path, data)
    except OSError as exc:
        raise SequenceError(f"cannot write the split cache {path} ({os_reason(exc)}); set "
                            "ROBODEPTH_CACHE_DIR or pass --split FILE") from None
    return path
