"""Snow (SPEC section 2, definition 5): a zoomed, thresholded, motion-blurred noise layer
added twice (once rotated by 180 degrees) to a whitened image."""

from __future__ import annotations

import cv2
import numpy as np

from ._ops import to_uint8
from .motion_blur import shift_blur
from .registry import WEATHER, register
from .zoom_blur import linear_zoom, zoom_axis

LEVELS = (
    (0.1, 0.3, 3, 0.5, 10, 4, 0.8),
    (0.2, 0.3, 2, 0.5, 12, 4, 0.7),
    (0.55, 0.3, 4, 0.9, 12, 8, 0.7),
    (0.55, 0.3, 4.5, 0.85, 12, 8, 0.65),
    (0.55, 0.3, 2.5, 0.85, 12, 12, 0.55),
)


def snow_layer(shape: tuple[int, int], mu: float, sigma: float, z: float, tau: float,
               radius: int, s: float, rng: np.random.Generator) -> np.ndarray:
    """The snow layer ``S`` of an H x W image, uint8 in 0..255 (``S * 255`` of the SPEC).

    ``Normal(mu, sigma)`` noise, clipped-zoomed by ``z``; values ``< tau`` set to 0; clip01;
    motion-blurred (``radius``, ``s``, angle uniform in [-135, -45) degrees, drawn after the
    noise) on the whole zoomed layer, whose replicated edges are its own; rounded to
    1/255; cropped to H x W.

    The clipped zoom reads only the centre ``ceil(H / z)`` x ``ceil(W / z)`` block of the
    noise, so only that block is drawn: the layer has the same distribution as when the
    whole H x W is drawn, at a fraction of the cost.
    """
    h, w = shape
    _, ch, _ = zoom_axis(h, z)
    _, cw, _ = zoom_axis(w, z)
    noise = rng.standard_normal((ch, cw), dtype=np.float32)
    noise *= np.float32(sigma)
    noise += np.float32(mu)
    layer = linear_zoom(noise, z)
    layer[layer < tau] = 0
    np.clip(layer, 0, 1, out=layer)
    angle = rng.uniform(-135, -45)
    blurred = shift_blur(layer, radius, sigma=s, angle=angle)
    # round(S * 255): values stay within 0..255 because the blur weights sum to 1.
    return np.rint(blurred[:h, :w] * np.float32(255)).astype(np.uint8)


@register(WEATHER, ("mu", "sigma", "z", "tau", "r", "s", "beta"), LEVELS)
def snow(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """On ``f = x / 255`` in float32: ``g = beta * f + (1 - beta) * max(f, gray(f) * 1.5 +
    0.5)`` with ``gray`` OpenCV's RGB-to-gray, then ``clip01(g + S + rot180(S))`` with ``S``
    the :func:`snow_layer` / 255 on every channel; truncated to uint8."""
    mu, sigma, z, tau, radius, s, beta = LEVELS[level - 1]
    h, w = x.shape[:2]
    layer = snow_layer((h, w), mu, sigma, z, tau, radius, s, rng)
    f = x.astype(np.float32) * np.float32(1 / 255)
    lifted = cv2.cvtColor(f, cv2.COLOR_RGB2GRAY)
    lifted *= np.float32(1.5)
    lifted += np.float32(0.5)
    g = np.maximum(f, lifted[..., None])
    g *= np.float32(1 - beta)
    g += np.float32(beta) * f
    # Both snow terms in one uint16 sum: at most 510, exact.
    flakes = layer.astype(np.uint16) + layer[::-1, ::-1]
    g += (flakes * np.float32(1 / 255))[..., None]
    return to_uint8(g)
