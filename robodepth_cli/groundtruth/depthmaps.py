"""The ground truth of a build with depth (``OUT/gt/<key stem>.npy``, float32 metres, NaN
where invalid), read one map at a time.

These maps can be large (ETH3D's are 6048 x 4032, 97 MB each), so unlike KITTI's and NYU's
ground truth they are never all held at once: opening checks every file's header (present,
a 2-D float map), and :meth:`DepthMaps.get` reads one map, memory-mapped, when its image is
evaluated. Workers (``evaluate --jobs N``) get the same object: it holds only paths.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..files import read_npy_header
from .kitti import GroundTruthError


class NoValidPixel(GroundTruthError):
    """A map without a pixel to judge a prediction on (in another unit than metres, say):
    its image is left out of the evaluation."""


class DepthMaps:
    """The interface of :class:`~.read.GroundTruth` that evaluation uses (``len``,
    ``get``, ``shapes``, ``share``/``open``, ``mapped``), over one ``.npy`` file per image."""

    keys = None  # no frame keys to check the order against: the names are the keys
    mapped = None  # read map by map, never from the ground-truth cache

    def __init__(self, directory: Path, names: Sequence[str], protocol: str, valid,
                 absent=frozenset()):
        self.source = str(directory)
        self.protocol = protocol
        self.valid = valid
        self.paths = [str(Path(directory) / n) for n in names]
        # absent: images the build has no ground truth of (their depth map is unusable);
        # get() gives None for them and the evaluation leaves them out.
        self.absent = frozenset(absent)
        self.shapes = [(0, 0) if i in self.absent else self._header(Path(p), i)
                       for i, p in enumerate(self.paths)]

    @staticmethod
    def _header(path: Path, i: int) -> tuple[int, int]:
        try:
            with open(path, "rb") as fh:
                shape, _, dtype = read_npy_header(fh)
        except FileNotFoundError:
            raise GroundTruthError(f"{path}: no such ground-truth file (image {i}); rerun the build "
                                  "to make it") from None
        except (OSError, ValueError) as exc:
            raise GroundTruthError(f"{path}: not a ground-truth .npy map ({exc})") from None
        if len(shape) != 2 or dtype.kind != "f":
            raise GroundTruthError(f"{path}: ground truth of shape {shape} and dtype {dtype}; "
                                  "expected one 2-D float map")
        return tuple(shape)

    def __len__(self) -> int:
        return len(self.paths)

    def get(self, i: int) -> tuple[tuple[int, int], np.ndarray, np.ndarray]:
        """(shape, flat indices of the valid pixels, their depths) of map ``i``, read now;
        None for an image without ground truth."""
        if i in self.absent:
            return None
        path = self.paths[i]
        try:
            depth = np.load(path, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise GroundTruthError(f"{path}: cannot read the ground truth ({exc})") from None
        if depth.shape != self.shapes[i]:
            raise GroundTruthError(f"{path}: changed while it was evaluated")
        index = self.valid(depth)
        if not index.size:
            raise NoValidPixel(f"{path} (ground truth of image {i}) has no valid pixel inside "
                               "the crop and depth range")
        return self.shapes[i], index, np.asarray(depth.reshape(-1)[index])

    def dense(self, i: int) -> None:
        """None: each map is read by :meth:`get` (which also says when it has no valid pixel)."""
        return None

    def share(self, path: Path) -> DepthMaps:
        return self  # paths only: each worker reads the maps it evaluates

    def open(self) -> DepthMaps:
        return self
