"""The :class:`KittiC` dataset of a built benchmark, and :func:`collate` for its items."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from .. import open_dataset
from ..api import failed_text, read_neighbours
from ..output.layout import CLEAN, GT_FILE, variant_dir
from .errors import TorchAPIError
from .transforms import Corrupt


# --- a built dataset -----------------------------------------------------------------------

class KittiC(torch.utils.data.Dataset):
    """One corruption at one level of a build made by ``robodepth build`` (KITTI-C, also
    NYUDepth2-C and custom builds), item ``i`` being the ``i``-th image of the split.

    ``root`` is the build's output directory. ``corruption`` may be a chain of the build
    (``"fog:3+gaussian_noise:2.5"``, no level) and ``level`` a decimal one. With
    ``on_the_fly=False`` the images are read from ``root/<corruption>/<level>/<key>``
    (a chain: ``root/<chain directory name>/<key>``); with ``on_the_fly=True`` they are
    computed from ``root/clean/<key>`` with :class:`Corrupt` seeded as the build was (its
    seed, dataset and severity size from ``build.json``), which gives the same pixels: only the clean
    images need to be on disk.

    An item is a dict: ``key`` (str), ``image`` (3 x H x W uint8 tensor, or whatever
    ``transform`` makes of the H x W x 3 array) and, when ``root/gt_depths.npz`` exists
    (``robodepth gt``; a pickle: open only builds you trust), ``depth`` (the ground-truth
    map of that image, float32 tensor, at the raw frame's size, which varies between KITTI
    drives: batch with ``collate_fn=robodepth_cli.torch.collate``).

    After a build that failed some images (it exited 1), ``missing="raise"`` (the default)
    raises :class:`TorchAPIError` naming them; ``missing="skip"`` serves the ones that exist
    (``len`` counts those; ``key`` says which each is).

    ``frames=(-1, 1)`` (a build made with ``--frames``): the item also holds ``neighbours``,
    the images of those neighbour frames in that order (the same variant, transformed
    alike); a neighbour the drive does not have is black, as ManyDepth's loader gives it.
    They are read from disk (not with ``on_the_fly``).
    """

    def __init__(self, root, corruption: str, level=None, on_the_fly: bool = False, transform=None,
                 missing: str = "raise", frames=()):
        if missing not in ("raise", "skip"):
            raise TorchAPIError(f"missing={missing!r}: expected 'raise' or 'skip'")
        self.root = Path(root)
        built = open_dataset(self.root)  # the build record and the split order, checked
        self.keys = list(built.keys)
        # Item i is split image self._index[i]: every one, or (missing="skip") the ones the
        # build made; the ground truth is indexed by the split.
        self._index = list(range(len(self.keys)))
        self.dataset = built.name
        self.seed = int(built.record.seed or 0)
        # The build's severity size too, so that on_the_fly gives the built pixels.
        severity = ((built.record.config or {}).get("extra") or {}).get("severity_size")
        self.corruption = Corrupt(corruption, level, seed=self.seed, dataset=self.dataset,
                                  severity_size=severity)
        self.level = self.corruption.level
        self.on_the_fly = bool(on_the_fly)
        self.transform = transform
        # An export (robodepth export) is read from its shards, its ground truth copied out.
        self._store = built.store
        self._gt_path = self.root / GT_FILE if self._store is None else built.ground_truth()
        self._gt = None
        variant = next((v for v in built.variants() if v.relpath == self._relpath()), None)
        if variant is not None and variant.missing:
            if missing == "raise":
                raise TorchAPIError(f"{self.root / variant.relpath}: "
                                    f"{failed_text(variant.missing, len(self.keys))}; rerun the "
                                    f"build command to make them, or KittiC(..., missing='skip') "
                                    f"for the {len(self.keys) - len(variant.missing)} that exist")
            self._index = [i for i, k in enumerate(self.keys) if k not in variant.missing]
            self.keys = [self.keys[i] for i in self._index]
        self.frames = tuple(frames)
        lacking = sorted(set(self.frames) - built.record.frames)
        if lacking:
            raise TorchAPIError(f"{self.root}: no neighbour frames at {', '.join(map(str, lacking))} "
                                f"(build it with --frames {','.join(map(str, self.frames))})")
        if self.frames and self.on_the_fly:
            raise TorchAPIError("frames=: the neighbour frames are read from the build; "
                                "on_the_fly=True makes only the test frames")
        first = self._path(0) if self.keys else None
        there = self._store.has if self._store is not None else lambda p: p.is_file()
        if first is not None and not there(first if self._store is None else self._output(0)):
            what = ("clean" if self.on_the_fly else self.corruption.name if self.corruption.chain
                    else f"{self.corruption.name} level {self.level}")
            raise TorchAPIError(f"{first}: missing; was {what} "
                                f"built into {self.root}?")

    def _relpath(self) -> str:
        """The directory of the images read, relative to the build."""
        if self.on_the_fly:
            return variant_dir(CLEAN, None)
        if self.corruption.chain is not None:
            return variant_dir(self.corruption.chain.dirname, None)
        return variant_dir(self.corruption.name, self.level)

    def _output(self, i: int) -> str:
        return f"{self._relpath()}/{self.keys[i]}"

    def _path(self, i: int) -> Path:
        return self.root / self._output(i)

    def __len__(self) -> int:
        return len(self.keys)

    def _depth(self, i: int):
        if self._gt is None:
            if self._gt_path is None or not self._gt_path.is_file():
                return None
            from ..groundtruth.read import read_depth_maps

            # Read lazily in each process (a DataLoader worker reads its own copy).
            self._gt = read_depth_maps(self._gt_path)
        return torch.from_numpy(np.asarray(self._gt[self._index[i]], dtype=np.float32))

    def __getitem__(self, i: int) -> dict:
        if not 0 <= i < len(self.keys):
            raise IndexError(i)
        from ..imageio import read_rgb

        if self._store is None:
            img = np.asarray(read_rgb(self._path(i)))
        else:
            import io

            img = np.asarray(read_rgb(io.BytesIO(self._store.read(self._output(i)))))
        if self.on_the_fly:
            img = self.corruption._apply(img, self.keys[i])
        item = {"key": self.keys[i]}
        item["image"] = self._tensor(img)
        if self.frames:
            item["neighbours"] = [self._tensor(n) for n in self._neighbours(i, img)]
        depth = self._depth(i)
        if depth is not None:
            item["depth"] = depth
        return item

    def _tensor(self, img: np.ndarray):
        return self.transform(img) if self.transform else torch.from_numpy(img.copy()).permute(2, 0, 1)

    def _neighbours(self, i: int, img: np.ndarray) -> list[np.ndarray]:
        return read_neighbours(self.root, self._store, self._relpath(), self.keys[i], self.frames, img)

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_gt"] = None
        return state


# Fields of a KittiC item whose height and width can differ within a batch: KITTI's ground
# truth is at each drive's raw frame size, and a custom build keeps each image's own size.
_SIZED = ("image", "depth")


def collate(items: list[dict]) -> dict:
    """A ``collate_fn`` for :class:`KittiC` that batches items whose maps differ in size.

    ``image`` and ``depth`` (when they are tensors) are stacked into one tensor, each padded
    with zeros at the bottom and right to the largest height and width in the batch (a depth
    of 0 is the ground truth's own "no measurement", which every protocol ignores), and
    ``image_size`` / ``depth_size`` (N x 2, int64: HxW) keep each item's own size, so
    ``batch["depth"][i, :h, :w]`` is item ``i``'s map. ``key`` becomes a list; anything
    else is batched by torch's default collate.
    """
    from torch.utils.data import default_collate

    batch = {}
    for name in items[0]:
        values = [item[name] for item in items]
        if name in _SIZED and all(isinstance(v, torch.Tensor) and v.ndim >= 2 for v in values):
            sizes = [tuple(v.shape[-2:]) for v in values]
            lead = {tuple(v.shape[:-2]) for v in values}
            if len(lead) > 1:
                raise TorchAPIError(f"collate: {name} has different leading dimensions in one "
                                    f"batch: {sorted(lead)}")
            h, w = max(s[0] for s in sizes), max(s[1] for s in sizes)
            out = values[0].new_zeros((len(values), *values[0].shape[:-2], h, w))
            for i, v in enumerate(values):
                out[i, ..., : v.shape[-2], : v.shape[-1]] = v
            batch[name] = out
            batch[f"{name}_size"] = torch.tensor(sizes, dtype=torch.int64)
        else:
            batch[name] = default_collate(values)
    return batch
