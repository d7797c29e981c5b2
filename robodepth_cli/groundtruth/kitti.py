"""KITTI ground-truth depth from the raw velodyne scans, value for value as the benchmark's:
the float32 arrays of monodepth2's ``export_gt_depth.py --split eigen``, quirks included
(docs/ground-truth.md gives the rules), without that script's Python loop over duplicate
pixels. :func:`depth_map` computes one map, :func:`export` writes them in the same file
format."""

from __future__ import annotations

import pickle
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from ..errors import RobodepthError, cannot_write, os_reason
from ..sourcekeys import KITTI_PREFIX

CAM_TO_CAM = "calib_cam_to_cam.txt"
VELO_TO_CAM = "calib_velo_to_cam.txt"
NPZ_MEMBER = "data.npy"  # np.savez_compressed(out, data=...) names its member this way
# Beside the maps, the frame of each (KittiFrame.key, split order) as a plain string array:
# monodepth2's reader takes ["data"] and never sees it; ours checks the order against the split.
KEYS_MEMBER = "keys.npy"


class GroundTruthError(RobodepthError):
    """Input that ground truth cannot be made from, or ground truth that cannot be read
    for an evaluation; the message names the file."""


@dataclass(frozen=True)
class KittiFrame:
    """One line of an Eigen-format split, as the ground truth needs it."""

    line: int  # 1-based line number in the split file
    folder: str  # DATE/DRIVE
    frame: int

    @property
    def date(self) -> str:
        return self.folder.split("/")[0]

    def velodyne(self, root: Path) -> Path:
        return Path(root) / self.folder / "velodyne_points" / "data" / f"{self.frame:010d}.bin"

    @property
    def key(self) -> str:
        """``DATE/DRIVE NNNNNNNNNN``: which frame a ground-truth map is of (:data:`KEYS_MEMBER`)."""
        return f"{self.folder} {self.frame:010d}"


def frame_key(image_key: str) -> str | None:
    """The :attr:`KittiFrame.key` of a KITTI build's image key
    (``kitti_data/DATE/DRIVE/image_02/data/NNNNNNNNNN.png``), or None for another form."""
    parts = image_key.split("/")
    if parts and parts[0] == KITTI_PREFIX:
        parts = parts[1:]
    if len(parts) < 4 or parts[-2] != "data" or not parts[-1].split(".")[0].isdigit():
        return None
    return f"{'/'.join(parts[:-3])} {int(parts[-1].split('.')[0]):010d}"


def read_frames(split: Path) -> list[KittiFrame]:
    """The frames of an Eigen-format split file (``DATE/DRIVE FRAME SIDE`` per line), with
    the checks every split gets (:func:`robodepth_cli.sources.datasets.read_split`)."""
    from ..sources.datasets import read_split

    return [KittiFrame(e.line, e.fields[0], int(e.fields[1])) for e in read_split(split, "eigen")]


# --- calibration ---------------------------------------------------------------------------

def read_calib_file(path: Path) -> dict[str, str]:
    """``KEY: VALUE`` lines of a KITTI calibration file, split at the first ``:``, key and
    value stripped; blank lines are ignored. :class:`GroundTruthError` (naming the file and
    line) for an unreadable file or a line without ``:``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise GroundTruthError(f"{path}: no such calibration file") from None
    except (OSError, UnicodeDecodeError) as exc:
        reason = os_reason(exc) if isinstance(exc, OSError) else "not a text file"
        raise GroundTruthError(f"{path}: cannot read the calibration ({reason})") from None
    values = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        if ":" not in line:
            raise GroundTruthError(f"{path}:{n}: not a 'KEY: values' line")
        key, value = line.split(":", 1)
        values[key.strip()] = value.strip()
    return values


def _numbers(calib: dict[str, str], key: str, count: int, path: Path) -> np.ndarray:
    """The ``count`` numbers of ``key`` as float64, or :class:`GroundTruthError`."""
    if key not in calib:
        raise GroundTruthError(f"{path}: no key {key!r}")
    fields = calib[key].split()
    try:
        values = np.array([float(f) for f in fields])
    except ValueError:
        raise GroundTruthError(f"{path}: key {key!r}: {calib[key]!r} is not a list of numbers") from None
    if values.size != count:
        raise GroundTruthError(f"{path}: key {key!r} has {values.size} values, expected {count}")
    return values


@dataclass(frozen=True)
class Calibration:
    """The velodyne-to-image projection of camera 2 for one recording date."""

    projection: np.ndarray  # 3 x 4 float64
    shape: tuple[int, int]  # (H, W) of the rectified image

    @classmethod
    def load(cls, date_dir: Path) -> "Calibration":
        """Read ``date_dir``'s two calibration files (see the module docstring)."""
        c2c_path, v2c_path = Path(date_dir) / CAM_TO_CAM, Path(date_dir) / VELO_TO_CAM
        cam2cam = read_calib_file(c2c_path)
        velo2cam = read_calib_file(v2c_path)
        rot = _numbers(velo2cam, "R", 9, v2c_path).reshape(3, 3)
        trans = _numbers(velo2cam, "T", 3, v2c_path)
        size = _numbers(cam2cam, "S_rect_02", 2, c2c_path)
        rect = _numbers(cam2cam, "R_rect_00", 9, c2c_path).reshape(3, 3)
        p_rect = _numbers(cam2cam, "P_rect_02", 12, c2c_path).reshape(3, 4)
        if not np.all(np.isfinite(size)) or not np.all(size >= 1):
            raise GroundTruthError(f"{c2c_path}: key 'S_rect_02' is not an image size: {cam2cam['S_rect_02']!r}")
        # The same float64 operations, in the same order, as the reference: the projected
        # coordinates are rounded, so a different last bit could move a point.
        v2c = np.vstack((np.hstack((rot, trans[..., np.newaxis])), np.array([0, 0, 0, 1.0])))
        r_cam2rect = np.eye(4)
        r_cam2rect[:3, :3] = rect
        projection = np.dot(np.dot(p_rect, r_cam2rect), v2c)
        h, w = (int(x) for x in size[::-1].astype(np.int32))
        return cls(projection, (h, w))


# --- points and depth ------------------------------------------------------------------------

def load_velodyne(path: Path) -> np.ndarray:
    """The scan at ``path`` as float32 N x 4 with the fourth column set to 1.
    :class:`GroundTruthError` for a missing file, an empty one, or one whose size is not a
    multiple of 16 bytes (a truncated download)."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise GroundTruthError(f"{path}: no such velodyne file") from None
    except OSError as exc:
        raise GroundTruthError(f"{path}: cannot read ({os_reason(exc)})") from None
    if size == 0:
        raise GroundTruthError(f"{path}: 0 bytes: an empty scan (a failed download?)")
    if size % 16:
        raise GroundTruthError(f"{path}: {size} bytes is not a whole number of points (16 bytes "
                               f"each); truncated?")
    try:
        points = np.fromfile(path, dtype=np.float32)
    except OSError as exc:
        raise GroundTruthError(f"{path}: cannot read ({os_reason(exc)})") from None
    if points.size * 4 != size:  # the file changed under us
        raise GroundTruthError(f"{path}: read {points.size * 4} of {size} bytes")
    points = points.reshape(-1, 4)
    points[:, 3] = 1.0
    return points


def depth_map(calib: Calibration, velo: np.ndarray) -> np.ndarray:
    """The ground-truth depth map (float32, H x W, 0 where there is no point) of the scan
    ``velo`` (float32 N x 4, fourth column 1), by the rules of the module docstring.

    Duplicates are resolved with one stable sort by group index instead of a loop: the
    first element of each group in sorted order is the group's first point, and the
    group minimum comes from ``np.minimum.reduceat``.
    """
    h, w = calib.shape
    velo = velo[velo[:, 0] >= 0, :]
    # np.dot(P, velo.T).T, exactly as the reference writes it: another formulation (e.g.
    # velo @ P.T) may round differently in the last bit and move a point by one pixel.
    pts = np.dot(calib.projection, velo.T).T
    with np.errstate(divide="ignore", invalid="ignore"):
        pts[:, :2] = pts[:, :2] / pts[:, 2][..., np.newaxis]
    u = np.round(pts[:, 0]) - 1
    v = np.round(pts[:, 1]) - 1
    keep = (u >= 0) & (v >= 0) & (u < w) & (v < h)  # NaN and inf (points at z = 0) fail these
    u = u[keep].astype(np.intp)
    v = v[keep].astype(np.intp)
    d = velo[keep, 0]  # float32: the lidar x, exactly as the reference's float64 holds it

    depth = np.zeros((h, w), dtype=np.float32)
    # The last point on a pixel wins. Stated explicitly: numpy does not promise an order for
    # repeated indices in ``depth[v, u] = d``.
    pixels, last = np.unique((v * w + u)[::-1], return_index=True)
    depth.flat[pixels] = d[len(d) - 1 - last]
    group = v * (w - 1) + u - 1
    order = np.argsort(group, kind="stable")
    if len(order):
        sorted_group = group[order]
        starts = np.flatnonzero(np.r_[True, sorted_group[1:] != sorted_group[:-1]])
        shared = np.diff(np.r_[starts, len(order)]) > 1
        first = order[starts[shared]]
        smallest = np.minimum.reduceat(d[order], starts)[shared]
        depth[v[first], u[first]] = smallest
    depth[depth < 0] = 0
    return depth


# --- export ---------------------------------------------------------------------------------

def missing_velodyne(root: Path, frames: Sequence[KittiFrame]) -> list[KittiFrame]:
    """The frames whose velodyne file is not under ``root``."""
    return [f for f in frames if not f.velodyne(root).is_file()]


def depth_maps(root: Path, frames: Sequence[KittiFrame], split_name: str = "split",
               progress: Callable[[int], object] | None = None, jobs: int = 1) -> Iterable[np.ndarray]:
    """The depth map of every frame, in split order, one at a time (calibrations are read
    once per date). A problem raises :class:`GroundTruthError` naming the split line and file.
    With ``jobs`` > 1, worker processes make the maps (:func:`_depth_maps_in_workers`)."""
    if jobs > 1 and len(frames) > FRAMES_PER_TASK:
        yield from _depth_maps_in_workers(root, frames, split_name, progress, jobs)
        return
    root = Path(root)
    calibs: dict[str, Calibration] = {}
    for f in frames:
        yield _frame_depth(root, f, split_name, calibs)
        if progress:
            progress(1)


def _frame_depth(root: Path, f: KittiFrame, split_name: str, calibs: dict) -> np.ndarray:
    try:
        if f.date not in calibs:
            calibs[f.date] = Calibration.load(root / f.date)
        velo = load_velodyne(f.velodyne(root))
        depth = depth_map(calibs[f.date], velo)
        if not np.any(depth > 0):
            # Evaluation would refuse the map much later, without naming the scan.
            raise GroundTruthError(f"{f.velodyne(root)}: no point falls in camera 2's image in "
                                   f"front of the car (of {len(velo)} points); a damaged scan?")
    except GroundTruthError as exc:
        raise GroundTruthError(f"{split_name}:{f.line}: {exc}") from None
    return depth


# Frames per task of a worker: large enough that sending tasks costs nothing, small enough
# that the main process (which keeps every map) is never far behind the workers.
FRAMES_PER_TASK = 16


def _depth_maps_in_workers(root: Path, frames: Sequence[KittiFrame], split_name: str,
                           progress, jobs: int) -> Iterable[np.ndarray]:
    """:func:`depth_maps` by ``jobs`` fresh processes, each making runs of
    :data:`FRAMES_PER_TASK` consecutive frames with the same code, so every map is the same
    to the last bit; yielded in split order (an error: the first in split order)."""
    from ..workers import in_order

    runs = [list(frames[i:i + FRAMES_PER_TASK]) for i in range(0, len(frames), FRAMES_PER_TASK)]
    tasks = [(str(root), run, split_name) for run in runs]
    for run, maps in zip(runs, in_order(_run_maps, tasks, min(jobs, len(runs)), _start_worker)):
        yield from (_unpack(*m) for m in maps)
        if progress:
            progress(len(run))


def _pack(depth: np.ndarray) -> tuple:
    """A map as (shape, flat indices, values) of its pixels whose bits are not all zero:
    lidar maps are ~95% empty, and sending the whole maps back from the workers cost more
    than making them. -0.0 (a point at depth -0, kept as the rules keep it) is sent too."""
    flat = depth.reshape(-1)
    where = np.flatnonzero(flat.view(np.uint32)).astype(np.int32)
    return depth.shape, where, flat[where]


def _unpack(shape, where, values) -> np.ndarray:
    depth = np.zeros(shape, dtype=np.float32)  # numpy's own dtype: the npz's bytes stay those of one job
    depth.reshape(-1)[where] = values
    return depth


_WORKER_CALIBS: dict[str, Calibration] = {}


def _start_worker() -> None:
    from threadpoolctl import threadpool_limits

    threadpool_limits(1, user_api="blas")  # as export: BLAS threads only cost time here


def _run_maps(root: str, run: list[KittiFrame], split_name: str) -> list[tuple]:
    return [_pack(_frame_depth(Path(root), f, split_name, _WORKER_CALIBS)) for f in run]


def export(root: Path, frames: Sequence[KittiFrame], out: Path, split_name: str = "split",
           progress: Callable[[int], object] | None = None,
           stage: Callable[[str], object] | None = None, jobs: int = 1) -> Path:
    """Write the depth maps of ``frames`` to ``out`` as monodepth2's ``gt_depths.npz``
    (:func:`save_object_npz`), made by ``jobs`` processes (:func:`depth_maps`). Every
    velodyne file is checked to exist before any work; ``out`` is written only once every
    map is made, atomically. ``progress(1)`` follows each map; ``stage(text)`` announces
    the last step, compressing and writing (a minute for the 697 Eigen maps)."""
    root = Path(root)
    missing = missing_velodyne(root, frames)
    if missing:
        f = missing[0]
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise GroundTruthError(f"{split_name}:{f.line}: {f.velodyne(root)}: no such velodyne file{more}")
    from threadpoolctl import threadpool_limits

    # The projection is a 3 x 4 by 4 x N product: BLAS threads only cost time on it (twice
    # the CPU, far more wall time on a busy machine) and do not change its result.
    with threadpool_limits(1, user_api="blas"):
        maps = list(depth_maps(root, frames, split_name, progress, jobs))
    if stage:
        stage(f"compressing and writing {out}")
    try:
        save_object_npz(out, maps, [f.key for f in frames])
    except OSError as exc:
        raise GroundTruthError(cannot_write(out, exc)) from None
    return Path(out)


def save_object_npz(path: Path, arrays: Sequence[np.ndarray], keys: Sequence[str] | None = None) -> str:
    """Write ``arrays`` as ``np.savez_compressed(path, data=<1-D object array of them>)``
    does (a deflated zip holding ``data.npy``), so ``np.load(path, allow_pickle=True)["data"][i]``
    is ``arrays[i]``, and return the file's sha256. ``keys`` (one per array, e.g.
    :attr:`KittiFrame.key`) go into a second member, ``keys.npy``, a plain string array.

    Unlike ``np.savez_compressed``, which pickles with protocol 4 and so keeps a bytes copy
    of every array alive until the end, the object array is pickled with protocol 5: each
    array's buffer goes straight into the compressor, no copy of the maps is made. The
    file appears atomically (temporary name in the same directory, then rename).
    """
    from ..files import atomic_output, sha256_stream

    obj = np.empty(len(arrays), dtype=object)
    for i, a in enumerate(arrays):  # item by item: obj[:] = arrays would try to broadcast
        obj[i] = np.ascontiguousarray(a)
    with atomic_output(path) as raw:
        with zipfile.ZipFile(raw, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
            with zf.open(NPZ_MEMBER, "w", force_zip64=True) as member:
                np.lib.format.write_array_header_1_0(member, np.lib.format.header_data_from_array_1_0(obj))
                pickle.Pickler(member, protocol=5).dump(obj)
            if keys is not None:
                if len(keys) != len(arrays):
                    raise ValueError(f"{len(keys)} keys for {len(arrays)} maps")
                with zf.open(KEYS_MEMBER, "w") as member:
                    np.lib.format.write_array(member, np.array(list(keys), dtype=str), allow_pickle=False)
        raw.seek(0)
        return sha256_stream(raw)
