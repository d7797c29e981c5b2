"""Where a build's depth-aware corruptions get each source image's depth.

A :class:`DepthSource` gives the depth of one source (by its key) in metres, NaN where
missing, at the build's output size or at its own with the same aspect ratio (the
corruption engine fills and resizes it: :mod:`robodepth_cli.corruptions._depth`). It is
small and picklable (the renderer carries it to the workers) and reads its files lazily.
The renderer asks it for a source's depth only when a job needs it; :func:`depth_for`
chooses it for a build. A custom build's depth folder (``build custom --depth DIR``) plugs
in as one more :class:`DepthSource` chosen there (and the dataset's
``depth_variant_names`` then lists the depth-aware corruptions).

- :class:`NyuDepth`: NYU Depth V2's own dense ground truth: the split line's
  ``sync_depth`` PNG (millimetres, 0 missing) under a BTS test folder, or the labeled
  ``.mat``'s ``rawDepths`` (metres, 0 missing).
- :class:`KittiLidarDepth`: KITTI's velodyne scan projected into camera 2 (the rules of
  the ground truth, :func:`~.kitti_raw.depth_map`), then *densified at the output size*:
  each output pixel takes the nearest return (smallest depth) among the projected points
  falling in it, and every pixel without one takes the depth of the nearest pixel with one
  (Euclidean distance, the engine's fill rule), so the sky continues the highest returns.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RobodepthError

_VERSION = "1"  # bump when a source gives other depths for the same files


class DepthSource:
    """The depth of the sources of one build."""

    kind = ""
    method = ""

    def depth(self, key: str, shape: tuple[int, int]) -> np.ndarray:
        """The depth of source ``key`` in metres (NaN where missing) for an output of
        ``shape`` (H, W); :class:`RobodepthError` naming the file when it cannot be read."""
        raise NotImplementedError

    def describe(self) -> dict:
        """What the build record keeps: the kind and the method."""
        return {"kind": self.kind, "method": self.method, "version": _VERSION}

    @property
    def fingerprint(self) -> str:
        """The manifest's account of the depth behind a depth-aware output: a row made from
        another depth source is made again."""
        return f"depth={self.kind}/v{_VERSION}"


class NyuDepth(DepthSource):
    kind = "nyu-ground-truth"
    method = ("the dataset's dense ground truth: sync_depth PNG (mm / 1000) or the labeled "
              "file's rawDepths (m); 0 is missing")

    def __init__(self, root: Path, depth_paths: dict[str, tuple[str, str]]):
        self.root = str(root)
        self.paths = depth_paths  # key -> (RGB path, depth path) as the split lists them

    def depth(self, key, shape):
        from . import nyu_labeled

        rgb, rel = self.paths[key]
        root = Path(self.root)
        if root.is_file():
            labeled = nyu_labeled.opened(root)
            d = labeled.depth(nyu_labeled.frame_index(labeled, rgb)).astype(np.float64)
        else:
            from .depthfile import read_depth

            return read_depth(root / rel, nyu_labeled.DEPTH_SCALE)
        d[~(d > 0)] = np.nan
        return d


class KittiLidarDepth(DepthSource):
    kind = "kitti-lidar-densified"
    method = ("velodyne projected into camera 2 as for the ground truth, the nearest return per "
              "output pixel, empty pixels from the nearest pixel with a return")

    def __init__(self, root: Path):
        self.root = str(root)
        self._calibs: dict = {}

    def __getstate__(self):
        return {"root": self.root, "_calibs": {}}

    def depth(self, key, shape):
        from . import kitti_raw

        frame = kitti_raw.frame_key(key)
        if frame is None or "/image_02/" not in key:
            raise RobodepthError(f"{key}: depth from the velodyne is made for camera 2 (image_02) only")
        folder, number = frame.split()
        date = folder.split("/")[0]
        root = Path(self.root)
        if date not in self._calibs:
            self._calibs[date] = kitti_raw.Calibration.load(root / date)
        calib = self._calibs[date]
        velo = root / folder / "velodyne_points" / "data" / f"{number}.bin"
        sparse = kitti_raw.depth_map(calib, kitti_raw.load_velodyne(velo))
        return densify_grid(sparse, shape)


def densify_grid(sparse: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A sparse depth map (0 where empty) at the output size ``shape``: each output pixel
    the smallest depth among the input pixels that fall in it (NaN where none)."""
    h0, w0 = sparse.shape
    h, w = shape
    v, u = np.nonzero(sparse > 0)
    out = np.full(h * w, np.inf)
    cells = (v * h // h0) * w + (u * w // w0)
    np.minimum.at(out, cells, sparse[v, u].astype(np.float64))
    out[np.isinf(out)] = np.nan
    return out.reshape(h, w)


def depth_for(ds, variants, root: Path, split_path: str | None) -> DepthSource | None:
    """Where the depth-aware corruptions among ``variants`` (names or chains) of a build of
    dataset ``ds`` get each source's depth; None when no variant needs depth. The
    configuration has already refused them for a dataset without depth
    (:meth:`~.datasets.Dataset.depth_variant_names` is empty)."""
    from ..corruptions.chains import looks_like_chain, parse_chain

    names = {n for v in variants for n in (parse_chain(v).names if looks_like_chain(v) else (v,))}
    if not names & set(ds.depth_variant_names()):
        return None
    if ds.split_format == "eigen":
        return KittiLidarDepth(Path(root))
    from .datasets import read_split

    entries = read_split(Path(split_path or ""), "nyu")
    return NyuDepth(Path(root), {e.key: (e.fields[0], e.fields[1]) for e in entries})
