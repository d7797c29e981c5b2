"""Where a build's depth-aware corruptions get each source image's depth.

A :class:`DepthSource` gives the depth of one source (by its key) in metres, NaN where
missing, at the build's output size or at its own with the same aspect ratio (the
corruption engine fills and resizes it: :mod:`robodepth_cli.corruptions.depth`). It is
small and picklable (the renderer carries it to the workers) and reads its files lazily.
The renderer asks it for a source's depth only when a job needs it; :func:`depth_for`
chooses it for a build.

- :class:`NyuDepth`: NYU Depth V2's own dense ground truth: the split line's
  ``sync_depth`` PNG (millimetres, 0 missing) under a BTS test folder, or the labeled
  ``.mat``'s ``rawDepths`` (metres, 0 missing).
- :class:`KittiLidarDepth`: KITTI's velodyne scan projected into camera 2 (the rules of
  the ground truth, :func:`~robodepth_cli.groundtruth.kitti.depth_map`), then *densified at the output size*:
  each output pixel takes the nearest return (smallest depth) among the projected points
  falling in it, and every pixel without one takes the depth of the nearest pixel with one
  (Euclidean distance, the engine's fill rule), so the sky continues the highest returns.
- :class:`FolderDepth`: a custom build's ``--depth DIR`` or a zero-shot preset's ground
  truth, paired and read as its ground truth is (:mod:`robodepth_cli.sources.depth_pairs`), turned upright with
  its image (EXIF orientation), then brought to the output size by :func:`at_size`.
- :class:`PredictedDepth` (``--scene-depth PRED``): a model's predictions for
  the clean images, in metres by the rule of :mod:`robodepth_cli.sources.predicted`.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from ..errors import InvalidValueError, RobodepthError, os_reason
from ..sources.depth_io import DepthError

_VERSION = "1"  # bump when a source gives other depths for the same files
DEPTH = "depth="  # the start of a depth source's fingerprint in a manifest row's params


def files_stamp(paths) -> str:
    """The sha256 of the files ``paths`` (in order) taken together; a file that cannot be read
    counts as ``missing`` (its output fails with the reason when it is rendered)."""
    from ..files import sha256_file

    parts = []
    for p in paths:
        try:
            parts.append(sha256_file(p))
        except OSError:
            parts.append("missing")
    return hashlib.sha256(" ".join(parts).encode("ascii")).hexdigest()


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
        """The manifest's account of how a depth-aware output's depth is made (the same for
        every source): a row made from another depth source is made again."""
        return f"{DEPTH}{self.kind}/v{_VERSION}"

    def stamp(self, key: str) -> str:
        """What identifies source ``key``'s depth: the sha256 of the files it is made from
        (a row made from other bytes is made again); "" where they are not hashed."""
        return ""


class NyuDepth(DepthSource):
    kind = "nyu-ground-truth"
    method = ("the dataset's dense ground truth: sync_depth PNG (mm / 1000) or the labeled "
              "file's rawDepths (m); 0 is missing")

    def __init__(self, root: Path, depth_paths: dict[str, tuple[str, str]]):
        self.root = str(root)
        self.paths = depth_paths  # key -> (RGB path, depth path) as the split lists them

    def depth(self, key, shape):
        from ..groundtruth import nyu as nyu_labeled

        rgb, rel = self.paths[key]
        root = Path(self.root)
        if root.is_file():
            labeled = nyu_labeled.opened(root)
            d = labeled.depth(nyu_labeled.frame_index(labeled, rgb)).astype(np.float64)
        else:
            from ..sources.depthfile import read_depth

            return read_depth(root / rel, nyu_labeled.DEPTH_SCALE)
        d[~(d > 0)] = np.nan
        return d

    def stamp(self, key):
        # A frame inside the labeled .mat is not hashed, as its image is not: that would read
        # the whole multi-GB file for every image.
        root = Path(self.root)
        return "" if root.is_file() else files_stamp([root / self.paths[key][1]])


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
        from ..groundtruth import kitti as kitti_raw

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

    def stamp(self, key):
        from ..groundtruth import kitti as kitti_raw

        frame = kitti_raw.frame_key(key)
        if frame is None:
            return ""
        folder, number = frame.split()
        date = Path(self.root) / folder.split("/")[0]
        return files_stamp([Path(self.root) / folder / "velodyne_points" / "data" / f"{number}.bin",
                            date / kitti_raw.CAM_TO_CAM, date / kitti_raw.VELO_TO_CAM])


class FolderDepth(DepthSource):
    method = ("the depth map paired with each image (the ground truth's pairing rule and reader), "
              "turned with the image by its EXIF orientation; at another size than the output, "
              "holes filled by the nearest valid pixel, then each output pixel the depth under "
              "its centre (nearest neighbour)")

    def __init__(self, kind: str, options, root: Path, in_root: bool,
                 sources: dict[str, tuple[str, int]]):
        from ..sources.depth_pairs import rule_of

        self.kind = kind
        self.rule = rule_of(options, Path(root), in_root)
        self.root = str(root)
        self.sources = sources  # key -> (path relative to the root, EXIF orientation)

    def describe(self):
        return {**super().describe(), "directory": self.rule.directory}

    @property
    def fingerprint(self):
        # The rule reads the files: another --depth-scale (or pattern, mask, form) is another
        # depth. Only the options given are named: "depth=depth-folder/v1(scale=1000.0)".
        r = self.rule
        named = {"pattern": r.pattern, "mask": r.mask, "camera": r.camera, "scale": r.scale,
                 "format": r.fmt, "size": None if r.same_size else "any"}
        given = ",".join(f"{k}={v}" for k, v in named.items() if v is not None)
        return super().fingerprint + (f"({given})" if given else "")

    def stamp(self, key):
        from ..sources.depth_pairs import pair

        found = pair(self.rule, self.sources[key][0])
        if found.error:
            return "missing"
        root = Path(self.rule.directory)
        return files_stamp([root / f for f in (found.depth, found.mask, found.camera) if f])

    def depth(self, key, shape):
        from PIL import Image

        from ..sources.depth_io import DepthError
        from ..sources.depth_pairs import pair, read_pair

        rel, orientation = self.sources[key]
        found = pair(self.rule, rel)
        try:
            with Image.open(Path(self.root) / rel) as im:
                stored = im.height, im.width
        except Exception:  # noqa: BLE001 (the image's own failure is reported with it)
            stored = None
        d = read_pair(self.rule, found, stored)
        where = Path(self.rule.directory) / found.depth
        if self.rule.same_size and stored is not None and d.shape != stored:
            raise DepthError(f"{where}: depth map of {d.shape[0]} x {d.shape[1]}, its image {rel} "
                             f"is {stored[0]} x {stored[1]} (--depth-size any allows it)")
        if not (np.isfinite(d) & (d > 0)).any():
            raise DepthError(f"{where}: no valid depth (every pixel 0 or invalid)")
        return at_size(upright(d, orientation), shape)


# The EXIF orientations as numpy operations on a stored array: what ImageOps.exif_transpose
# does to the image, so that depth and pixels stay aligned.
_UPRIGHT = {2: lambda a: a[:, ::-1], 3: lambda a: a[::-1, ::-1], 4: lambda a: a[::-1],
            5: lambda a: a.T, 6: lambda a: np.rot90(a, -1), 7: lambda a: a[::-1, ::-1].T,
            8: lambda a: np.rot90(a, 1)}


def upright(d: np.ndarray, orientation: int) -> np.ndarray:
    """The stored map ``d`` turned as EXIF ``orientation`` turns its image (1: as stored)."""
    turn = _UPRIGHT.get(orientation)
    return d if turn is None else np.ascontiguousarray(turn(d))


def at_size(d: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A depth map (NaN where missing) for an output of ``shape`` (H, W): as it is when it
    already has that size; else holes filled by the nearest valid pixel (the corruptions'
    own rule), then each output pixel the depth under its centre, whatever the aspect ratio."""
    if d.shape == tuple(shape):
        return d
    from ..corruptions.depth import fill_missing, nearest_resize

    return nearest_resize(fill_missing(d), shape)


class PredictedDepth(DepthSource):
    kind = "predictions"

    def __init__(self, pred: Path, record: dict, keys: dict[str, int], own: DepthSource | None):
        from ..predictions import model_identity
        from ..sources import predicted

        self.pred = str(pred)
        self.model = str(record.get("model"))
        self.identity = model_identity(record)
        self.disparity = record["evaluate"]["kind"] == "disp"
        self.rule = predicted.conversion(record, pred)
        self.keys = keys  # key -> index in the predicting build's split order
        self.own = own
        self._array = None
        self.method = ("a model's predictions for the clean images: " + (
            "metric, as metres" if self.rule == "metric" else
            f"relative, median-scaled per image to the dataset's own depth ({own and own.kind})")
            + "; at the output size by nearest neighbour after filling holes")

    @classmethod
    def open(cls, pred: Path, own: DepthSource | None) -> PredictedDepth:
        """The depth of ``PRED``, checked before any work; ``own``: the dataset's own depth,
        which relative maps are scaled to. :class:`RobodepthError` naming ``--scene-depth``."""
        from .. import predictions
        from ..sources import predicted

        try:
            record = predicted.read_record(pred)
            rule = predicted.conversion(record, pred)
        except InvalidValueError as exc:
            raise exc.at("--scene-depth") from None
        if rule == "median" and own is None:
            raise RobodepthError(f"--scene-depth: {pred}: the maps of {record.get('model')} are relative "
                                 "(median-scaled to the dataset's own depth) and this build has no depth "
                                 "of its own: give --depth DIR too, or a metric model's predictions")
        built = Path(str(record.get("dataset_path")))
        try:
            keys = json.loads((built / "build.json").read_text(encoding="utf-8"))["split"]["keys"]
        except (OSError, ValueError, KeyError, TypeError):
            raise RobodepthError(f"--scene-depth: {pred}: the build its {predictions.RECORD} names ({built}) has no "
                                 "readable build.json listing its images (moved or deleted?)") from None
        if predictions.split_digest(keys) != record.get("split_sha256"):
            raise RobodepthError(f"--scene-depth: {pred}: {built} holds other images than when the "
                                 "predictions were made; predict again")
        src = cls(pred, record, {k: i for i, k in enumerate(keys)}, own)
        if src._source() is None:
            raise RobodepthError(f"--scene-depth: {pred}: no predictions of the clean images "
                                 "(clean.npy, clean.npz or clean/); run robodepth predict with "
                                 "--variants clean")
        return src

    def __getstate__(self):
        return {**self.__dict__, "_array": None}

    @property
    def fingerprint(self):
        return f"{DEPTH}predictions:{self.identity}"

    def stamp(self, key):
        try:
            m = np.ascontiguousarray(self._read(key))
        except DepthError:
            return "missing"
        own = self.own.stamp(key) if self.rule == "median" else ""
        head = f"{m.dtype.str}{m.shape}{own}".encode("ascii")
        return hashlib.sha256(head + m.tobytes()).hexdigest()

    def describe(self):
        return {**super().describe(), "model": self.model, "identity": self.identity,
                "predictions": self.pred, "rule": self.rule}

    def _source(self) -> Path | None:
        from ..predictions import clean_source

        return clean_source(Path(self.pred))

    def _read(self, key: str) -> np.ndarray:
        if key not in self.keys:
            raise DepthError(f"{self.pred}: no prediction for {key} (the predictions are of another "
                             "build's images)")
        i, src = self.keys[key], self._source()
        if src is not None and src.is_dir():
            from ..predictions import image_files

            path = image_files(src, [key])[0]
            try:
                return np.load(path, allow_pickle=False)
            except (OSError, ValueError, EOFError) as exc:
                reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
                raise DepthError(f"{path}: cannot read the prediction ({reason})") from None
        try:
            if self._array is None:
                if src.suffix == ".npz":
                    with np.load(src, allow_pickle=False) as z:
                        self._array = z[z.files[0]]
                else:
                    self._array = np.load(src, mmap_mode="r", allow_pickle=False)
            return np.array(self._array[i])
        except (OSError, ValueError, EOFError, IndexError) as exc:
            reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
            raise DepthError(f"{src}: cannot read prediction {i} ({reason})") from None

    def depth(self, key, shape):
        from ..corruptions.depth import FAR, nearest_resize

        m = self._read(key)
        if m.ndim != 2 or m.dtype.kind not in "fiu" or not np.isfinite(m).all():
            raise DepthError(f"{self.pred}: the prediction for {key} is not a finite 2-D map")
        m = m.astype(np.float64)
        with np.errstate(divide="ignore"):
            d = np.where(m > 0, 1.0 / np.where(m > 0, m, 1.0), FAR) if self.disparity \
                else np.where(m > 0, m, np.nan)
        d = at_size(d, shape)
        if self.rule == "median":
            own = nearest_resize(np.asarray(self.own.depth(key, shape), dtype=np.float64), shape)
            valid = np.isfinite(own) & (own > 0) & np.isfinite(d) & (d < FAR)
            if not valid.any():
                raise DepthError(f"{key}: no pixel where both the prediction and the dataset's own "
                                 "depth are valid, so no median scaling")
            s = np.median(own[valid]) / np.median(d[valid])
            d = np.where(d < FAR, d * s, FAR)
        return d


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


def depth_for(ds, cfg, root: Path, split_path: str | None, sources=()) -> DepthSource | None:
    """Where the depth-aware corruptions among ``cfg.variants`` (names or chains) of a build
    of dataset ``ds`` get each source's depth; None when no variant needs depth. ``sources``:
    the build's sources (``key``, ``rel``, ``orientation``), which a custom build's depth
    folder pairs by path. The configuration has already refused depth-aware variants for a
    build without a depth source."""
    if not depth_aware(ds, cfg.variants):
        return None
    own = own_depth(ds, cfg, root, split_path, sources)
    if cfg.options.scene_depth:
        return PredictedDepth.open(Path(cfg.options.scene_depth), own)
    return own


def depth_aware(ds, variants) -> list[str]:
    """The depth-aware corruptions named in ``variants`` (names or chains) of dataset ``ds``."""
    from ..corruptions.chains import looks_like_chain, parse_chain

    aware = set(ds.depth_variant_names())
    names = (n for v in variants for n in (parse_chain(v).names if looks_like_chain(v) else (v,)))
    return list(dict.fromkeys(n for n in names if n in aware))


def missing_depth(ds, values: dict, options) -> tuple[str, str] | None:
    """``(config key, reason)`` when the variants of a configuration (``values``: its
    variant key and ``compose``) need depth that a build of ``ds`` with ``options`` lacks;
    None otherwise."""
    if not ds.leveled or ds.has_depth(options):
        return None
    for key in (ds.variant_key, "compose"):
        aware = depth_aware(ds, values.get(key, ()))
        if aware:
            return key, (f"{aware[0]} needs the scene's depth and this {ds.name} build has none: give "
                         "--depth DIR (a depth map per image) or --scene-depth PRED (robodepth "
                         "predict's output for the clean images)")
    return None


def own_depth(ds, cfg, root: Path, split_path: str | None, sources) -> DepthSource | None:
    """The dataset's own depth (its ground truth, or a custom build's depth folder); None for
    a custom build without one."""
    if ds.split_format == "eigen":
        return KittiLidarDepth(Path(root))
    if ds.split_format == "nyu":
        from ..sources.datasets import read_split

        entries = read_split(Path(split_path or ""), "nyu")
        return NyuDepth(Path(root), {e.key: (e.fields[0], e.fields[1]) for e in entries})
    if not (cfg.options.depth or ds.depth_in_root):
        return None
    kind = f"{ds.name}-ground-truth" if ds.depth_in_root else "depth-folder"
    return FolderDepth(kind, cfg.options, Path(root), ds.depth_in_root,
                       {s.key: (s.rel, s.orientation) for s in sources if s.rel})
