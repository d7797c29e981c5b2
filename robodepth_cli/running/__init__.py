"""``robodepth run``: a model's robustness on a benchmark without writing the dataset.

The build's sources, renderers and seeded generators make each variant's images in memory
(:mod:`.inputs`), the model of ``robodepth predict`` predicts them in the same batches, and
the evaluation of ``robodepth evaluate`` judges each map against the ground truth read from
the root (:mod:`.loop`); the finished variants' rows are kept beside the results CSV so a
stopped run resumes (:mod:`.state`). Nothing heavy is imported here.
"""
