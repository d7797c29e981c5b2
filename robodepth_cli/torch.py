"""On-the-fly corruption for PyTorch: transforms and a dataset of a built benchmark.

This is the only module of the package that imports torch.

* :class:`Corrupt` applies one corruption at one level. Given ``key=`` (the source path as
  a build's manifest records it) it draws exactly what ``robodepth build`` draws for that
  image, so the pixels equal the built file's; without a key it draws from its own
  generator.
* :class:`RandomCorrupt` picks a corruption and a level at random, for augmentation-style
  experiments; :class:`RandomChain` draws a whole chain at decimal severities,
  reproducibly per sample and epoch, and says what it applied. The RoboDepth challenge rules forbid training on the benchmark's
  corruptions for results submitted to it: this is for research on robustness, not for
  leaderboard entries.
* :func:`collate` batches :class:`KittiC` items whose ground truth (or images) differ in
  size, zero-padded, with each item's own size.
* :class:`KittiC` reads one corruption and level of a build (KITTI-C, NYUDepth2-C or a
  custom build) in split order, from disk or computed from the build's clean images.

Every generator is per process: a transform copied into ``DataLoader`` workers gives each
worker its own stream (derived from the seed and the worker's seed), and keyed draws do
not depend on any state at all. Nothing uses numpy's or torch's global random state.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from PIL import Image

from . import corruptions, seeding
from .api import _failed_text, open_dataset
from .corruptions.severity import LevelError
from .errors import InvalidValueError, RobodepthError
from .imageio import ImageError
from .keys import seed_key
from .output.layout import CLEAN, GT_FILE, variant_dir

__all__ = ["Corrupt", "RandomCorrupt", "RandomChain", "KittiC", "collate"]


class TorchAPIError(RobodepthError):
    """A bad argument to a transform or dataset of :mod:`robodepth_cli.torch`."""


# --- image types ---------------------------------------------------------------------------

def _to_array(img):
    """``(uint8 H x W x 3 array, function turning a result back into img's type)``."""
    if isinstance(img, Image.Image):
        return np.asarray(img.convert("RGB")), lambda a: Image.fromarray(a, "RGB")
    if isinstance(img, np.ndarray):
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
            raise TorchAPIError(f"expected an H x W x 3 uint8 array, got {img.dtype} {img.shape}")
        return img, lambda a: a
    if isinstance(img, torch.Tensor):
        if img.ndim != 3 or img.shape[0] != 3:
            raise TorchAPIError(f"expected a 3 x H x W tensor, got shape {tuple(img.shape)}")
        t = img.detach().cpu()
        if t.dtype == torch.uint8:
            arr = t.permute(1, 2, 0).numpy()
            return np.ascontiguousarray(arr), lambda a: torch.from_numpy(a).permute(2, 0, 1).contiguous().to(img.device)
        if t.is_floating_point():
            # Rounded: a uint8 image put through ToTensor (k / 255) comes back exactly.
            arr = (t.clamp(0, 1) * 255).round().to(torch.uint8).permute(1, 2, 0).numpy()
            return (np.ascontiguousarray(arr),
                    lambda a: (torch.from_numpy(a).permute(2, 0, 1).to(img.dtype) / 255).to(img.device))
        raise TorchAPIError(f"expected a uint8 or floating-point tensor, got {t.dtype}")
    raise TorchAPIError(f"expected a PIL image, numpy array or tensor, got {type(img).__name__}")


# --- per-process generators ----------------------------------------------------------------

def _worker_tag() -> tuple:
    """What distinguishes this process's stream: the pid, and inside a DataLoader worker the
    worker's seed (different for every worker and every epoch)."""
    info = torch.utils.data.get_worker_info()
    return (os.getpid(), None if info is None else int(info.seed))


class _ProcessGenerator:
    """A numpy Generator re-created in every process (and DataLoader worker) that uses it."""

    def __init__(self, seed: int | None):
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise TorchAPIError(f"seed must be an integer >= 0 or None, got {seed!r}")
        self.seed = None if seed is None else int(seed)
        self._tag = None
        self._rng = None

    def get(self) -> np.random.Generator:
        tag = _worker_tag()
        if tag != self._tag:
            worker_seed = tag[1]
            if self.seed is None:
                self._rng = np.random.default_rng()  # fresh OS entropy in this process
            elif worker_seed is None:
                self._rng = np.random.default_rng(self.seed)
            else:
                self._rng = np.random.default_rng([self.seed, worker_seed % (1 << 63)])
            self._tag = tag
        return self._rng

    def __getstate__(self):
        return {"seed": self.seed, "_tag": None, "_rng": None}


def _check(name: str, level) -> tuple[str, int | float]:
    try:
        c = corruptions.get(name)
        return c.name, corruptions.check_level(c, level)
    except (InvalidValueError, LevelError) as exc:
        raise TorchAPIError(str(exc)) from None


# --- transforms ----------------------------------------------------------------------------

class Corrupt:
    """Apply corruption ``name`` at ``level``.

    Parameters
    ----------
    name, level : a corruption of ``robodepth list`` and a level 1..5 (decimals allowed);
        or a chain such as ``"fog:3+gaussian_noise:2.5"`` (``level`` unused), drawing per
        step as a build draws for that chain.
    seed : the build's ``--seed`` when used with ``key=``; otherwise the seed of this
        transform's own generator (``None``: fresh entropy in every process).
    dataset : the dataset whose seeding ``key=`` follows: ``"custom"`` (default),
        ``"kitti-c"`` or ``"nyudepth2-c"``.

    Calling it with a PIL image, an H x W x 3 uint8 array or a 3 x H x W tensor (uint8, or
    floating point in [0, 1], rounded to uint8 levels first) returns the same type.
    ``key=`` is the source path as the manifest records it (``row.source``; for a custom
    build the path relative to ``--root``): the image is then corrupted with the generator
    the build uses for that (seed, dataset, corruption, level, key), so given the build's
    clean image the result equals the built file pixel for pixel. Without a key each call
    draws from the transform's own generator.
    """

    def __init__(self, name: str, level=None, seed: int | None = 0, dataset: str = "custom"):
        from .corruptions.chains import ChainError, looks_like_chain, parse_chain

        if looks_like_chain(name):
            try:
                self.chain = parse_chain(name)
            except ChainError as exc:
                raise TorchAPIError(str(exc)) from None
            self.name, self.level = self.chain.text, None
        else:
            self.chain = None
            self.name, self.level = _check(name, level)
        self.dataset = str(dataset)
        self._gen = _ProcessGenerator(seed)

    @property
    def seed(self):
        return self._gen.seed

    def rng_for(self, key: str | None) -> np.random.Generator:
        if key is None:
            return self._gen.get()
        if self.seed is None:
            raise TorchAPIError("key= needs the build's seed: create the transform with seed=N")
        return seeding.job_rng(self.seed, self.dataset, self.name, self.level or 1,
                               seed_key(self.dataset, key))

    def _apply(self, arr: np.ndarray, key: str | None) -> np.ndarray:
        if self.chain is None:
            return corruptions.corrupt(arr, self.name, self.level, self.rng_for(key))
        if key is None:
            rngs = [self._gen.get()] * len(self.chain.steps)
        else:
            self.rng_for(key)  # the same refusal without a seed
            rngs = seeding.chain_rngs(self.seed, self.dataset, self.chain, seed_key(self.dataset, key))
        return corruptions.corrupt_chain(arr, self.chain, rngs)

    def __call__(self, img, key: str | None = None):
        arr, back = _to_array(img)
        try:
            out = self._apply(arr, key)
        except ImageError as exc:  # e.g. an image below 32 x 32
            raise TorchAPIError(str(exc)) from None
        return back(out)

    def __repr__(self) -> str:
        level = "" if self.chain else f", {self.level}"
        return f"Corrupt({self.name!r}{level}, seed={self.seed}, dataset={self.dataset!r})"


class RandomCorrupt:
    """With probability ``p``, one corruption of ``names`` at one level of ``levels``, both
    chosen uniformly; otherwise the image unchanged (the same object).

    All draws (whether to corrupt, which corruption and level, the corruption's own
    randomness) come from one generator per process seeded from ``seed``
    (``None``: fresh entropy). Defaults: all 18 corruptions, levels 1 to 5.
    """

    def __init__(self, names: Sequence[str] | None = None, levels: Sequence[int] | None = None,
                 p: float = 0.5, seed: int | None = None):
        names = tuple(corruptions.NAMES if names is None else names)
        levels = tuple(range(1, 6) if levels is None else levels)
        if not names or not levels:
            raise TorchAPIError("names and levels must not be empty")
        for n in names:
            for lv in levels:
                _check(n, lv)
        if not 0.0 <= float(p) <= 1.0:
            raise TorchAPIError(f"p must be in [0, 1], got {p!r}")
        self.names, self.levels, self.p = names, tuple(_check(names[0], lv)[1] for lv in levels), float(p)
        self._gen = _ProcessGenerator(seed)

    def __call__(self, img):
        rng = self._gen.get()
        if rng.random() >= self.p:
            return img
        name = self.names[rng.integers(len(self.names))]
        level = self.levels[rng.integers(len(self.levels))]
        arr, back = _to_array(img)
        return back(corruptions.corrupt(arr, name, level, rng))

    def __repr__(self) -> str:
        return f"RandomCorrupt(names={list(self.names)}, levels={list(self.levels)}, p={self.p})"


class RandomChain:
    """A random chain of corruptions at random decimal severities, reproducible per sample
    and epoch, for training on compound corruptions.

    Parameters
    ----------
    names : the corruptions a chain may draw (default: all 18).
    steps : how many steps, an integer or an inclusive ``(min, max)`` range drawn
        uniformly (default ``(1, 3)``; at most 8).
    severity : the range ``(low, high)`` in [1, 5] each step's level is drawn from,
        uniformly, rounded to 0.01 (default ``(1, 5)``); or a dict giving some names their
        own range (the others keep ``(1, 5)``).
    distinct : no corruption twice in one chain (default True).
    p : probability of applying a chain at all (default 1); otherwise the image is returned
        unchanged with the empty chain ``""``.
    seed : an integer >= 0.

    ``t(img, key, epoch=None)`` returns ``(image, chain)``: the corrupted image (same type
    as ``img``, see :class:`Corrupt`) and the canonical text of the chain applied
    (``"fog:2.37+gaussian_noise:1.5"``), to log or to pass to ``robodepth corrupt -c``.
    Everything drawn for a sample (the chain, then each step's randomness, as
    :func:`robodepth_cli.seeding.chain_rngs` keys it) depends only on ``seed``, ``key``
    (the sample's index or path) and the epoch, never on the process: a DataLoader worker,
    a rerun or another machine draws the same. ``epoch`` defaults to the one set with
    :meth:`set_epoch` (0 at first); set it in the main process before each epoch's
    iterator is created, as with ``DistributedSampler``. :meth:`draw` gives the chain
    without applying it.
    """

    def __init__(self, names: Sequence[str] | None = None, steps=(1, 3), severity=(1.0, 5.0),
                 distinct: bool = True, p: float = 1.0, seed: int = 0):
        from .corruptions.chains import MAX_STEPS

        self.names = tuple(corruptions.NAMES if names is None else names)
        if not self.names:
            raise TorchAPIError("names must not be empty")
        for n in self.names:
            _check(n, 1)
        lo, hi = (steps, steps) if isinstance(steps, (int, np.integer)) else tuple(steps)
        if not (isinstance(lo, (int, np.integer)) and isinstance(hi, (int, np.integer)) and 1 <= lo <= hi <= MAX_STEPS):
            raise TorchAPIError(f"steps must be an integer or a range (min, max) within 1..{MAX_STEPS}, got {steps!r}")
        if distinct and hi > len(self.names):
            raise TorchAPIError(f"steps: up to {hi} distinct corruptions, but names has only {len(self.names)}")
        self.steps = (int(lo), int(hi))
        ranges = dict(severity) if isinstance(severity, dict) else {n: severity for n in self.names}
        unknown = sorted(set(ranges) - set(self.names))
        if unknown:
            raise TorchAPIError(f"severity names {', '.join(unknown)}, which are not among names")
        self.severity = {n: self._range(n, ranges.get(n, (1.0, 5.0))) for n in self.names}
        if not 0.0 <= float(p) <= 1.0:
            raise TorchAPIError(f"p must be in [0, 1], got {p!r}")
        self.p = float(p)
        self.distinct = bool(distinct)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise TorchAPIError(f"seed must be an integer >= 0, got {seed!r}")
        self.seed = int(seed)
        self.epoch = 0

    @staticmethod
    def _range(name: str, r) -> tuple[float, float]:
        try:
            lo, hi = (_check(name, v)[1] for v in r)
        except (TypeError, ValueError) as exc:
            raise TorchAPIError(f"severity of {name}: expected (low, high) within 1..5, got {r!r} ({exc})") from None
        if lo > hi:
            raise TorchAPIError(f"severity of {name}: low {lo} above high {hi}")
        return float(lo), float(hi)

    @classmethod
    def from_protocol(cls, path, seed: int = 0, p: float = 1.0, distinct: bool = True) -> "RandomChain":
        """The training side of a held-out protocol file (``configs/protocols/``): its
        ``train`` mapping's corruptions, steps and severity range (as a build checks them),
        so training never draws the corruptions the file builds for testing."""
        from .build.config import ConfigError, check_train, load_yaml
        from .sources.datasets import get_dataset

        data = load_yaml(Path(path))
        try:
            train = check_train(f"{path}: train", data.get("train"), get_dataset(data.get("dataset", "custom")))
        except ConfigError as exc:
            raise TorchAPIError(str(exc)) from None
        return cls(names=train["corruptions"], steps=tuple(train["steps"]), severity=tuple(train["severity"]),
                   distinct=distinct, p=p, seed=seed)

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def _epoch(self, epoch) -> int:
        return self.epoch if epoch is None else int(epoch)

    def draw(self, key, epoch: int | None = None):
        """The :class:`~robodepth_cli.corruptions.chains.Chain` drawn for sample ``key`` in
        ``epoch``, or None when the draw (probability ``1 - p``) applies nothing."""
        from .corruptions.chains import Chain, Step

        rng = seeding.sample_rng(self.seed, "random-chain", self._epoch(epoch), str(key))
        if rng.random() >= self.p:
            return None
        n = int(rng.integers(self.steps[0], self.steps[1] + 1))
        picks = rng.choice(len(self.names), size=n, replace=not self.distinct)
        steps = []
        for i in picks:
            name = self.names[int(i)]
            lo, hi = self.severity[name]
            level = round(float(rng.uniform(lo, hi)), 2)
            steps.append(Step(name, _check(name, min(max(level, lo), hi))[1]))
        return Chain(tuple(steps))

    def __call__(self, img, key, epoch: int | None = None):
        chain = self.draw(key, epoch)
        if chain is None:
            return img, ""
        arr, back = _to_array(img)
        rngs = seeding.chain_rngs(self.seed, f"random-chain epoch {self._epoch(epoch)}", chain, str(key))
        return back(corruptions.corrupt_chain(arr, chain, rngs)), chain.text

    def __repr__(self) -> str:
        return (f"RandomChain(names={list(self.names)}, steps={self.steps}, p={self.p}, "
                f"distinct={self.distinct}, seed={self.seed})")


# --- a built dataset -----------------------------------------------------------------------

class KittiC(torch.utils.data.Dataset):
    """One corruption at one level of a build made by ``robodepth build`` (KITTI-C, also
    NYUDepth2-C and custom builds), item ``i`` being the ``i``-th image of the split.

    ``root`` is the build's output directory. ``corruption`` may be a chain of the build
    (``"fog:3+gaussian_noise:2.5"``, no level) and ``level`` a decimal one. With
    ``on_the_fly=False`` the images are read from ``root/<corruption>/<level>/<key>``
    (a chain: ``root/<chain directory name>/<key>``); with ``on_the_fly=True`` they are
    computed from ``root/clean/<key>`` with :class:`Corrupt` seeded as the build was (its
    seed and dataset from ``build.json``), which gives the same pixels: only the clean
    images need to be on disk.

    An item is a dict: ``key`` (str), ``image`` (3 x H x W uint8 tensor, or whatever
    ``transform`` makes of the H x W x 3 array) and, when ``root/gt_depths.npz`` exists
    (``robodepth gt``; a pickle: open only builds you trust), ``depth`` (the ground-truth
    map of that image, float32 tensor, at the raw frame's size, which varies between KITTI
    drives: batch with ``collate_fn=robodepth_cli.torch.collate``).

    After a build that failed some images (it exited 1), ``missing="raise"`` (the default)
    raises :class:`TorchAPIError` naming them; ``missing="skip"`` serves the ones that exist
    (``len`` counts those; ``key`` says which each is).
    """

    def __init__(self, root, corruption: str, level=None, on_the_fly: bool = False, transform=None,
                 missing: str = "raise"):
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
        self.corruption = Corrupt(corruption, level, seed=self.seed, dataset=self.dataset)
        self.level = self.corruption.level
        self.on_the_fly = bool(on_the_fly)
        self.transform = transform
        self._gt_path = self.root / GT_FILE
        self._gt = None
        variant = next((v for v in built.variants() if v.relpath == self._relpath()), None)
        if variant is not None and variant.missing:
            if missing == "raise":
                raise TorchAPIError(f"{self.root / variant.relpath}: "
                                    f"{_failed_text(variant.missing, len(self.keys))}; rerun the "
                                    f"build command to make them, or KittiC(..., missing='skip') "
                                    f"for the {len(self.keys) - len(variant.missing)} that exist")
            self._index = [i for i, k in enumerate(self.keys) if k not in variant.missing]
            self.keys = [self.keys[i] for i in self._index]
        first = self._path(0) if self.keys else None
        if first is not None and not first.is_file():
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

    def _path(self, i: int) -> Path:
        return self.root / self._relpath() / self.keys[i]

    def __len__(self) -> int:
        return len(self.keys)

    def _depth(self, i: int):
        if self._gt is None:
            if not self._gt_path.is_file():
                return None
            from .evaluation.groundtruth import read_depth_maps

            # Read lazily in each process (a DataLoader worker reads its own copy).
            self._gt = read_depth_maps(self._gt_path)
        return torch.from_numpy(np.asarray(self._gt[self._index[i]], dtype=np.float32))

    def __getitem__(self, i: int) -> dict:
        if not 0 <= i < len(self.keys):
            raise IndexError(i)
        from .imageio import read_rgb

        img = np.asarray(read_rgb(self._path(i)))
        if self.on_the_fly:
            img = self.corruption._apply(img, self.keys[i])
        item = {"key": self.keys[i]}
        item["image"] = self.transform(img) if self.transform else torch.from_numpy(img.copy()).permute(2, 0, 1)
        depth = self._depth(i)
        if depth is not None:
            item["depth"] = depth
        return item

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
