"""Where a build's images come from: the datasets' split formats and source paths
(:mod:`.datasets`), choosing and fetching a standard split (:mod:`.splits`), any folder of
images (:mod:`.custom`), and where depth comes from: depth maps in every shipped form
(:mod:`.depth_io`, paired to images by :mod:`.depth_pairs`), ``--depth FILE``
(:mod:`.depthfile`) and a model's predictions (:mod:`.predicted`). The ground truth made
from the official downloads is :mod:`robodepth_cli.groundtruth`'s; which depth a build's
depth-aware corruptions take, :mod:`robodepth_cli.building.scenedepth`'s.

Kept light: nothing heavy is imported here, so ``robodepth --help`` stays fast."""
