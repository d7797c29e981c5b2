"""The scene depth a depth-aware corruption receives: checked, sized to the image, with no
missing value left, by the same rules for every corruption (docs/depth-aware-corruptions.md),
so a chain sees one scene: metres, H x W; a value not finite or not above 0 is missing and
takes the depth of the nearest valid pixel; another size of the same aspect ratio (within
2 %) is resized by nearest neighbour after filling, another aspect ratio refused; no valid
value at all: :data:`FAR` metres; depths clipped to ``[NEAR, FAR]``."""

from __future__ import annotations

import numpy as np

from ..errors import RobodepthError

NEAR = 0.05  # metres: nothing a camera sees sharply is nearer
FAR = 1000.0  # metres: the depth of a scene without any valid value, and the clip


class DepthError(RobodepthError):
    """A depth map that cannot be read (the message names the file) or used with an image,
    or a depth-aware corruption without one."""


def scene_depth(depth, shape: tuple[int, int]) -> np.ndarray:
    """``depth`` prepared for an image of ``shape`` (H, W) by the rules above: float32 H x W,
    every value in ``[NEAR, FAR]``. :class:`DepthError` for a map that is not 2-D or has
    another aspect ratio."""
    d = np.asarray(depth)
    if d.ndim == 3 and d.shape[2] == 1:
        d = d[:, :, 0]
    if d.ndim != 2 or d.size == 0 or not np.issubdtype(d.dtype, np.number):
        raise DepthError(f"depth: expected an H x W array of metres, got shape {d.shape} {d.dtype}")
    h, w = shape
    dh, dw = d.shape
    if abs(dh * w - dw * h) > 0.02 * dh * w:
        raise DepthError(f"depth: {dh}x{dw} (HxW) does not have the image's aspect ratio ({h}x{w})")
    d = nearest_resize(fill_missing(d), shape)
    out = np.clip(d, NEAR, FAR).astype(np.float32)
    out.flags.writeable = False
    return out


def fill_missing(depth: np.ndarray) -> np.ndarray:
    """``depth`` as float64 with every missing value (not finite, or not above 0) replaced
    by the nearest valid pixel's, :data:`FAR` everywhere when none is valid."""
    d = np.asarray(depth, dtype=np.float64)
    missing = ~np.isfinite(d) | (d <= 0)
    if missing.all():
        return np.full(d.shape, FAR)
    if missing.any():
        from scipy.ndimage import distance_transform_edt

        idx = distance_transform_edt(missing, return_distances=False, return_indices=True)
        return d[idx[0], idx[1]]
    return d


def nearest_resize(d: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``d`` at ``shape`` (H, W) by nearest neighbour: each output pixel the input pixel
    under its centre (any aspect ratio; no depth between two surfaces is invented)."""
    h, w = shape
    dh, dw = d.shape
    if (dh, dw) == (h, w):
        return d
    rows = np.minimum((np.arange(h) + 0.5) * dh / h, dh - 1).astype(np.intp)
    cols = np.minimum((np.arange(w) + 0.5) * dw / w, dw - 1).astype(np.intp)
    return d[rows[:, None], cols[None, :]]


def round_to_uint8(v: np.ndarray) -> np.ndarray:
    """``uint8(floor(clip(v, 0, 255) + 0.5))``: a physical model's value rounded to the
    nearest level, halves up (the 18's truncation would darken every pixel by half a level)."""
    out = np.clip(v, 0.0, 255.0)
    out += 0.5
    return np.floor(out, out=out).astype(np.uint8)
