"""One prediction judged against its image's ground truth: the checks of its values and
size, then the protocol (:mod:`.protocols`). ``robodepth evaluate`` and ``robodepth run``
(which never writes the maps it judges) share it, so their numbers are the same."""

from __future__ import annotations

import numpy as np

from ..groundtruth.read import pixels_of
from .protocols import EvaluationError, Setup, kitti_image, nyu_image, whole_map_image


def image_errors(m: np.ndarray, where: str, truth: tuple | None, setup: Setup, image_size,
                 is_png: bool = False, *, whole: tuple | None = None, gt_median=None) -> tuple:
    """The metrics of one prediction ``m`` (read from ``where``, which messages name) against
    ``truth`` (:meth:`robodepth_cli.groundtruth.read.GroundTruth.get` of its image), and its median-scaling ratio (None
    unless the protocol has one); :class:`EvaluationError` for a map that cannot be judged.
    ``whole`` instead of ``truth``: the map kept whole (:meth:`robodepth_cli.groundtruth.read.GroundTruth.dense`), judged
    in one pass where :func:`.protocols.whole_map_image` can (the same numbers).
    ``gt_median``: the median of the ground truth's depths, when known (kitti_image).
    ``robodepth run`` calls this on maps it never writes, so its numbers are these."""
    if m.dtype not in (np.float32, np.float64):
        m = m.astype(np.float32)  # OpenCV and the reference code work in float32
    check_values(m, where, setup.kind, allow_negative=setup.alignment == "scale-shift")
    if whole is not None:
        try:
            errs = whole_map_image(m, *whole, setup)
        except EvaluationError as exc:
            raise EvaluationError(f"{where}: {exc}") from None
        if errs is not None:
            return _finite(errs, where), None
        truth = pixels_of(*whole, setup.valid)
    shape, index, gt = truth
    if is_png and shape != m.shape and tuple(m.shape) != tuple(image_size or ()):
        raise EvaluationError(f"{where} is {m.shape[0]} x {m.shape[1]}; a PNG prediction must "
                              f"have the ground truth's size {shape[0]} x {shape[1]} or the "
                              "image's")
    if setup.protocol == "nyu" and (m.shape[0] > shape[0] or m.shape[1] > shape[1]):
        raise EvaluationError(f"{where} is {m.shape[0]} x {m.shape[1]}, larger than its "
                              f"ground truth ({shape[0]} x {shape[1]})")
    # 0 is a valid value (see ZERO_AND_INF); what it leads to is checked below instead.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        try:
            if setup.protocol == "kitti":
                errs, ratio = kitti_image(m, setup.kind, setup.stereo, shape, index, gt, setup,
                                          gt_median=gt_median)
            else:
                errs, ratio = nyu_image(m, shape, index, gt, setup), None
        except EvaluationError as exc:  # raised by the alignment, which knows no file
            raise EvaluationError(f"{where}: {exc}") from None
    return _finite(errs, where), ratio


def _finite(errs: tuple, where: str) -> tuple:
    if not np.all(np.isfinite(np.asarray(errs, dtype=np.float64))):
        raise EvaluationError(f"{where}: the metrics of this map are not finite numbers")
    return errs


def check_values(m: np.ndarray, where: str, kind: str = "depth",
                 allow_negative: bool = False) -> None:
    """Refuse a map that cannot give finite metrics (the rule is :data:`ZERO_AND_INF`):
    NaN, inf, negative values (unless ``allow_negative``: a prediction aligned by a scale
    and a shift may have them), a sigmoid output outside [0, 1], or (disp, depth) no
    positive value at all, a dead map."""
    low = np.min(m)
    if np.isnan(low):
        raise EvaluationError(f"{where} contains NaN")
    if low < 0 and not allow_negative:
        raise EvaluationError(f"{where} has negative values (min {float(low):g})")
    high = np.max(m)
    if np.isinf(high):
        raise EvaluationError(f"{where} contains inf ({int(np.isinf(m).sum())} pixels); give "
                              "finite values (a far pixel as a large depth or a 0 disparity)")
    if kind == "sigmoid":
        if high > 1:
            raise EvaluationError(f"{where}: values up to {float(high):g}; --kind sigmoid is a "
                                  "network's sigmoid output, in [0, 1] (a disparity or a depth? "
                                  "give --kind disp or --kind depth)")
    elif high == 0:
        raise EvaluationError(f"{where}: no positive finite value (all 0); a dead map cannot be "
                              "evaluated")


ZERO_AND_INF = ("0 and inf: a disparity (--kind disp) of 0 is infinitely far, a depth of 0 is "
                "distance 0; either is clamped to the protocol's depth range (1e-3 to 80 m kitti, "
                "10 m nyu) as the reference evaluators clamp. inf and NaN are refused, as are "
                "negative values, sigmoid outputs outside [0, 1], a map with no positive value "
                "and (median scaling) a map that is 0 at half of the valid pixels or more.")
