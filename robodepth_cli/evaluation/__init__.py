"""How a model is judged: the metric protocols (:mod:`.protocols`), the ground truth
(:mod:`.groundtruth`), the model's predictions (:mod:`.predictions`), the driver behind
``robodepth evaluate`` (:mod:`.evaluate`), the robustness scores (:mod:`.scores`) and their
chart (:mod:`.plot`)."""
