"""On-the-fly corruption for PyTorch: transforms and a dataset of a built benchmark.

Importing it imports torch; nothing else in a build or an evaluation does.

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

The transforms are :mod:`.transforms` (their path for an ``N x 3 x H x W`` batch on the
device, :mod:`.batch`), the dataset :mod:`.dataset`.
"""

from __future__ import annotations

from .dataset import KittiC, collate
from .errors import TorchAPIError
from .transforms import Corrupt, RandomChain, RandomCorrupt

__all__ = ["Corrupt", "RandomCorrupt", "RandomChain", "KittiC", "collate", "TorchAPIError"]
