"""The two resizes of the reference evaluators, whole-map: OpenCV's bilinear (monodepth2)
and PyTorch's corner-aligned bilinear (AdaBins). The KITTI protocol samples the first only
at the pixels it compares (:func:`.kernels.sample_linear`, the same values)."""

from __future__ import annotations

import numpy as np


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
