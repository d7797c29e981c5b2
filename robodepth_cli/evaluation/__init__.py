"""How a model is judged, with numpy alone: the metric protocols (:mod:`.protocols`), the
setup taken from the dataset and the flags (:mod:`.configure`), the driver behind ``robodepth
evaluate`` (:mod:`.evaluate`), the results CSV (:mod:`.csvrows`, :mod:`.results`) and the
robustness scores (:mod:`.scores`). The ground truth is :mod:`robodepth_cli.groundtruth`'s,
the predictions :mod:`robodepth_cli.predictions`'; the CE chart is the report's
(:mod:`robodepth_cli.report.plot`)."""
