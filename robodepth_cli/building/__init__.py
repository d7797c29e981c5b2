"""How a build runs: the resolved configuration (:mod:`.config`), the pipeline of named steps
(:mod:`.pipeline`), the checks that keep one OUT holding one build (:mod:`.checks`), where
tasks run (:mod:`.executors`, :mod:`.cluster` for Dask) and the ground truth written beside
the images (:mod:`.groundtruth`)."""
