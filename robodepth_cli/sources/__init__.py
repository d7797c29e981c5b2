"""Where a build's images come from: the datasets' split formats and source paths
(:mod:`.datasets`), choosing and fetching a standard split (:mod:`.splits`), any folder of
images (:mod:`.custom`), and the official downloads read directly: KITTI raw's velodyne scans
(:mod:`.kitti_raw`) and NYU Depth V2's labeled file (:mod:`.nyu_labeled`).

Kept light: nothing heavy is imported here, so ``robodepth --help`` stays fast."""
