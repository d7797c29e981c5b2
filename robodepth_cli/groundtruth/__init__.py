"""The ground truth, one owner for its formats: made from the official downloads (KITTI
raw's velodyne scans, :mod:`.kitti`; NYU Depth V2's labeled file and BTS's 16-bit depth
PNGs, :mod:`.nyu`), written beside a build's images (:mod:`.write`) and read back for an
evaluation (:mod:`.read`; a build with depth's per-image maps, :mod:`.depthmaps`). Its
16-bit PNGs are read by :func:`robodepth_cli.imageio.read_depth_png`, as every depth PNG is."""
