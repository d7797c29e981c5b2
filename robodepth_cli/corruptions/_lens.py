"""Thin-lens defocus by depth layers, shared by near_focus and far_focus (the rules:
docs/depth-aware-corruptions.md).

The blur radius is ``r(d) = R * min(1, |1 - f/d|)`` pixels for a focus at ``f``. Rendering is
layered, back to front: layers of ``f/d`` half a pixel of radius apart (the focal plane one
layer's centre, so it stays exactly sharp), each layer's premultiplied colour and mask
blurred with an anti-aliased disk and laid over what lies behind it, the sum divided by
the accumulated coverage; so a sharp near object keeps its hard edge over a blurred
background, and a blurred near object spreads over what is behind it."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ._exact import correlate2d

STEP = 0.5  # pixels of blur radius between neighbouring layers (R / 2 for R under a pixel)
U_CAP = 2.0  # f/d beyond this (d < f/2) has the full radius R: one layer


@lru_cache(maxsize=64)
def disk(radius: float) -> np.ndarray:
    """An anti-aliased disk of ``radius`` pixels, summing to 1: a pixel's weight is the part
    of it within the circle, approximated as ``clip(radius + 0.5 - distance, 0, 1)``."""
    span = int(np.ceil(radius))
    c = np.arange(-span, span + 1, dtype=np.float64)
    dist = np.hypot(c[:, None], c[None, :])
    k = np.clip(radius + 0.5 - dist, 0.0, 1.0)
    k = (k / k.sum()).astype(np.float32)
    k.flags.writeable = False
    return k


def spacing(radius: float) -> float:
    """Blur radius between neighbouring layers: :data:`STEP`, or ``radius / 2`` when that
    is smaller, so that even a sub-pixel lens has a layer at its full radius."""
    return min(STEP, radius / 2)


def layer_of(depth: np.ndarray, focus: float, radius: float) -> np.ndarray:
    """Each pixel's layer index ``k``: the layer's ``f/d`` is ``1 + k * s / radius``
    and its blur radius ``min(radius, |k| * s)``, ``s`` the :func:`spacing`; 0 is the
    focal plane."""
    u = np.minimum(focus / depth.astype(np.float64), U_CAP)
    return np.rint((u - 1.0) * (radius / spacing(radius))).astype(np.int32)


def lens_blur(x: np.ndarray, depth: np.ndarray, focus: float, radius: float) -> np.ndarray:
    """``x`` (uint8 H x W x 3) seen through a thin lens focused at ``focus`` metres whose
    blur radius at infinity is ``radius`` pixels: float32 H x W x 3 in 0..255."""
    img = x.astype(np.float32)
    if radius <= STEP:  # a disk of up to half a pixel covers its own pixel only
        return img
    layers = layer_of(depth, focus, radius)
    h, w = layers.shape
    colour = np.zeros((h, w, 3), np.float32)
    cover = np.zeros((h, w), np.float32)
    rgba = np.empty((h, w, 4), np.float32)
    for k in np.unique(layers):  # ascending k: far to near
        inside = layers == k
        r = min(radius, abs(int(k)) * spacing(radius))
        # Only the layer's bounding box grown by the kernel: beyond it the layer adds
        # nothing, and the zeros of the margin reflect as zeros at the box's edge.
        rows, cols = np.flatnonzero(inside.any(axis=1)), np.flatnonzero(inside.any(axis=0))
        m = int(np.ceil(r)) + 1
        box = (slice(max(rows[0] - m, 0), min(rows[-1] + m + 1, h)),
               slice(max(cols[0] - m, 0), min(cols[-1] + m + 1, w)))
        mask = inside[box].astype(np.float32)
        part = rgba[box]
        np.multiply(img[box], mask[:, :, None], out=part[:, :, :3])
        part[:, :, 3] = mask
        if r > STEP:
            part = correlate2d(part, disk(r))
        alpha = part[:, :, 3]
        behind = 1.0 - alpha
        colour[box] *= behind[:, :, None]
        colour[box] += part[:, :, :3]
        cover[box] *= behind
        cover[box] += alpha
    # Every pixel is in a layer whose kernel has weight at its centre, so cover > 0.
    colour /= np.maximum(cover, 1e-6)[:, :, None]
    return colour
