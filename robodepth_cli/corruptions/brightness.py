"""Brightness: raise the HSV value."""

from __future__ import annotations

import numpy as np

from ._jit import njit
from .registry import register
from .severity import interpolate

LEVELS = (0.1, 0.2, 0.3, 0.4, 0.5)


@njit
def _brighten(x, c, out):
    """Per pixel, scikit-image's ``rgb2hsv`` / ``hsv2rgb`` round trip with ``V + c``
    clipped, in float64 with the same operations in the same order, so the result is
    bit-identical to the array formula; then ``uint8(floor(clip01(.) * 255))``."""
    h, w, _ = x.shape
    for i in range(h):
        for j in range(w):
            r = x[i, j, 0] / 255.0
            g = x[i, j, 1] / 255.0
            b = x[i, j, 2] / 255.0
            v = max(r, g, b)
            delta = v - min(r, g, b)
            if delta == 0.0:
                s = 0.0
                hue = 0.0
            else:
                s = delta / v
                # rgb2hsv assigns red, then green, then blue: on ties the later one wins.
                if b == v:
                    hh = 4.0 + (r - g) / delta
                elif g == v:
                    hh = 2.0 + (b - r) / delta
                else:
                    hh = (g - b) / delta
                hue = (hh / 6.0) % 1.0
            v2 = min(max(v + c, 0.0), 1.0)
            hi = np.floor(hue * 6)
            f = hue * 6 - hi
            p = v2 * (1 - s)
            q = v2 * (1 - f * s)
            t = v2 * (1 - (1 - f) * s)
            k = int(hi) % 6
            if k == 0:
                o0, o1, o2 = v2, t, p
            elif k == 1:
                o0, o1, o2 = q, v2, p
            elif k == 2:
                o0, o1, o2 = p, v2, t
            elif k == 3:
                o0, o1, o2 = p, q, v2
            elif k == 4:
                o0, o1, o2 = t, p, v2
            else:
                o0, o1, o2 = v2, p, q
            out[i, j, 0] = np.uint8(min(max(o0, 0.0), 1.0) * 255)
            out[i, j, 1] = np.uint8(min(max(o1, 0.0), 1.0) * 255)
            out[i, j, 2] = np.uint8(min(max(o2, 0.0), 1.0) * 255)
    return out


@register(("c",), LEVELS, deterministic=True)
def brightness(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Raise the HSV value: ``hsv = rgb2hsv(f)``, ``V = clip01(V + c)``,
    ``clip01(hsv2rgb(hsv))`` truncated to uint8, with scikit-image's HSV conversions
    (``f = x / 255``, float64), evaluated pixel by pixel (see :func:`_brighten`).

    Between integer levels: ``c`` linear."""
    return _brighten(x, interpolate(LEVELS, level), np.empty_like(x))
