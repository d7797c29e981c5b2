"""How a build runs: the resolved configuration (:mod:`.config`), the pipeline of named steps
(:mod:`.pipeline`), the checks that keep one OUT holding one build (:mod:`.checks`) and where
tasks run (:mod:`.executors`, :mod:`.cluster` for Dask). The ground truth written beside the
images is :mod:`robodepth_cli.groundtruth`'s."""
