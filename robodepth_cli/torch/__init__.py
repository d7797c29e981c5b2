"""On-the-fly corruption for PyTorch: transforms and a dataset of a built benchmark
(docs/custom-and-torch.md). Importing it imports torch; nothing else in a build or an
evaluation does.

:class:`Corrupt` (with ``key=``, the very pixels of the build), :class:`RandomCorrupt` and
:class:`RandomChain` are in :mod:`.transforms` (their batch path :mod:`.batch`);
:class:`KittiC` and :func:`collate` in :mod:`.dataset`. Every generator is per process
and derived from the seed (and a ``DataLoader`` worker's seed); nothing uses numpy's or
torch's global random state. The RoboDepth challenge rules forbid training on the
benchmark's corruptions for results submitted to it."""

from __future__ import annotations

from .dataset import KittiC, collate
from .errors import TorchAPIError
from .transforms import Corrupt, RandomChain, RandomCorrupt

__all__ = ["Corrupt", "RandomCorrupt", "RandomChain", "KittiC", "collate", "TorchAPIError"]
