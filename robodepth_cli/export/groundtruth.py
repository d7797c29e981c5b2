"""The ground truth of an export: one row per image, its depth map in metres as a 2-D float32
array, NaN where there is no measurement, whatever file the build keeps it in
(docs/export.md). ``gt_depths.npz`` is read with robodepth's own unpickler. Each map's
identity is the sha256 of its ``.npy`` file (format 1.0, no pickle); :func:`write_back`
writes the build's files back from the maps, the same values."""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import numpy as np

from ..errors import reraise_interrupt
from ..output.layout import GT_FILE
from .plan import ExportError

MM = 1000.0  # NYU's ground-truth PNGs are in millimetres


def npy_bytes(depth: np.ndarray) -> bytes:
    """``depth`` as a ``.npy`` file (format 1.0, little-endian float32, no pickle)."""
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.ascontiguousarray(depth, dtype="<f4"), version=(1, 0),
                              allow_pickle=False)
    return buf.getvalue()


def from_npy(data: bytes, where: str) -> np.ndarray:
    """A map from its ``.npy`` bytes; :class:`ExportError` naming ``where`` unless it is a
    2-D float32 array (a pickle is never loaded)."""
    try:
        m = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise ExportError(f"{where}: not a depth map (.npy of float32; {exc})") from None
    if m.ndim != 2 or m.dtype != np.float32:
        raise ExportError(f"{where}: not a 2-D float32 depth map (shape {m.shape}, {m.dtype})")
    return m


def map_sha256(depth: np.ndarray) -> str:
    return hashlib.sha256(npy_bytes(depth)).hexdigest()


def read_maps(file: Path, path: str, parts) -> dict[int, np.ndarray]:
    """The maps ``parts`` (indices; 0 for a file of one map) of the build's ground-truth file
    ``file`` (its path in the build: ``path``) in metres, NaN where there is no measurement.
    Only those maps are kept: KITTI's 1.3 GB of maps are never in memory together."""
    from ..groundtruth.read import GroundTruthError, read_gt_file
    from ..imageio import read_depth_png

    try:
        if path == GT_FILE:
            maps = _Some(parts)
            read_gt_file(file, maps)
            lacking = set(parts) - set(maps.kept)
            if lacking:
                raise ExportError(f"{file}: holds no map {min(lacking)}; rerun the build command")
            return {i: _nan_where_zero(m) for i, m in maps.kept.items()}
        if path.endswith(".png"):
            return {0: _nan_where_zero(read_depth_png(file, "ground truth", GroundTruthError) / MM)}
        return {0: from_npy(file.read_bytes(), str(file))}
    except ExportError:
        raise
    except Exception as exc:  # noqa: BLE001 -- the readers' own errors name the file
        reraise_interrupt(exc)
        raise ExportError(f"{file}: cannot be read as ground truth ({exc})") from None


class _Some:
    """Keeps the maps ``wanted`` (indices) of a ground-truth file as it is read (the
    interface of the evaluation's ground truth that its file readers use)."""

    def __init__(self, wanted):
        self.wanted, self.kept, self.prepared, self.appended = set(wanted), {}, 0, 0

    def prepare(self, depth, raw, divisor, where):
        self.prepared += 1
        return np.array(depth, copy=True) if self.prepared - 1 in self.wanted else None

    def append(self, value):
        if value is not None:
            self.kept[self.appended] = value
        self.appended += 1

    def add(self, depth, *args):
        self.append(self.prepare(depth, None, None, ""))


def _nan_where_zero(m: np.ndarray) -> np.ndarray:
    m = np.asarray(m, dtype=np.float32)
    return np.where(m > 0, m, np.float32(np.nan)).astype(np.float32)


def write_back(root: Path, maps: dict[str, list[np.ndarray]], keys: dict[str, list[str]]) -> None:
    """The build's ground-truth files under ``root`` from the export's maps (``maps``: by
    path in the build, in order; ``keys``: their images), with the values the build's files
    hold: KITTI's 0 for no measurement, NYU's millimetres."""
    from ..files import write_atomic
    from ..groundtruth.kitti import frame_key, save_object_npz
    from ..groundtruth.nyu import encode_depth_png

    for path, ms in maps.items():
        target = root / path
        target.parent.mkdir(parents=True, exist_ok=True)
        if path == GT_FILE:
            frames = [frame_key(k) or k for k in keys[path]]  # the file names each map's frame
            save_object_npz(target, [np.nan_to_num(m, nan=0.0) for m in ms], frames)
        elif path.endswith(".png"):
            mm = np.rint(np.nan_to_num(ms[0].astype(np.float64) * MM, nan=0.0)).astype(np.uint16)
            write_atomic(target, encode_depth_png(mm))
        else:
            write_atomic(target, npy_bytes(ms[0]))
