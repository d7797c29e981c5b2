"""``robodepth gt kitti`` and ``robodepth gt nyu``: the ground truth a benchmark's evaluation
compares predictions with, made from the official downloads."""

from __future__ import annotations

import os
from pathlib import Path

import click

from ..errors import RobodepthError
from . import common


@click.group("gt")
def gt_command():
    """Ground-truth depth for evaluation, from the official downloads.

    \b
    KITTI (monodepth2's gt_depths.npz, value for value):
      robodepth gt kitti --root KITTI_RAW --out gt_depths.npz
    NYU Depth V2 (BTS's test layout, from the official labeled file):
      robodepth gt nyu --root nyu_depth_v2_labeled.mat --out NYU_TEST
    """


def _split(value: str, split_format: str, owner: str, root: Path | None = None) -> Path:
    """The split file ``value`` names, chosen by the same rule as a build's ``--split``: a
    standard split of the right format (downloaded and checked on first use, or made from
    the tree under ``root`` for a split of consecutive frames) or a file."""
    from ..sources import splits

    try:
        path = splits.split_path(splits.check_choice(value, split_format, Path.cwd(), owner), root)
    except RobodepthError as exc:  # a bad name, or a standard split that cannot be had
        raise RobodepthError(f"--split: {exc}") from None
    if not path.is_file():
        raise RobodepthError(f"--split: {value}: {'not a file' if path.exists() else 'no such file'}")
    return path


def _stage(bar, text: str) -> None:
    """Show a step that has no count of its own (the maps are all made; compressing takes
    a while) in place of the bar's description."""
    bar.set_description_str(text)
    bar.refresh()


def _bar(total: int, progress: bool):
    from ..progress import bar

    return bar("frame", total, progress=progress)


@gt_command.command("kitti")
@click.option("--root", required=True, type=click.Path(path_type=Path),
              help="KITTI raw root: DATE/calib_*.txt and DATE/DRIVE/velodyne_points/data/*.bin.")
@click.option("--split", metavar="NAME|FILE", default="eigen_test", show_default=True,
              help="Standard split name (eigen_test, or kitti_sequences: consecutive frames made "
                   "from the tree) or a split file in the Eigen format (DATE/DRIVE FRAME SIDE).")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="Output file, e.g. gt_depths.npz.")
@click.option("--jobs", "-j", type=common.Jobs(), default=1, show_default=True, metavar="N|auto",
              help="Worker processes making the maps ('auto' or -1: one per CPU); the file is "
                   "the same for any N. Writing "
                   "the compressed file is serial and the workers' start costs more than they "
                   "save on 2 cores: worth it only with many cores.")
@common.progress_option
def gt_kitti_command(root, split, out, jobs, progress):
    """monodepth2's gt_depths.npz from velodyne scans.

    The ground-truth depth of every split frame, exactly as monodepth2's export_gt_depth.py
    --split eigen makes it (camera 2, lidar depth). OUT is np.savez_compressed(OUT, data=<object array of float32 H x W maps>), in split
    order; np.load(OUT, allow_pickle=True)["data"] reads it, as monodepth2's and the
    benchmark's evaluation scripts do. The file appears only when every map is made.
    """
    from ..files import check_writable
    from ..groundtruth import kitti as gt_kitti

    if not root.is_dir():
        raise RobodepthError(f"--root {root}: not a directory (the KITTI raw root)")
    if out.is_dir():
        raise RobodepthError(f"--out {out}: is a directory; give a file name such as gt_depths.npz")
    if out.suffix.lower() != ".npz":
        raise RobodepthError(f"--out {out}: the ground truth is an .npz file (a numpy zip); "
                             "end it in .npz, e.g. gt_depths.npz")
    check_writable(out, "--out")
    common.will_write(out)
    split_path = _split(split, "eigen", "KITTI ground truth", root)
    frames = gt_kitti.read_frames(split_path)
    with _bar(len(frames), progress) as bar:
        gt_kitti.export(root, frames, out, split_name=str(split_path), progress=bar.update,
                        stage=lambda text: _stage(bar, text), jobs=jobs)
    common.wrote(f"{out} ({len(frames)} depth maps)")


@gt_command.command("nyu")
@click.option("--root", required=True, type=click.Path(path_type=Path),
              help="The official nyu_depth_v2_labeled.mat, or a BTS test folder (SCENE/sync_depth_N.png).")
@click.option("--split", metavar="NAME|FILE", default="nyu_test", show_default=True,
              help="Standard split name or a split file in the NYU format (RGB DEPTH FOCAL).")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="Output folder.")
@common.progress_option
def gt_nyu_command(root, split, out, progress):
    """BTS's NYU test folder from the labeled .mat.

    Writes BTS's test layout for every split frame under OUT. From the labeled .mat: OUT/SCENE/rgb_NNNNN.jpg (frame NNNNN of the file, outside rows
    7..473 and columns 7..631 black, JPEG quality 95, as BTS extracts it) and
    OUT/SCENE/sync_depth_NNNNN.png (uint16 millimetres: rawDepths * 1000 in float32,
    truncated). From a BTS folder: its sync_depth files, copied. Every frame is checked
    (index, scene) before anything is written.
    """
    from ..files import check_writable
    from ..groundtruth import nyu as gt_nyu

    if not root.exists():
        raise RobodepthError(f"--root {root}: no such file or directory")
    if out.exists() and not out.is_dir():
        raise RobodepthError(f"--out {out}: exists and is not a directory")
    build = _enclosing_build(out)
    if build is not None:
        raise RobodepthError(f"--out {out}: inside the build {build}, whose files its manifest "
                             "lists; a build's own ground truth is its gt/: rerun robodepth build "
                             "(it adds the ground truth), or give a folder outside the build")
    if out.is_dir() and any(out.iterdir()):
        raise RobodepthError(f"--out {out}: exists and is not empty; give a new folder (it is "
                             "written whole, at the end)")
    check_writable(out, "--out")
    common.will_write(out)
    split_path = _split(split, "nyu", "NYU ground truth")
    frames = gt_nyu.read_frames(split_path)
    with _bar(len(frames), progress) as bar:
        gt_nyu.export(root, frames, out, split_name=str(split_path), progress=bar.update)
    what = "images and depth maps" if gt_nyu.is_labeled_file(root) else "depth maps"
    common.wrote(f"{out} ({len(frames)} {what})")


def _enclosing_build(path: Path) -> Path | None:
    """The built dataset (a folder with build.json) that ``path`` is, or is inside."""
    from ..output.layout import RECORD

    here = Path(os.path.abspath(path))
    for folder in (here, *here.parents):
        if (folder / RECORD).is_file():
            return folder if path.is_absolute() else Path(os.path.relpath(folder))
    return None
