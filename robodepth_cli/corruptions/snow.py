"""Snow: a zoomed, thresholded, motion-blurred noise layer
added twice (once rotated by 180 degrees) to a whitened image."""

from __future__ import annotations

import numpy as np

from ._jit import njit
from .motion_blur import scaled_radius, shift_blur
from .registry import register
from .severity import LINEAR, ROUND, interpolate
from .zoom_blur import linear_zoom, zoom_axis

LEVELS = (
    (0.1, 0.3, 3, 0.5, 10, 4, 0.8),
    (0.2, 0.3, 2, 0.5, 12, 4, 0.7),
    (0.55, 0.3, 4, 0.9, 12, 8, 0.7),
    (0.55, 0.3, 4.5, 0.85, 12, 8, 0.65),
    (0.55, 0.3, 2.5, 0.85, 12, 12, 0.55),
)


def snow_noise(shape: tuple[int, int], mu: float, sigma: float, z: float,
               rng: np.random.Generator) -> np.ndarray:
    """The ``Normal(mu, sigma)`` float32 noise of the snow layer, only the centre block of
    ``ceil(H / z)`` x ``ceil(W / z)`` that the clipped zoom reads (see :func:`snow_layer`):
    the first draw of snow on ``rng``, shared by both engines."""
    _, ch, _ = zoom_axis(shape[0], z)
    _, cw, _ = zoom_axis(shape[1], z)
    noise = rng.standard_normal((ch, cw), dtype=np.float32)
    noise *= np.float32(sigma)
    noise += np.float32(mu)
    return noise


def snow_layer(shape: tuple[int, int], mu: float, sigma: float, z: float, tau: float,
               radius: int, s: float, rng: np.random.Generator) -> np.ndarray:
    """The snow layer ``S`` of an H x W image before its rounding: float32, at least
    H x W (the zoomed size; :func:`_blend` rounds it and reads its top-left H x W).

    ``Normal(mu, sigma)`` noise, clipped-zoomed by ``z``; values ``< tau`` set to 0; clip01;
    motion-blurred (``radius``, ``s``, angle uniform in [-135, -45) degrees, drawn after the
    noise) on the whole zoomed layer, whose replicated edges are its own.

    The clipped zoom reads only the centre ``ceil(H / z)`` x ``ceil(W / z)`` block of the
    noise, so only that block is drawn: the layer has the same distribution as when the
    whole H x W is drawn, at a fraction of the cost.
    """
    layer = linear_zoom(snow_noise(shape, mu, sigma, z, rng), z)
    layer[layer < tau] = 0
    np.clip(layer, 0, 1, out=layer)
    angle = rng.uniform(-135, -45)
    return shift_blur(layer, radius, sigma=s, angle=angle)


@njit
def _blend(x, layer, beta, out):
    """Per pixel and channel, with ``f = x / 255`` in float32:
    ``g = beta * f + (1 - beta) * max(f, gray * 1.5 + 0.5)``, ``gray = 0.299 R + 0.587 G +
    0.114 B`` (OpenCV's RGB-to-gray); ``S = round(layer * 255) / 255`` on the top-left
    H x W of ``layer``; ``out = floor(clip01(g + S + rot180(S)) * 255)``."""
    h, w, _ = x.shape
    b = np.float32(beta)
    nb = np.float32(1.0) - b
    scale = np.float32(1.0 / 255.0)
    for i in range(h):
        for j in range(w):
            r = x[i, j, 0] * scale
            g = x[i, j, 1] * scale
            bl = x[i, j, 2] * scale
            lift = (np.float32(0.299) * r + np.float32(0.587) * g + np.float32(0.114) * bl) \
                * np.float32(1.5) + np.float32(0.5)
            flakes = (np.rint(layer[i, j] * np.float32(255))
                      + np.rint(layer[h - 1 - i, w - 1 - j] * np.float32(255))) * scale
            for c in range(3):
                f = x[i, j, c] * scale
                v = b * f + nb * max(f, lift) + flakes
                out[i, j, c] = np.uint8(min(max(v, np.float32(0)), np.float32(1)) * np.float32(255))
    return out


# The blur radius is a whole number of pixels; every other parameter is continuous.
RULES = (LINEAR, LINEAR, LINEAR, LINEAR, ROUND, LINEAR, LINEAR)


@register(("mu", "sigma", "z", "tau", "r", "s", "beta"), LEVELS, rules=RULES, scaled=True)
def snow(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """On ``f = x / 255`` in float32: ``g = beta * f + (1 - beta) * max(f, gray(f) * 1.5 +
    0.5)`` with ``gray`` OpenCV's RGB-to-gray, then ``clip01(g + S + rot180(S))`` with ``S``
    the :func:`snow_layer` rounded to 1/255 and cropped to H x W, on every channel;
    truncated to uint8 (fused in :func:`_blend`).

    Size rule: without a severity size (as imagecorruptions-imaug 1.1.5) the noise is
    drawn at the image size and zoomed by the fixed factor ``z``, so flakes are ``z``
    pixels wide at any size, and the blur's radius is fixed in pixels; with one, ``z``,
    ``r`` (rounded, halves up) and ``s`` are multiplied by its ``scale``, so the flakes and
    their streaks keep their share of the image (and the number of flakes stays that of
    the severity size). The blur's taps stop at the layer's border
    (:func:`~.motion_blur.motion_taps`); the zoomed layer, ``round(ceil(H / z) * z)`` by
    ``round(ceil(W / z) * z)``, is at least H x W and is cropped to its top-left H x W.

    Between integer levels: ``mu``, ``sigma``, ``z`` (a fractional zoom is resampled like
    any other), ``tau``, ``s`` and ``beta`` linear; the blur radius ``r`` linear, rounded to
    the nearest integer (halves up)."""
    mu, sigma, z, tau, radius, s, beta = interpolate(LEVELS, level, RULES)
    if scale is not None:
        z, radius, s = z * scale, scaled_radius(radius, scale), s * scale
    h, w = x.shape[:2]
    layer = snow_layer((h, w), mu, sigma, z, tau, radius, s, rng)
    return _blend(x, layer[:h, :w], beta, np.empty_like(x))
