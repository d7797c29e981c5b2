"""Kernels that only a severity size makes long: on a 4032 x 6048 frame, level 5's motion
streak at 192x640's severity has 561 taps and glass blur's sigma is 21 pixels. Applied
directly they would take time in proportion to their taps; these take about the time of
the tabulated (short) kernels. None of them is used at a tabulated size, whose bytes stay
those of the exact kernels."""

from __future__ import annotations

import math

import cv2
import numpy as np


def box_gaussian(img: np.ndarray, sigma: float, border: int) -> np.ndarray:
    """A Gaussian blur of ``sigma`` (both axes, each channel) as three box blurs whose
    widths give the Gaussian's variance (to a rounding of the last box, Kovesi's
    almost-Gaussian filtering); time independent of ``sigma``. Samples outside the image
    by OpenCV ``border``; the result has ``img``'s float dtype."""
    n = 3
    ideal = math.sqrt(12 * sigma * sigma / n + 1)
    lower = int(ideal) - (int(ideal) % 2 == 0)  # odd, at most the ideal width
    upper = lower + 2
    m = round((12 * sigma * sigma - n * lower * lower - 4 * n * lower - 3 * n) / (-4 * lower - 4))
    widths = [lower] * m + [upper] * (n - m)
    # Padded once, so that every box reads the image's own extension (as one Gaussian would),
    # not the previous box's blurred border.
    pad = sum(w // 2 for w in widths)
    h, w = img.shape[:2]
    out = cv2.copyMakeBorder(img, pad, pad, pad, pad, border)
    for width in widths:
        out = cv2.blur(out, (width, width), borderType=border)
    return np.ascontiguousarray(out[pad:pad + h, pad:pad + w])


def split_streak(dys: np.ndarray, dxs: np.ndarray, ks: np.ndarray):
    """A streak of taps ``(dys, dxs, ks)`` (shifts that all lead one way from the origin)
    as two: ``m`` unit taps of its first ``m`` shifts, weight ``1 / m`` each, then every
    ``m``-th shift weighted by the sum of its block of ``m`` weights, ``m`` about the root
    of the taps: ``m + n / m`` taps instead of ``n``. The shifts add up to within a pixel of
    the originals (their rounding), the weights vary over a block by ``m / sigma``.

    Returns ``((dys1, dxs1, ks1), (dys2, dxs2, ks2))``."""
    n = len(ks)
    m = max(1, int(round(math.sqrt(n))))
    starts = np.arange(0, n, m)
    block = np.add.reduceat(ks, starts)
    first = (dys[:m], dxs[:m], np.full(min(m, n), 1.0 / min(m, n)))
    return first, (dys[starts], dxs[starts], block)
