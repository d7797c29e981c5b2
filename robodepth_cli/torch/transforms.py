"""The PyTorch transforms behind :mod:`robodepth_cli.torch`: :class:`Corrupt`,
:class:`RandomCorrupt` and :class:`RandomChain`, with the per-process generators that keep
them reproducible in ``DataLoader`` workers. Import them from :mod:`robodepth_cli.torch`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from PIL import Image

from .. import corruptions, seeding
from . import batch as transforms_batch
from ..corruptions.severity import LevelError
from ..errors import InvalidValueError, RobodepthError
from ..imageio import ImageError
from ..sourcekeys import seed_key
from .errors import TorchAPIError

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
        checked = c.name, corruptions.check_level(c, level)
    except (InvalidValueError, LevelError) as exc:
        raise TorchAPIError(str(exc)) from None
    _no_depth(name)
    return checked


def _no_depth(variant: str) -> None:
    """The transforms see images only: a depth-aware corruption is refused up front."""
    if corruptions.needs_depth(variant):
        raise TorchAPIError(f"{variant}: needs the scene's depth, which the transforms do not "
                            f"take; call robodepth_cli.corruptions.corrupt(image, name, level, "
                            f"rng, depth=...)")


def _severity_size(value) -> tuple[int, int] | None:
    """``severity_size=`` of a transform: ``(H, W)``, ``"HxW"`` or ``"none"``/None (see
    :mod:`robodepth_cli.corruptions.scaling`)."""
    from ..corruptions.scaling import parse_severity_size

    try:
        return parse_severity_size(value)
    except InvalidValueError as exc:
        raise TorchAPIError(f"severity_size: {exc}") from None


def _batch_unscaled(t) -> None:
    """A batch goes to the torch engine, which does not scale the levels yet."""
    if t.severity_size is not None:
        raise TorchAPIError("severity_size: a batch (N x 3 x H x W) is corrupted by the torch engine, "
                            "which does not scale the levels yet; call the transform per image")


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
    severity_size : the size ``(H, W)`` (or ``"HxW"``) at which the level's spatial
        parameters are defined, scaled to each image as ``--severity-size`` does (a build's
        pixels need the build's); None (default): as tabulated. Images only, not batches.

    Calling it with a PIL image, an H x W x 3 uint8 array or a 3 x H x W tensor (uint8, or
    floating point in [0, 1], rounded to uint8 levels first) returns the same type.
    ``key=`` is the source path as the manifest records it (``row.source``; for a custom
    build the path relative to ``--root``): the image is then corrupted with the generator
    the build uses for that (seed, dataset, corruption, level, key), so given the build's
    clean image the result equals the built file pixel for pixel. Without a key each call
    draws from the transform's own generator.

    An ``N x 3 x H x W`` batch (on any device) is corrupted there by the torch engine, item
    ``i`` with ``key[i]`` when ``key`` is a sequence of keys (see :mod:`.batch`).
    """

    def __init__(self, name: str, level=None, seed: int | None = 0, dataset: str = "custom",
                 severity_size=None):
        from ..corruptions.chains import looks_like_chain, parse_chain

        if looks_like_chain(name):
            try:
                self.chain = parse_chain(name)
            except RobodepthError as exc:
                raise TorchAPIError(str(exc)) from None
            _no_depth(self.chain.text)
            self.name, self.level = self.chain.text, None
        else:
            self.chain = None
            self.name, self.level = _check(name, level)
        self.dataset = str(dataset)
        self.severity_size = _severity_size(severity_size)
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
            return corruptions.corrupt(arr, self.name, self.level, self.rng_for(key),
                                       severity_size=self.severity_size)
        if key is None:
            rngs = [self._gen.get()] * len(self.chain.steps)
        else:
            self.rng_for(key)  # the same refusal without a seed
            rngs = seeding.chain_rngs(self.seed, self.dataset, self.chain, seed_key(self.dataset, key))
        return corruptions.corrupt_chain(arr, self.chain, rngs, severity_size=self.severity_size)

    def __call__(self, img, key: str | None = None):
        if transforms_batch.is_batch(img):  # key: one per item, or None
            _batch_unscaled(self)
            return transforms_batch.corrupt(self, img, key)
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
    ``severity_size`` as :class:`Corrupt` takes it.

    ``t(batch, keys=None, epoch=0)`` on an ``N x 3 x H x W`` batch returns ``(batch,
    applied)``, ``applied[i]`` the ``name:level`` item ``i`` got or ``""``; with ``keys`` each
    item draws from its own generator (seed, key, epoch) (see :mod:`.batch`).
    """

    def __init__(self, names: Sequence[str] | None = None, levels: Sequence[int] | None = None,
                 p: float = 0.5, seed: int | None = None, severity_size=None):
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
        self.severity_size = _severity_size(severity_size)
        self._gen = _ProcessGenerator(seed)

    def __call__(self, img, keys=None, epoch: int = 0):
        if transforms_batch.is_batch(img):
            _batch_unscaled(self)
            return transforms_batch.random_corrupt(self, img, keys, int(epoch))
        if keys is not None:
            raise TorchAPIError("keys= is for a batch (an N x 3 x H x W tensor), one key per item")
        rng = self._gen.get()
        if rng.random() >= self.p:
            return img
        name = self.names[rng.integers(len(self.names))]
        level = self.levels[rng.integers(len(self.levels))]
        arr, back = _to_array(img)
        return back(corruptions.corrupt(arr, name, level, rng, severity_size=self.severity_size))

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
    severity_size : as :class:`Corrupt` takes it.

    ``t(img, key, epoch=None)`` returns ``(image, chain)``: the corrupted image (same type
    as ``img``, see :class:`Corrupt`) and the canonical text of the chain applied
    (``"fog:2.37+gaussian_noise:1.5"``), to log or to pass to ``robodepth corrupt -c``.
    Everything drawn for a sample (the chain, then each step's randomness, as
    :func:`robodepth_cli.seeding.chain_rngs` keys it) depends only on ``seed``, ``key``
    (the sample's index or path) and the epoch, never on the process: a DataLoader worker,
    a rerun or another machine draws the same. ``epoch`` defaults to the one set with
    :meth:`set_epoch` (0 at first); set it in the main process before each epoch's
    iterator is created, as with ``DistributedSampler``. The epoch lives in shared memory
    (a one-element torch tensor), so DataLoader workers see it even when they outlive the
    epoch (``persistent_workers=True``): a copy of the transform made by pickling outside
    torch's multiprocessing (a plain ``pickle.dumps``) no longer follows the original's
    :meth:`set_epoch`. :meth:`draw` gives the chain without applying it.
    ``t(batch, keys, epoch=None)`` on an ``N x 3 x H x W`` batch returns ``(batch, chains)``,
    item ``i`` as ``t(item_i, keys[i], epoch)`` makes it.
    """

    def __init__(self, names: Sequence[str] | None = None, steps=(1, 3), severity=(1.0, 5.0),
                 distinct: bool = True, p: float = 1.0, seed: int = 0, severity_size=None):
        from ..corruptions.chains import MAX_STEPS

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
        self.severity_size = _severity_size(severity_size)
        # Shared memory, not an int: persistent DataLoader workers keep the copy they got
        # when they started, and an int there would stay at that epoch for ever.
        self._shared_epoch = torch.zeros((), dtype=torch.int64).share_memory_()

    @property
    def epoch(self) -> int:
        return int(self._shared_epoch.item())

    @epoch.setter
    def epoch(self, value: int) -> None:
        self._shared_epoch.fill_(int(value))

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
        from ..building.config import ConfigError, check_train, load_yaml
        from ..sources.datasets import get_dataset

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
        from ..corruptions.chains import Chain, Step

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
        if transforms_batch.is_batch(img):  # key: one per item
            _batch_unscaled(self)
            return transforms_batch.random_chain(self, img, key, epoch)
        chain = self.draw(key, epoch)
        if chain is None:
            return img, ""
        arr, back = _to_array(img)
        rngs = seeding.chain_rngs(self.seed, f"random-chain epoch {self._epoch(epoch)}", chain, str(key))
        return back(corruptions.corrupt_chain(arr, chain, rngs, severity_size=self.severity_size)), chain.text

    def __repr__(self) -> str:
        return (f"RandomChain(names={list(self.names)}, steps={self.steps}, p={self.p}, "
                f"distinct={self.distinct}, seed={self.seed})")
