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

Beyond the two reference protocols, a setup can change how a prediction is aligned to the
ground truth (``align``: none, median, scale, scale-shift, in depth or disparity space; see
:func:`align_prediction`), the crop (garg, eigen, none; :func:`crop_box`) and the valid
depth range, which is also the clamp. The defaults are the protocols' above.

Metrics are computed per image over its valid pixels and averaged over the images
(:func:`depth_errors`, :func:`nyu_errors`). Each pixel's arithmetic follows the inputs'
dtype, as the reference code's does (float32 maps: float32 depths and terms); the sums,
logarithms and averages are float64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import RobodepthError
from .resample import resize_bilinear, upsample_corners  # noqa: F401  (public here too)

MIN_DEPTH = 1e-3
KITTI_MAX_DEPTH = 80.0
NYU_MAX_DEPTH = 10.0
STEREO_SCALE = 5.4  # monodepth2's STEREO_SCALE_FACTOR: the KITTI stereo baseline in its units
SIGMOID_MIN_DEPTH, SIGMOID_MAX_DEPTH = 0.1, 100.0  # monodepth2's defaults for disp_to_depth
GARG_CROP = (0.40810811, 0.99189189, 0.03594771, 0.96405229)  # top, bottom, left, right
NYU_EIGEN_CROP = (45, 471, 41, 601)  # rows 45..470, columns 41..600 (slice bounds)
KITTI_EIGEN_CROP = (0.3324324, 0.91351351, 0.0359477, 0.96405229)  # top, bottom, left, right
KITTI_METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3")
NYU_METRICS = KITTI_METRICS + ("log10", "silog")
PROTOCOLS = ("kitti", "nyu")
KINDS = ("disp", "sigmoid", "depth")
PNG_SCALE = {"kitti": 256.0, "nyu": 1000.0}  # BTS's units: KITTI depth * 256, NYU millimetres
ALIGNS = ("none", "median", "scale", "scale-shift")
ALIGN_SPACES = ("depth", "disparity")
CROPS = ("garg", "eigen", "cityscapes", "none")
CITYSCAPES_CROP = (0.25, 0.75, 0.09375, 0.90625)  # top, bottom, left, right: ManyDepth's
DEFAULT_CROP = {"kitti": "garg", "nyu": "eigen"}
MAX_DEPTH = {"kitti": KITTI_MAX_DEPTH, "nyu": NYU_MAX_DEPTH}


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


def crop_box(crop: str, protocol: str, height: int, width: int) -> tuple[int, int, int, int]:
    """The evaluation crop of an H x W ground-truth map as slice bounds ``(top, bottom,
    left, right)``.

    ``garg``: :func:`garg_crop`. ``eigen``: on KITTI (protocol kitti), rows
    ``int(0.3324324 H)`` .. ``int(0.91351351 H)``, columns ``int(0.0359477 W)`` ..
    ``int(0.96405229 W)``; on NYU (protocol nyu), rows 45..470 and columns 41..600 of the
    480 x 640 map. ``cityscapes``: rows ``int(0.25 H)`` .. ``int(0.75 H)``, columns
    ``int(0.09375 W)`` .. ``int(0.90625 W)`` (ManyDepth's rows 256..767 and columns
    192..1855 of a 1024 x 2048 frame). ``none``: the whole map.
    """
    if crop == "garg":
        return garg_crop(height, width)
    if crop == "cityscapes":
        t, b, left, right = CITYSCAPES_CROP
        return int(t * height), int(b * height), int(left * width), int(right * width)
    if crop == "eigen":
        if protocol == "nyu":
            return NYU_EIGEN_CROP
        t, b, left, right = KITTI_EIGEN_CROP
        return int(t * height), int(b * height), int(left * width), int(right * width)
    return 0, height, 0, width


def valid_pixels(gt: np.ndarray, crop: str, protocol: str, min_depth: float,
                 max_depth: float) -> np.ndarray:
    """Flat indices (row-major) of the valid pixels of a ground-truth map:
    ``min_depth < gt < max_depth`` (NaN and infinity never are) inside :func:`crop_box`."""
    mask = (gt > min_depth) & (gt < max_depth)
    top, bottom, left, right = crop_box(crop, protocol, *gt.shape)
    inside = np.zeros(gt.shape, bool)
    inside[top:bottom, left:right] = True
    return np.flatnonzero(mask & inside)


def align_prediction(values: np.ndarray, is_disp: bool, gt: np.ndarray, align: str,
                     space: str, min_depth: float, max_depth: float,
                     factor: float | None = None) -> tuple[np.ndarray, float | None]:
    """A prediction's values at an image's valid pixels, aligned to the ground truth's
    depths ``gt`` there, as depths clamped to ``[min_depth, max_depth]``; and the scale
    ``s`` used (None for ``none``).

    ``values`` is a disparity (``is_disp``) or a depth. In ``space`` ``"depth"`` the
    prediction ``p`` is a depth (a disparity is inverted) and ``g = gt``; in
    ``"disparity"``, ``p`` is a disparity (a depth is inverted) and ``g = 1 / gt``. Then:

    - ``none``: ``a = p`` (times ``factor`` when given: stereo's 5.4);
    - ``median``: ``a = s p`` with ``s = median(g) / median(p)`` (monodepth2's median scaling);
    - ``scale``: ``a = s p`` with ``s = sum(p g) / sum(p^2)``: least squares of ``s p``
      against ``g``;
    - ``scale-shift``: ``a = s p + t``, least squares of ``s p + t`` against ``g``:
      ``s = sum((p - mean p)(g - mean g)) / sum((p - mean p)^2)``, ``t = mean(g) - s mean(p)``
      (``s = 0``, ``t = mean(g)`` when ``p`` is constant).

    Least squares is computed in float64. The aligned ``a`` is a depth (``d = a``) or a
    disparity (``d = 1 / a``, and ``d = max_depth`` where ``a <= 0``: nothing is farther);
    then ``d`` is clamped to ``[min_depth, max_depth]``, as the protocols clamp.
    """
    # Zeros and infinities may be inverted here; a NaN they lead to is refused below.
    with np.errstate(divide="ignore", invalid="ignore"):
        p, g = ((1 / values if is_disp else values), gt) if space == "depth" else \
            ((values if is_disp else 1 / values), 1 / gt)
        s = None
        if align == "none":
            a = p if factor is None else p * factor
        elif align == "median":
            s = median_ratio(g, p, space, is_disp)
            a = p * s
        else:
            p64, g64 = p.astype(np.float64), g.astype(np.float64)
            if align == "scale":
                s = float(np.dot(p64, g64) / np.dot(p64, p64))
                a = p64 * s
            else:
                dp = p64 - p64.mean()
                var = float(np.dot(dp, dp))
                s = float(np.dot(dp, g64 - g64.mean()) / var) if var > 0 else 0.0
                a = p64 * s + (g64.mean() - s * p64.mean())
        if space == "disparity":
            positive = a > 0
            d = np.where(positive, 1 / np.where(positive, a, 1), max_depth).astype(a.dtype)
        else:
            d = a.copy() if a is values else a
    if np.isnan(d).any():
        raise _not_a_number(align, space)
    d[d < min_depth] = min_depth
    d[d > max_depth] = max_depth
    return d, s


def median_ratio(g: np.ndarray, p: np.ndarray, space: str = "depth", is_disp: bool = True,
                 g_median=None):
    """``median(g) / median(p)`` (monodepth2's median scaling; ``g_median``: ``median(g)``
    when known) in the arrays' dtype, as numpy computes it; :class:`EvaluationError`
    unless it is positive and finite."""
    try:
        from .kernels import median
    except ImportError:  # no numba (a challenge's scoring program): numpy's, the same number
        median = np.median

    with np.errstate(divide="ignore", invalid="ignore"):
        s = (median(g) if g_median is None else g_median) / median(p)
    if not (np.isfinite(s) and s > 0):
        raise EvaluationError(
            f"median scaling needs a positive finite median {space} at the valid "
            "pixels, and this map is 0 at half of them or more "
            f"({'infinitely far' if is_disp else 'distance 0'})")
    return s


def _not_a_number(align: str, space: str) -> EvaluationError:
    # e.g. a zero disparity inverted for the depth space: no number to report
    return EvaluationError(f"not a number after --align {align} in {space} space (zero or "
                           "infinite values where 1/x is taken?)")


def depth_errors(gt: np.ndarray, pred: np.ndarray) -> tuple:
    """The seven depth metrics of one image over its valid pixels (1-D arrays, same order).

    With ``t = max(gt / pred, pred / gt)`` and means over the pixels:

    - ``abs_rel = mean(|gt - pred| / gt)``
    - ``sq_rel = mean((gt - pred)^2 / gt)``
    - ``rmse = sqrt(mean((gt - pred)^2))``
    - ``rmse_log = sqrt(mean((log gt - log pred)^2))``
    - ``a1, a2, a3 = mean(t < 1.25), mean(t < 1.25^2), mean(t < 1.25^3)``

    Returned in that order (:data:`KITTI_METRICS`), as float64: each pixel's terms in the
    arrays' (promoted) dtype, as numpy would compute them, the sums and logarithms in
    float64, in one pass (:func:`.kernels.errors`; where numba is not installed, as in a
    challenge's scoring program on Codabench's image, :func:`_numpy_errors`).
    """
    return _errors(gt, pred, nyu=False)


def nyu_errors(gt: np.ndarray, pred: np.ndarray) -> tuple:
    """:func:`depth_errors` plus the two NYU metrics (:data:`NYU_METRICS` order):

    - ``log10 = mean(|log10 gt - log10 pred|)``
    - ``silog = sqrt(mean(e^2) - mean(e)^2) * 100`` with ``e = log pred - log gt``
    """
    return _errors(gt, pred, nyu=True)


def _errors(gt: np.ndarray, pred: np.ndarray, nyu: bool) -> tuple:
    try:
        from .kernels import errors
    except ImportError:  # no numba: the same terms and float64 sums, in numpy's passes
        return _numpy_errors(gt, pred, nyu)
    return errors(gt, pred, nyu=nyu)


def _numpy_errors(gt: np.ndarray, pred: np.ndarray, nyu: bool) -> tuple:
    """:func:`depth_errors` (``nyu``: :func:`nyu_errors`) in numpy: each pixel's terms in
    the arrays' dtype, the logarithms and sums in float64 (pairwise sums, so the last bits
    may differ from the kernel's pixel-order sums: far below the metrics' 1e-6)."""
    f8 = np.float64
    t = np.maximum(gt / pred, pred / gt)
    diff = gt - pred
    e = np.log(pred.astype(f8)) - np.log(gt.astype(f8))
    out = (np.mean(np.abs(diff) / gt, dtype=f8), np.mean(diff * diff / gt, dtype=f8),
           math.sqrt(np.mean(diff * diff, dtype=f8)), math.sqrt(np.mean(e * e)),
           np.mean(t < 1.25), np.mean(t < 1.25 ** 2), np.mean(t < 1.25 ** 3))
    if nyu:
        out += (np.mean(np.abs(e)) / math.log(10), math.sqrt(max(np.mean(e * e) - np.mean(e) ** 2, 0.0)) * 100)
    return tuple(float(v) for v in out)


# --------------------------------------------------------------------------- protocols

@dataclass(frozen=True)
class Setup:
    """How the predictions are read and scored (build one with :func:`make_setup`)."""

    protocol: str  # "kitti" or "nyu"
    kind: str  # "disp", "sigmoid" or "depth"
    stereo: bool = False
    png_scale: float = 256.0
    kind_given: bool = True  # False: the protocol's default, and a PNG (a depth) overrides it
    align: str | None = None  # None: the protocol's (kitti mono: median; stereo, nyu: none)
    align_space: str = "depth"
    crop: str | None = None  # None: the protocol's (kitti: garg, nyu: eigen)
    min_depth: float = MIN_DEPTH
    max_depth: float | None = None  # None: the protocol's (kitti 80, nyu 10)

    @property
    def alignment(self) -> str:
        if self.align is not None:
            return self.align
        return "median" if self.protocol == "kitti" and not self.stereo else "none"

    @property
    def crop_name(self) -> str:
        return self.crop or DEFAULT_CROP[self.protocol]

    @property
    def depth_cap(self) -> float:
        return MAX_DEPTH[self.protocol] if self.max_depth is None else self.max_depth

    @property
    def metrics(self) -> tuple[str, ...]:
        return NYU_METRICS if self.protocol == "nyu" else KITTI_METRICS

    @property
    def median_scaling(self) -> bool:
        return self.alignment == "median"

    @property
    def is_default(self) -> bool:
        """Whether alignment, crop and depth range are the protocol's own."""
        return (self.alignment == Setup(self.protocol, self.kind, self.stereo).alignment
                and self.align_space == "depth" and self.crop_name == DEFAULT_CROP[self.protocol]
                and self.min_depth == MIN_DEPTH and self.depth_cap == MAX_DEPTH[self.protocol])

    def valid(self, gt: np.ndarray) -> np.ndarray:
        """Flat indices of the valid pixels of a ground-truth map (:func:`valid_pixels`)."""
        return valid_pixels(gt, self.crop_name, self.protocol, self.min_depth, self.depth_cap)

    @property
    def valid_rule(self) -> str:
        """What decides :meth:`valid`'s pixels, as text: the protocol, crop and depth range."""
        return f"{self.protocol} {self.crop_name} {self.min_depth!r} {self.depth_cap!r}"

    def describe(self) -> str:
        if self.is_default:
            if self.protocol == "nyu":
                how = "metric depth, no scaling"
            elif self.stereo:
                how = f"stereo: depth x {STEREO_SCALE}, no median scaling"
            else:
                how = "mono: per-image median scaling"
        else:
            how = (f"align {self.alignment}" + (f" in {self.align_space} space"
                                                if self.alignment != "none" else "")
                   + (f", stereo x {STEREO_SCALE}" if self.stereo else "")
                   + f", crop {self.crop_name}, depths {self.min_depth:g}..{self.depth_cap:g}")
        return f"protocol {self.protocol} ({how}), predictions: {self.kind}"


def make_setup(protocol: str, kind: str | None = None, stereo: bool = False,
               png_scale: float | None = None, *, align: str | None = None,
               align_space: str | None = None, crop: str | None = None,
               min_depth: float | None = None, max_depth: float | None = None) -> Setup:
    """Check a combination of options; :class:`EvaluationError` naming the flag otherwise.
    Options left None take the protocol's defaults."""
    if protocol not in PROTOCOLS:
        raise EvaluationError(f"--protocol {protocol!r}: valid: {', '.join(PROTOCOLS)}")
    if kind is not None and kind not in KINDS:
        raise EvaluationError(f"--kind {kind!r}: valid: {', '.join(KINDS)}")
    if align is not None and align not in ALIGNS:
        raise EvaluationError(f"--align {align!r}: valid: {', '.join(ALIGNS)}")
    if align_space is not None and align_space not in ALIGN_SPACES:
        raise EvaluationError(f"--align-space {align_space!r}: valid: {', '.join(ALIGN_SPACES)}")
    if crop is not None and crop not in CROPS:
        raise EvaluationError(f"--crop {crop!r}: valid: {', '.join(CROPS)}")
    if stereo:
        if align not in (None, "none"):
            raise EvaluationError(f"--stereo scales by {STEREO_SCALE} and aligns nothing; it takes "
                                  f"no --align {align}")
        if align_space not in (None, "depth"):
            raise EvaluationError("--stereo scales the depth; it takes no --align-space disparity")
    if protocol == "nyu":
        if stereo:
            raise EvaluationError("--stereo applies to --protocol kitti only (nyu predictions are "
                                  "metric depths, never scaled)")
        if kind not in (None, "depth") and align in (None, "none"):
            raise EvaluationError(f"--kind {kind}: --protocol nyu evaluates depths in metres "
                                  "(--kind depth), or a relative map with --align")
    low = MIN_DEPTH if min_depth is None else float(min_depth)
    high = MAX_DEPTH[protocol] if max_depth is None else float(max_depth)
    if not (math.isfinite(low) and math.isfinite(high) and 0 < low < high):
        raise EvaluationError(f"--min-depth {low:g} / --max-depth {high:g}: need "
                              "0 < min-depth < max-depth")
    if png_scale is not None and not (math.isfinite(png_scale) and png_scale > 0):
        raise EvaluationError(f"--png-scale {png_scale:g}: must be a positive number")
    default = "depth" if protocol == "nyu" else "disp"
    return Setup(protocol, kind or default, stereo,
                 PNG_SCALE[protocol] if png_scale is None else float(png_scale),
                 kind_given=kind is not None, align=align, align_space=align_space or "depth",
                 crop=crop, min_depth=low, max_depth=None if max_depth is None else high)


def kitti_image(pred: np.ndarray, kind: str, stereo: bool, gt_shape: tuple[int, int],
                index: np.ndarray, gt: np.ndarray, setup: Setup | None = None, *,
                gt_median=None) -> tuple[tuple, float | None]:
    """One image under the kitti protocol; returns (the :func:`depth_errors`, the median
    scaling ratio or None).

    ``pred`` (any size) is a disparity (``kind="disp"``, already scaled as monodepth2 saves
    it), a raw sigmoid output (``"sigmoid"``: first :func:`disp_to_depth`) or a depth
    (``"depth"``), resized to ``gt_shape`` as :func:`resize_bilinear` does, but only at the
    pixels compared (:func:`.kernels.sample_linear`: the same values); a disparity is then
    inverted. ``index``: the flat indices of the valid pixels (:func:`kitti_valid`), ``gt``
    their depths (``gt_median``: its median, when known). Mono: ``depth *= median(gt) /
    median(depth)`` (the ratio); stereo: ``depth *= 5.4``. Then ``depth`` is clamped to
    [1e-3, 80]. A ``setup`` with another alignment, space or depth range aligns by
    :func:`align_prediction` (the median rule is its ``median`` in depth space).
    """
    if setup is None:
        setup = Setup("kitti", kind, stereo)
    from .kernels import sample_linear, scaled_errors

    is_disp = kind != "depth"
    # Median scaling and stereo's factor in one pass; other alignments by align_prediction.
    direct = setup.align_space == "depth" and setup.alignment in ("none", "median")
    values = sample_linear(pred, gt_shape, index, invert=direct and is_disp,
                           sigmoid=_SIGMOID if kind == "sigmoid" else None)
    if not direct:
        depth, s = align_prediction(values, is_disp, gt, setup.alignment, setup.align_space,
                                    setup.min_depth, setup.depth_cap,
                                    STEREO_SCALE if stereo else None)
        return depth_errors(gt, depth), (s if setup.alignment == "median" else None)
    if setup.alignment == "median":
        s = median_ratio(gt, values, "depth", is_disp, gt_median)
    else:
        s = values.dtype.type(STEREO_SCALE) if stereo else None  # numpy's p * 5.4
    errs = scaled_errors(gt, values, s, setup.min_depth, setup.depth_cap)
    if errs is None:
        raise _not_a_number(setup.alignment, "depth")
    return errs, (s if setup.alignment == "median" else None)


_SIGMOID = (1 / SIGMOID_MAX_DEPTH, 1 / SIGMOID_MIN_DEPTH - 1 / SIGMOID_MAX_DEPTH)  # disp_to_depth's


def kitti_valid(gt: np.ndarray) -> np.ndarray:
    """Flat indices (row-major) of the kitti protocol's valid pixels of a ground-truth map:
    ``1e-3 < gt < 80`` inside the :func:`garg_crop`."""
    return valid_pixels(gt, "garg", "kitti", MIN_DEPTH, KITTI_MAX_DEPTH)


def nyu_valid(gt: np.ndarray) -> np.ndarray:
    """Flat indices (row-major) of the nyu protocol's valid pixels: ``1e-3 < gt < 10``
    (non-finite depths never count) inside rows 45..470 and columns 41..600."""
    return valid_pixels(gt, "eigen", "nyu", MIN_DEPTH, NYU_MAX_DEPTH)


def nyu_image(pred: np.ndarray, gt_shape: tuple[int, int], index: np.ndarray,
              gt: np.ndarray, setup: Setup | None = None, kind: str | None = None) -> tuple:
    """One image under the nyu protocol; returns the :func:`nyu_errors`.

    ``pred`` is a depth in metres of the ground truth's size, or smaller: then it is first
    upsampled with :func:`upsample_corners`. Clamped to [1e-3, 10] (infinity becomes 10),
    compared at the valid pixels ``index`` (:func:`nyu_valid`) with their depths ``gt``.
    No scaling. A ``setup`` with another kind, alignment or depth range goes through
    :func:`align_prediction` (a sigmoid output first through :func:`disp_to_depth`).
    """
    if setup is None:
        setup = Setup("nyu", "depth")
    kind = kind or setup.kind
    if kind == "sigmoid":
        pred = disp_to_depth(pred)
    if pred.shape != gt_shape:
        pred = upsample_corners(pred, *gt_shape)
    values = pred.reshape(-1)[index]
    if kind == "depth" and setup.alignment == "none":  # clamped and compared in one pass
        from .kernels import scaled_errors

        errs = scaled_errors(gt, values, None, setup.min_depth, setup.depth_cap, nyu=True)
        if errs is None:
            raise _not_a_number("none", setup.align_space)
        return errs
    depth, _ = align_prediction(values, kind != "depth", gt, setup.alignment,
                                setup.align_space, setup.min_depth, setup.depth_cap)
    return nyu_errors(gt, depth)


def whole_map_image(pred: np.ndarray, kept: np.ndarray, divisor: float | None,
                    setup: Setup) -> tuple | None:
    """The metrics of one image whose ground truth is a whole map, ``depth = kept /
    divisor`` in float32 (``divisor`` None: ``kept`` as it is), in one pass with no
    per-pixel arrays: :func:`nyu_image`'s (or :func:`kitti_image`'s) numbers at the map's
    :meth:`Setup.valid` pixels. None where it does not apply: a prediction of another size,
    a setup that aligns, scales or converts it, a map neither integer nor float32."""
    if (pred.shape != kept.shape or setup.kind != "depth" or setup.stereo
            or setup.alignment != "none"
            or not (kept.dtype.kind in "iu" or kept.dtype == np.float32)):
        return None
    from .kernels import dense_errors

    result = dense_errors(pred, kept, 1.0 if divisor is None else divisor,
                          crop_box(setup.crop_name, setup.protocol, *kept.shape),
                          (setup.min_depth, setup.depth_cap), setup.min_depth, setup.depth_cap,
                          nyu=setup.protocol == "nyu")
    if result is None:
        raise _not_a_number("none", setup.align_space)
    return result[0]


VALID = {"kitti": kitti_valid, "nyu": nyu_valid}
