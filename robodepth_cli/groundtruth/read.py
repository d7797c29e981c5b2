"""The ground truth of a built dataset (KITTI's ``gt_depths.npz``, NYU's 16-bit PNGs in
millimetres), read once, map by map; a map is kept as its valid pixels when that is smaller
(KITTI's sparse lidar maps). The pickle is read with only numpy's array reconstructors
allowed (:func:`load_ground_truth`); the same reader serves ``robodepth evaluate``,
:func:`robodepth_cli.open_dataset` and ``robodepth_cli.torch.KittiC``
(:func:`read_depth_maps`), so nothing unpickles ground truth with ``allow_pickle=True``."""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import os_reason
from . import cache
from .kitti import KEYS_MEMBER, GroundTruthError, frame_key
from ..files import read_npy_header
from ..imageio import read_depth_png


class GroundTruth:
    """The ground-truth maps of a split, read once, in split order.

    Each map is kept as its valid pixels (flat indices and depths) when that is smaller
    than the map itself, else as read and prepared again on each use.
    """

    def __init__(self, source: str, protocol: str, valid):
        self.source = source
        self.protocol = protocol
        # valid: the evaluation setup's rule of valid pixels (its protocol's crop, depth range)
        self._valid = valid
        self._items: list = []
        self.shapes: list[tuple[int, int]] = []
        self.keys: list[str] | None = None  # the frame of each map, when the file says
        self.mapped: SharedGroundTruth | None = None  # the file its arrays are mapped from, if any

    def add(self, depth: np.ndarray, raw: np.ndarray | None = None,
            divisor: float | None = None, where: str | None = None) -> None:
        """Add the next map: ``depth`` in metres; ``raw`` and ``divisor`` (optional) a
        smaller form it can be recomputed from as ``raw.astype(float32) / divisor``."""
        self.append(self.prepare(depth, raw, divisor,
                                 where or f"{self.source}: ground-truth map {len(self._items)}"))

    def prepare(self, depth: np.ndarray, raw: np.ndarray | None, divisor: float | None,
                where: str) -> tuple:
        """The kept form of one map (see :meth:`add`), not yet added."""
        index = self._valid(depth).astype(np.int32 if depth.size < 2 ** 31 else np.int64)
        if not index.size:
            # The reference would average a NaN into every metric; say which map instead.
            raise GroundTruthError(f"{where} has no valid pixel inside the protocol's crop and "
                                  "depth range")
        values = depth.reshape(-1)[index]
        kept = raw if raw is not None else depth
        if index.nbytes + values.nbytes <= kept.nbytes:
            return depth.shape, (index, values)
        return depth.shape, (kept, divisor)

    def append(self, prepared: tuple) -> None:
        shape, item = prepared
        self._items.append(item)
        self.shapes.append(shape)

    def __len__(self) -> int:
        return len(self._items)

    def get(self, i: int) -> tuple[tuple[int, int], np.ndarray, np.ndarray]:
        """(shape, flat indices of the valid pixels, their ground-truth depths) of map ``i``."""
        item = self._items[i]
        if isinstance(item[1], np.ndarray):
            return self.shapes[i], item[0], item[1]
        return pixels_of(item[0], item[1], self._valid)

    def dense(self, i: int) -> tuple[np.ndarray, float | None] | None:
        """Map ``i`` as kept whole, ``(kept, divisor)`` (:func:`pixels_of` reads it), or
        None when it is kept as its valid pixels."""
        item = self._items[i]
        return None if isinstance(item[1], np.ndarray) else item

    def share(self, path: Path) -> "SharedGroundTruth":
        """Write every kept array into the file ``path`` (:meth:`write_arrays`) and return
        what other processes need to map it back: ``evaluate --jobs N`` hands its workers
        this instead of a copy each, so the page cache holds the maps once however many
        workers read them."""
        with open(path, "wb") as fh:
            entries = self.write_arrays(fh)
        return SharedGroundTruth(str(path), self.source, self.protocol, list(self.shapes), entries,
                                 self._valid)

    def write_arrays(self, fh) -> list:
        """Write every kept array into the binary file ``fh``, each at a 64-byte boundary
        (as numpy aligns its own); return each map's ``(pixels, [(offset, dtype, shape),
        ...], divisor)``: its valid pixels (indices, depths), or the map kept whole and
        its divisor."""
        entries, offset = [], 0
        for item in self._items:
            pixels = isinstance(item[1], np.ndarray)
            placed = []
            for a in (item if pixels else (item[0],)):
                a = np.ascontiguousarray(a)
                offset = -(-offset // 64) * 64
                fh.seek(offset)
                fh.write(a.tobytes())
                placed.append((offset, a.dtype.str, a.shape))
                offset += a.nbytes
            entries.append((pixels, placed, None if pixels else item[1]))
        return entries


def pixels_of(kept: np.ndarray, divisor: float | None, valid) -> tuple:
    """(shape, flat indices of the valid pixels, their depths) of a map kept whole: depth
    ``kept.astype(float32) / divisor`` (``divisor`` None: ``kept`` as it is), valid pixels
    by the rule ``valid``."""
    depth = kept if divisor is None else kept.astype(np.float32) / divisor
    index = valid(depth)
    return depth.shape, index, depth.reshape(-1)[index]


class SharedGroundTruth:
    """A :class:`GroundTruth` in a file (:meth:`GroundTruth.share`): small to pickle;
    :meth:`open` maps the file read-only and gives back the same arrays."""

    def __init__(self, path: str, source: str, protocol: str, shapes: list, entries: list,
                 valid=None):
        self.path, self.source, self.protocol = path, source, protocol
        self.shapes, self.entries = shapes, entries
        self.valid = valid  # the rule of valid pixels (picklable: a function or a setup's method)

    def moved(self, path: str) -> "SharedGroundTruth":
        """The same arrays in a copy (or link) of the file at ``path``."""
        return SharedGroundTruth(path, self.source, self.protocol, self.shapes, self.entries, self.valid)

    def open(self) -> GroundTruth:
        gt = GroundTruth(self.source, self.protocol, self.valid)
        size = Path(self.path).stat().st_size
        buf = np.memmap(self.path, dtype=np.uint8, mode="r") if size else np.zeros(0, np.uint8)
        for shape, (pixels, placed, divisor) in zip(self.shapes, self.entries):
            arrays = tuple(buf[off:off + int(np.prod(shp, dtype=np.int64)) * np.dtype(dt).itemsize]
                           .view(dt).reshape(shp) for off, dt, shp in placed)
            gt.append((shape, arrays if pixels else (arrays[0], divisor)))
        gt.mapped = self
        return gt


def load_ground_truth(path: Path, names: Sequence[str], protocol: str, valid,
                      absent=frozenset(), rule: str | None = None) -> GroundTruth:
    """Read the ground truth of a split's images from ``path``: a ``.npz``/``.npy`` file of
    depth maps in metres, one per image in split order (monodepth2's ``gt_depths.npz``), or
    a directory of 16-bit PNGs in millimetres at the relative paths ``names`` (one per
    image, in split order). Raises :class:`GroundTruthError` naming the file (and map index)
    for a missing, unreadable or malformed map, and when the file holds another number of
    maps than the split has images. The file is read as :func:`read_gt_file` says (peak
    ~125 MB for the 697 Eigen maps, against ~1.3 GB with ``np.load``). ``absent``: the
    images of a build with depth that have no map (left out, see
    :class:`.depthmaps.DepthMaps`). ``rule``: the name of the rule ``valid``
    (:attr:`.protocols.Setup.valid_rule`); with it, the maps as kept are also written to
    the user's cache and mapped from there the next time (:mod:`.cache`)."""
    path = Path(path)
    if path.is_dir() and names and all(n.endswith(".npy") for n in names):
        from .depthmaps import DepthMaps  # a build with depth: one float map per image

        return DepthMaps(path, names, protocol, valid, absent)
    key = cache.entry_key(path, names if path.is_dir() else None, rule) if rule is not None else None
    kept = _cached(key, path, protocol, valid) if key else None
    if kept is not None:
        _check_count(path, len(kept), names)
        _check_order(path, kept.keys, names)
        return kept
    gt = GroundTruth(str(path), protocol, valid)
    if path.is_dir():
        for i, name in enumerate(names):
            file = path / name
            raw = read_depth_png(file, f"ground truth of image {i}", GroundTruthError)
            gt.add(raw.astype(np.float32) / 1000.0, raw, 1000.0,
                   f"{file} (ground truth of image {i})")
    else:
        _check_count(path, read_gt_file(path, gt), names)
        _check_order(path, gt.keys, names)
    if key:
        cache.store(key, gt.source, gt.shapes, gt.keys, gt.write_arrays)
    return gt


def _cached(key: str, path: Path, protocol: str, valid) -> GroundTruth | None:
    """The cache's entry ``key`` of the ground truth at ``path``, mapped; None when there is
    none, or it went or changed between its check and its mapping (the file is read)."""
    found = cache.load(key)
    if found is None:
        return None
    where, shapes, entries, keys = found
    try:
        kept = SharedGroundTruth(where, str(path), protocol, shapes, entries, valid).open()
    except (OSError, ValueError):
        return None
    kept.keys = keys
    return kept


def _check_count(path: Path, count: int, names: Sequence[str]) -> None:
    if count != len(names):
        raise GroundTruthError(f"{path}: {count} ground-truth maps, but the dataset's split has "
                              f"{len(names)} images; ground truth and split must match one to one")


def _check_order(path: Path, keys: Sequence[str] | None, names: Sequence[str]) -> None:
    """Refuse ground truth whose maps (as its recorded frame keys say) are of other frames
    than the split's images, in order; a file without keys (monodepth2's) cannot be checked."""
    if keys is None:
        return
    if len(keys) != len(names):
        raise GroundTruthError(f"{path}: {len(keys)} frame keys for its maps; the file is damaged")
    for i, (have, name) in enumerate(zip(keys, names)):
        want = frame_key(name)
        if want is not None and have != want:
            raise GroundTruthError(f"{path}: map {i} is the ground truth of {have}, but image {i} of "
                                  f"the split is {want} ({name}); ground truth and split must be "
                                  "in the same order")


def read_depth_maps(path: Path) -> list[np.ndarray]:
    """Every depth map of a ``.npz``/``.npy`` ground-truth file, as stored (metres), in order;
    read with the same safe unpickler as :func:`load_ground_truth`."""
    maps = _Maps()
    read_gt_file(Path(path), maps)
    return maps


class _Maps(list):
    """Keeps each map whole: the part of :class:`GroundTruth`'s interface the file readers use."""

    def prepare(self, depth, raw, divisor, where):
        return depth

    def add(self, depth):
        self.append(depth)


def _check_gt_map(m, path: Path, i: int) -> np.ndarray:
    if not isinstance(m, np.ndarray) or m.ndim != 2 or m.dtype.kind not in "fiu" or 0 in m.shape:
        what = (f"shape {m.shape} and dtype {m.dtype}" if isinstance(m, np.ndarray)
                else f"a {type(m).__name__}")
        raise GroundTruthError(f"{path}: ground-truth map {i} has {what}; expected a 2-D depth map")
    return m


def read_gt_file(path: Path, gt: GroundTruth) -> int:
    """Add every map of a ``.npz``/``.npy`` ground-truth file to ``gt``; return how many.

    monodepth2's file is an object array of differently sized maps, which numpy stores as
    a pickle. It is unpickled here with only numpy's array and dtype reconstructors allowed
    (anything else in the file is refused, so a crafted file cannot run code), and each map
    is reduced to its kept form as soon as it is read: the ~1.3 GB of maps are never in
    memory together. A plain N x H x W array is read as it is.
    """
    if not path.exists():
        raise GroundTruthError(f"{path}: no such ground-truth file")
    try:
        with open(path, "rb") as raw:
            if zipfile.is_zipfile(raw):
                raw.seek(0)
                with zipfile.ZipFile(raw) as zf:
                    names = zf.namelist()
                    member = ("data.npy" if "data.npy" in names
                              else names[0] if len(names) == 1 else None)
                    if member is None:
                        raise GroundTruthError(f"{path}: holds {', '.join(names)}; expected 'data' "
                                              "(monodepth2's gt_depths.npz) or a single array")
                    with zf.open(member) as fh:
                        count = _read_gt_stream(fh, path, gt)
                    if member == "data.npy" and KEYS_MEMBER in names:
                        with zf.open(KEYS_MEMBER) as fh:
                            keys = np.lib.format.read_array(fh, allow_pickle=False)
                        if keys.ndim != 1 or keys.dtype.kind != "U":
                            raise GroundTruthError(f"{path}: {KEYS_MEMBER} is not a list of frame keys")
                        gt.keys = [str(k) for k in keys]
                    return count
            raw.seek(0)
            return _read_gt_stream(raw, path, gt)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        if isinstance(exc, GroundTruthError):
            raise
        reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
        raise GroundTruthError(f"{path}: not a numpy .npz/.npy ground-truth file ({reason})") from None


def _read_gt_stream(fh, path: Path, gt: GroundTruth) -> int:
    shape, fortran, dtype = read_npy_header(fh)
    if not dtype.hasobject:
        if len(shape) != 3:
            raise GroundTruthError(f"{path}: ground truth of shape {shape}; expected N depth maps "
                                  "(an object array of 2-D maps, or N x H x W)")
        nbytes = int(np.prod(shape)) * dtype.itemsize
        buf = fh.read(nbytes)
        if len(buf) != nbytes:
            raise GroundTruthError(f"{path}: the array ends early (truncated?)")
        data = np.frombuffer(buf, dtype).reshape(shape, order="F" if fortran else "C")
        for i in range(len(data)):
            gt.add(_check_gt_map(data[i], path, i))
        return len(data)
    if len(shape) != 1:
        raise GroundTruthError(f"{path}: ground truth of shape {shape}; expected a 1-D object "
                              "array of 2-D depth maps")
    counter = iter(range(1 << 62))

    def reduce(m: np.ndarray):
        i = next(counter)
        return _Prepared(gt.prepare(_check_gt_map(m, path, i), None, None,
                                    f"{path}: ground-truth map {i}"))

    data = _MapUnpickler(fh, path, reduce).load()
    if not isinstance(data, np.ndarray) or data.ndim != 1:
        raise GroundTruthError(f"{path}: does not hold a 1-D array of depth maps")
    for i, m in enumerate(data):
        prepared = m if isinstance(m, _Prepared) else getattr(m, "prepared", None)
        if prepared is None:
            _check_gt_map(m, path, i)  # raises: not a map
        gt.append(prepared.value)
    return len(data)


class _Prepared:
    """A ground-truth map already reduced to its kept form, inside the unpickled array."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value


_NUMPY_MODULES = ("numpy", "numpy.core.multiarray", "numpy._core.multiarray",
                  "numpy.core.numeric", "numpy._core.numeric")
_ALLOWED = {"ndarray", "dtype", "_reconstruct", "_frombuffer"}


class _MapUnpickler:
    """Unpickles an object array of maps, allowing only numpy's reconstructors and handing
    each 2-D numeric map to ``reduce`` the moment it is complete (protocol 5:
    ``_frombuffer``; older protocols: ``ndarray.__setstate__``).

    The unpickler's memo would keep every map's raw bytes alive to the end (pickle
    memoizes each bytes object and state tuple); every few maps, those large entries are
    replaced by None. Nothing refers back to them: each map's bytes are its own.
    """

    PRUNE_EVERY = 8
    LARGE = 1 << 12  # bytes; the small shared constants (dtype codes, shapes) stay

    def __init__(self, fh, path: Path, reduce):
        import pickle

        outer = self
        self._done = 0
        self._pruned = 0  # memo entries before this one have been pruned

        def reduced(arr):
            result = reduce(arr)
            outer._done += 1
            if outer._done % outer.PRUNE_EVERY == 0:
                outer._prune()
            return result

        class Map(np.ndarray):
            def __setstate__(self, state):
                super().__setstate__(state)
                if self.dtype.hasobject or self.ndim != 2:
                    return
                self.prepared = reduced(np.array(self, copy=True).view(np.ndarray))
                # Release the pixels: only the reduced form is kept.
                super().__setstate__((1, (0,), self.dtype, False, b""))

        def frombuffer(*args):
            arr = outer._frombuffer(*args)
            if arr.dtype.hasobject or arr.ndim != 2:
                return arr
            return reduced(np.array(arr, copy=True))

        # The Python implementation: its memo is a plain dict that can be pruned mid-load.
        class Unpickler(pickle._Unpickler):
            def find_class(self, module, name):
                # Protocol 2 (numpy's np.save before 1.17) spells bytes as _codecs.encode.
                if (module, name) == ("_codecs", "encode"):
                    return super().find_class(module, name)
                if module not in _NUMPY_MODULES or name not in _ALLOWED:
                    raise GroundTruthError(f"{path}: holds a pickled {module}.{name}; ground truth "
                                          "may hold only numpy arrays (refused, not loaded)")
                if name == "ndarray":
                    return Map
                real = super().find_class(module, name)
                if name == "_frombuffer":
                    outer._frombuffer = real
                    return frombuffer
                return real

        self._unpickler = Unpickler(fh, encoding="latin1")

    def load(self):
        return self._unpickler.load()

    def _prune(self) -> None:
        def large(v) -> bool:
            if isinstance(v, (bytes, bytearray, str)):
                return len(v) >= self.LARGE
            return isinstance(v, tuple) and any(large(x) for x in v)

        memo = self._unpickler.memo
        # Only the entries made since the last pruning (the memo grows with every map, and
        # scanning it all each time took 0.3 s of KITTI's 697 maps): picklers number them
        # 0, 1, 2, ... (a file numbered otherwise is pruned less, never read otherwise).
        for k in range(self._pruned, len(memo)):
            if large(memo.get(k)):
                memo[k] = None  # not deleted: new entries are numbered by the memo's length
        self._pruned = len(memo)
