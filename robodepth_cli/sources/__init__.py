"""Where a build's images come from: the datasets' split formats and source paths
(:mod:`.datasets`), choosing and fetching a standard split (:mod:`.splits`), any folder of
images (:mod:`.custom`), and the depth a build's depth-aware corruptions take (:mod:`.scenedepth`,
from the files of :mod:`.depth_io`). The ground truth made from the official downloads is
:mod:`robodepth_cli.groundtruth`'s.

Kept light: nothing heavy is imported here, so ``robodepth --help`` stays fast."""
