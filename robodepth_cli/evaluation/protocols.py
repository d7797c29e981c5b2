"""The metric protocols of the published RoboDepth numbers: which pixels count, how a
prediction becomes a depth, and the metrics.

Two protocols, each computed the way its reference evaluator computes it:

kitti
    monodepth2's ``evaluate_depth.py`` (the benchmark's KITTI-C evaluation is a copy of it):
    a disparity is resized to the ground truth's size with ``cv2.resize`` (bilinear) and
    inverted; valid pixels are ``1e-3 < gt < 80`` inside the Garg crop; each image's
    prediction is scaled by ``median(gt) / median(pred)`` (mono) or by 5.4 (stereo), then
    clamped to [1e-3, 80]. See :func:`kitti_image`.
nyu
    BTS's ``eval_with_pngs.py`` and AdaBins's ``evaluate.py``: depth in metres, upsampled
    (bilinear, corner-aligned as AdaBins's ``interpolate(align_corners=True)``) to the ground
    truth's size if smaller, clamped to [1e-3, 10]; valid pixels ``1e-3 < gt < 10`` inside
    the Eigen crop (rows 45..470, columns 41..600); no scaling; two more metrics, log10 and
    silog. See :func:`nyu_image`.

Metrics are computed per image over its valid pixels and averaged over the images
(:func:`depth_errors`, :func:`nyu_errors`). Arithmetic follows the inputs' dtype, as the
reference code's does (float32 predictions and ground truth give float32 per-image
metrics); the average over images is float64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import RobodepthError

MIN_DEPTH = 1e-3
KITTI_MAX_DEPTH = 80.0
NYU_MAX_DEPTH = 10.0
STEREO_SCALE = 5.4  # monodepth2's STEREO_SCALE_FACTOR: the KITTI stereo baseline in its units
SIGMOID_MIN_DEPTH, SIGMOID_MAX_DEPTH = 0.1, 100.0  # monodepth2's defaults for disp_to_depth
GARG_CROP = (0.40810811, 0.99189189, 0.03594771, 0.96405229)  # top, bottom, left, right
NYU_EIGEN_CROP = (45, 471, 41, 601)  # rows 45..470, columns 41..600 (slice bounds)
KITTI_METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3")
NYU_METRICS = KITTI_METRICS + ("log10", "silog")
PROTOCOLS = ("kitti", "nyu")
KINDS = ("disp", "sigmoid", "depth")
PNG_SCALE = {"kitti": 256.0, "nyu": 1000.0}  # BTS's units: KITTI depth * 256, NYU millimetres


class EvaluationError(RobodepthError):
    """Predictions or ground truth that cannot be evaluated; the message names the file."""


# --------------------------------------------------------------------------- formulas

def disp_to_depth(disp: np.ndarray, min_depth: float = SIGMOID_MIN_DEPTH,
                  max_depth: float = SIGMOID_MAX_DEPTH) -> np.ndarray:
    """A network's sigmoid output as a scaled disparity (monodepth2's ``disp_to_depth``).

    ``scaled = 1 / max_depth + (1 / min_depth - 1 / max_depth) * disp``; with the defaults
    (0.1, 100) that is ``0.01 + 9.99 * disp``. Its inverse is the depth.
    """
    min_disp = 1 / max_depth
    max_disp = 1 / min_depth
    return min_disp + (max_disp - min_disp) * disp


def garg_crop(height: int, width: int) -> tuple[int, int, int, int]:
    """The Garg crop of an H x W map as slice bounds ``(top, bottom, left, right)``.

    ``top = int(0.40810811 H)``, ``bottom = int(0.99189189 H)``, ``left = int(0.03594771 W)``,
    ``right = int(0.96405229 W)``; the crop is ``rows top..bottom-1, columns left..right-1``.
    """
    t, b, left, right = GARG_CROP
    return int(t * height), int(b * height), int(left * width), int(right * width)


def depth_errors(gt: np.ndarray, pred: np.ndarray) -> tuple:
    """The seven depth metrics of one image over its valid pixels (1-D arrays, same order).

    With ``t = max(gt / pred, pred / gt)`` and means over the pixels:

    - ``abs_rel = mean(|gt - pred| / gt)``
    - ``sq_rel = mean((gt - pred)^2 / gt)``
    - ``rmse = sqrt(mean((gt - pred)^2))``
    - ``rmse_log = sqrt(mean((log gt - log pred)^2))``
    - ``a1, a2, a3 = mean(t < 1.25), mean(t < 1.25^2), mean(t < 1.25^3)``

    Returned in that order (:data:`KITTI_METRICS`).
    """
    thresh = np.maximum(gt / pred, pred / gt)
    a1 = (thresh < 1.25).mean()
    a2 = (thresh < 1.25 ** 2).mean()
    a3 = (thresh < 1.25 ** 3).mean()
    diff = gt - pred
    abs_rel = np.mean(np.abs(diff) / gt)
    sq_rel = np.mean(diff ** 2 / gt)
    rmse = np.sqrt(np.mean(diff ** 2))
    rmse_log = np.sqrt(np.mean((np.log(gt) - np.log(pred)) ** 2))
    return abs_rel, sq_rel, rmse, rmse_log, a1, a2, a3


def nyu_errors(gt: np.ndarray, pred: np.ndarray) -> tuple:
    """:func:`depth_errors` plus the two NYU metrics (:data:`NYU_METRICS` order):

    - ``log10 = mean(|log10 gt - log10 pred|)``
    - ``silog = sqrt(mean(e^2) - mean(e)^2) * 100`` with ``e = log pred - log gt``
    """
    e = np.log(pred) - np.log(gt)
    silog = np.sqrt(np.mean(e ** 2) - np.mean(e) ** 2) * 100
    log10 = np.mean(np.abs(np.log10(pred) - np.log10(gt)))
    return depth_errors(gt, pred) + (log10, silog)


def resize_bilinear(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """``cv2.resize(img, (width, height))``: bilinear, pixel centres aligned (OpenCV's
    ``INTER_LINEAR``), as monodepth2 resizes a disparity to the ground truth's size."""
    import cv2

    return cv2.resize(img, (width, height), interpolation=cv2.INTER_LINEAR)


def upsample_corners(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """Bilinear resize with the corner pixels aligned, as PyTorch's
    ``interpolate(mode="bilinear", align_corners=True)`` (AdaBins's evaluation).

    Output pixel ``(i, j)`` samples the input at ``(y, x) = (s_y i, s_x j)`` with
    ``s_y = (h - 1) / (H - 1)`` and ``s_x = (w - 1) / (W - 1)`` (0 when the output side is
    1): ``out = (1 - ly) ((1 - lx) a[y0, x0] + lx a[y0, x1]) + ly ((1 - lx) a[y1, x0] +
    lx a[y1, x1])`` with ``y0 = floor(y)``, ``y1 = min(y0 + 1, h - 1)``, ``ly = y - y0``,
    likewise for x. Like PyTorch on a float32 tensor, the positions and weights are
    float32 (their rounding moves samples by up to ~1e-5 pixel on a 480-row map, which
    float64 would not reproduce); the result is float32.
    """
    h, w = img.shape
    one = np.float32(1)

    def axis(n_in: int, n_out: int):
        scale = np.float32(n_in - 1) / np.float32(n_out - 1) if n_out > 1 else np.float32(0)
        pos = scale * np.arange(n_out, dtype=np.float32)
        lo = np.minimum(pos.astype(np.intp), n_in - 1)
        hi = np.minimum(lo + 1, n_in - 1)
        return lo, hi, pos - lo.astype(np.float32)

    y0, y1, ly = axis(h, height)
    x0, x1, lx = axis(w, width)
    src = img.astype(np.float32, copy=False)
    top, bottom = src[y0], src[y1]  # separable gathers: rows first, then columns
    lx0, ly0, ly1 = one - lx, (one - ly)[:, None], ly[:, None]
    return (ly0 * (lx0 * top[:, x0] + lx * top[:, x1])
            + ly1 * (lx0 * bottom[:, x0] + lx * bottom[:, x1]))


# --------------------------------------------------------------------------- protocols

@dataclass(frozen=True)
class Setup:
    """How the predictions are read and scored."""

    protocol: str  # "kitti" or "nyu"
    kind: str  # "disp", "sigmoid" or "depth"
    stereo: bool = False
    png_scale: float = 256.0
    kind_given: bool = True  # False: the protocol's default, and a PNG (a depth) overrides it

    @property
    def metrics(self) -> tuple[str, ...]:
        return NYU_METRICS if self.protocol == "nyu" else KITTI_METRICS

    @property
    def median_scaling(self) -> bool:
        return self.protocol == "kitti" and not self.stereo

    def describe(self) -> str:
        if self.protocol == "nyu":
            how = "metric depth, no scaling"
        elif self.stereo:
            how = f"stereo: depth x {STEREO_SCALE}, no median scaling"
        else:
            how = "mono: per-image median scaling"
        return f"protocol {self.protocol} ({how}), predictions: {self.kind}"


def make_setup(protocol: str, kind: str | None = None, stereo: bool = False,
               png_scale: float | None = None) -> Setup:
    """Check a combination of options; :class:`EvaluationError` naming the flag otherwise."""
    if protocol not in PROTOCOLS:
        raise EvaluationError(f"--protocol {protocol!r}: valid: {', '.join(PROTOCOLS)}")
    if kind is not None and kind not in KINDS:
        raise EvaluationError(f"--kind {kind!r}: valid: {', '.join(KINDS)}")
    if protocol == "nyu":
        if stereo:
            raise EvaluationError("--stereo applies to --protocol kitti only (nyu predictions are "
                                  "metric depths, never scaled)")
        if kind not in (None, "depth"):
            raise EvaluationError(f"--kind {kind}: --protocol nyu evaluates depths in metres "
                                  "(--kind depth)")
    if png_scale is not None and not (math.isfinite(png_scale) and png_scale > 0):
        raise EvaluationError(f"--png-scale {png_scale:g}: must be a positive number")
    default = "depth" if protocol == "nyu" else "disp"
    return Setup(protocol, kind or default, stereo,
                 PNG_SCALE[protocol] if png_scale is None else float(png_scale),
                 kind_given=kind is not None)


def kitti_image(pred: np.ndarray, kind: str, stereo: bool, gt_shape: tuple[int, int],
                index: np.ndarray, gt: np.ndarray) -> tuple[tuple, float | None]:
    """One image under the kitti protocol; returns (the :func:`depth_errors`, the median
    scaling ratio or None).

    ``pred`` (any size) is a disparity (``kind="disp"``, already scaled as monodepth2 saves
    it), a raw sigmoid output (``"sigmoid"``: first :func:`disp_to_depth`) or a depth
    (``"depth"``). It is resized to the ground truth's ``gt_shape`` with
    :func:`resize_bilinear`; a disparity is then inverted, ``depth = 1 / disp``. ``index``
    holds the flat indices of the valid pixels (:func:`kitti_valid`) and ``gt`` their depths.
    Mono: ``depth *= median(gt) / median(depth)`` (the ratio); stereo: ``depth *= 5.4``.
    Then ``depth`` is clamped to [1e-3, 80].
    """
    if kind == "sigmoid":
        pred = disp_to_depth(pred)
    pred = resize_bilinear(pred, *gt_shape)
    depth = pred.reshape(-1)[index]
    if kind != "depth":
        with np.errstate(divide="ignore"):
            depth = 1 / depth
    ratio = None
    if stereo:
        depth = depth * STEREO_SCALE
    else:
        ratio = np.median(gt) / np.median(depth)
        depth = depth * ratio
    depth[depth < MIN_DEPTH] = MIN_DEPTH
    depth[depth > KITTI_MAX_DEPTH] = KITTI_MAX_DEPTH
    return depth_errors(gt, depth), ratio


def kitti_valid(gt: np.ndarray) -> np.ndarray:
    """Flat indices (row-major) of the kitti protocol's valid pixels of a ground-truth map:
    ``1e-3 < gt < 80`` inside the :func:`garg_crop`."""
    mask = (gt > MIN_DEPTH) & (gt < KITTI_MAX_DEPTH)
    top, bottom, left, right = garg_crop(*gt.shape)
    crop = np.zeros(gt.shape, bool)
    crop[top:bottom, left:right] = True
    return np.flatnonzero(mask & crop)


def nyu_valid(gt: np.ndarray) -> np.ndarray:
    """Flat indices (row-major) of the nyu protocol's valid pixels: ``1e-3 < gt < 10``
    (non-finite depths count as 0) inside rows 45..470 and columns 41..600."""
    finite = np.isfinite(gt)
    mask = finite & (gt > MIN_DEPTH) & (gt < NYU_MAX_DEPTH)
    top, bottom, left, right = NYU_EIGEN_CROP
    crop = np.zeros(gt.shape, bool)
    crop[top:bottom, left:right] = True
    return np.flatnonzero(mask & crop)


def nyu_image(pred: np.ndarray, gt_shape: tuple[int, int], index: np.ndarray,
              gt: np.ndarray) -> tuple:
    """One image under the nyu protocol; returns the :func:`nyu_errors`.

    ``pred`` is a depth in metres of the ground truth's size, or smaller: then it is first
    upsampled with :func:`upsample_corners`. Clamped to [1e-3, 10] (infinity becomes 10),
    compared at the valid pixels ``index`` (:func:`nyu_valid`) with their depths ``gt``.
    No scaling.
    """
    if pred.shape != gt_shape:
        pred = upsample_corners(pred, *gt_shape)
    depth = pred.reshape(-1)[index]
    depth[depth < MIN_DEPTH] = MIN_DEPTH
    depth[depth > NYU_MAX_DEPTH] = NYU_MAX_DEPTH
    return nyu_errors(gt, depth)


VALID = {"kitti": kitti_valid, "nyu": nyu_valid}
