"""Camera motion during the exposure, shared by motion_3d and zoom_3d.

A pinhole camera with its principal point at the image centre ``(cx, cy) = ((W-1)/2,
(H-1)/2)`` moves by ``(tx, 0, tz)`` metres. A pixel ``(x, y)`` at depth ``Z`` is then seen at

    x' = cx + ((x - cx) Z - a) / (Z - tz),   y' = cy + (y - cy) Z / (Z - tz)

with ``a = focal * tx`` (pixels x metres). Each path is set in pixels at the scene's median
depth ``Zm`` (a sideways shift of ``D`` pixels there is ``a = D * Zm``; a forward travel is
a fraction of ``Zm``), so the focal length cancels: the same level moves KITTI's street
and NYU's room by the same amount at their median distance, nearer things more.

One frame: every source pixel is splatted to its nearest target pixel, the nearest surface
winning (z-buffer); points that would reach the camera (``Z - tz < 0.05 Z``) leave the view.
Target pixels nobody reached are holes: each takes the depth of its farthest reached
neighbour, pass by pass (uncovered background continues the background, not the object that
uncovered it). Every target pixel is then traced back to the source with its depth and
sampled bilinearly; a hole whose trace lands outside the image or on a nearer surface (a
disocclusion: the source never saw it) instead takes the colour of its farthest coloured
neighbour. The exposure is the mean of ``n`` frames on a path centred on the captured
position (offsets ``i / (n - 1) - 1/2`` of the path, ``i = 0..n-1``), so the blurred image
stays aligned with the scene's depth; ``n`` (8..32) gives about one pixel of motion per
frame at the 2nd percentile of the depth.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import njit

MIN_FRAMES, MAX_FRAMES = 8, 32


@njit
def _splat(depth, a, tz, cx, cy, zbuf):
    h, w = depth.shape
    for y in range(h):
        for x in range(w):
            z = depth[y, x]
            zn = z - tz
            if zn < 0.05 * z:
                continue
            xt = cx + ((x - cx) * z - a) / zn
            yt = cy + (y - cy) * z / zn
            xi = int(math.floor(xt + 0.5))
            yi = int(math.floor(yt + 0.5))
            if 0 <= xi < w and 0 <= yi < h and zn < zbuf[yi, xi]:
                zbuf[yi, xi] = zn


@njit
def _grow(values, known, key):
    """Fill the unknown pixels of ``values`` (H x W x C), pass by pass, each from its known
    8-neighbour with the largest ``key`` (known before the pass); ``known`` is updated."""
    h, w, ch = values.shape
    n = 0
    for y in range(h):
        for x in range(w):
            if not known[y, x]:
                n += 1
    ty = np.empty(n, np.int64)
    tx = np.empty(n, np.int64)
    n = 0
    for y in range(h):
        for x in range(w):
            if not known[y, x]:
                ty[n], tx[n] = y, x
                n += 1
    src = np.empty(n, np.int64)
    while n > 0:
        for i in range(n):
            y, x = ty[i], tx[i]
            best, found = -1.0, -1
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < h and 0 <= xx < w and known[yy, xx] and key[yy, xx] > best:
                        best, found = key[yy, xx], yy * w + xx
            src[i] = found
        left = 0
        for i in range(n):
            y, x = ty[i], tx[i]
            if src[i] >= 0:
                by, bx = src[i] // w, src[i] % w
                for c in range(ch):
                    values[y, x, c] = values[by, bx, c]
                known[y, x] = True  # the search of this pass is over: no one reads it now
            else:
                ty[left], tx[left] = y, x  # still to fill: kept, in order, at the front
                left += 1
        if left == n:
            break
        n = left


@njit
def _shade(img, depth, zbuf, hole, a, tz, cx, cy, out, coloured):
    h, w = zbuf.shape
    for y in range(h):
        for x in range(w):
            zn = zbuf[y, x]
            z = zn + tz
            xs = cx + ((x - cx) * zn + a) / z
            ys = cy + (y - cy) * zn / z
            if hole[y, x]:
                if not (0.0 <= xs <= w - 1 and 0.0 <= ys <= h - 1):
                    continue
                zs = depth[int(math.floor(ys + 0.5)), int(math.floor(xs + 0.5))]
                if abs(zs - z) > 0.05 * z:
                    continue
            xs = min(max(xs, 0.0), w - 1.0)
            ys = min(max(ys, 0.0), h - 1.0)
            x0 = min(int(xs), w - 2) if w > 1 else 0
            y0 = min(int(ys), h - 2) if h > 1 else 0
            fx, fy = xs - x0, ys - y0
            for c in range(3):
                top = img[y0, x0, c] * (1 - fx) + img[y0, x0 + 1, c] * fx
                bot = img[y0 + 1, x0, c] * (1 - fx) + img[y0 + 1, x0 + 1, c] * fx
                out[y, x, c] = top * (1 - fy) + bot * fy
            coloured[y, x] = True


def frame(img: np.ndarray, depth: np.ndarray, a: float, tz: float) -> np.ndarray:
    """What the camera moved by ``a`` (focal x sideways metres) and ``tz`` (forward metres)
    sees: float32 H x W x 3."""
    h, w = depth.shape
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    zbuf = np.full((h, w), np.inf, np.float32)
    _splat(depth, float(a), float(tz), cx, cy, zbuf)
    hole = ~np.isfinite(zbuf)
    if hole.all():  # everything passed the camera: nothing to see but the nearest colour
        return np.broadcast_to(img.mean(axis=(0, 1)), img.shape).astype(np.float32)
    if hole.any():
        filled = np.where(hole, 0, zbuf).astype(np.float32)
        _grow(filled[:, :, None], ~hole, filled)
        zbuf = filled
    out = np.zeros(img.shape, np.float32)
    coloured = np.zeros((h, w), np.bool_)
    _shade(img, depth, zbuf, hole, float(a), float(tz), cx, cy, out, coloured)
    if not coloured.all():
        _grow(out, coloured, zbuf)
    return out


def offsets(n: int) -> np.ndarray:
    """The ``n`` positions of an exposure along a path of length 1 centred on 0."""
    return np.arange(n) / (n - 1) - 0.5


def frame_count(span_px: float) -> int:
    """Frames for a path moving the nearest things ``span_px`` pixels: about one per pixel."""
    return int(min(MAX_FRAMES, max(MIN_FRAMES, math.ceil(span_px) + 1)))


def exposure(x: np.ndarray, depth: np.ndarray, *, shift_px: float = 0.0, travel: float = 0.0) -> np.ndarray:
    """The mean of the frames along a path centred on the capture: sideways by
    ``shift_px`` pixels at the median depth, forward by ``travel`` times the median depth."""
    img = x.astype(np.float32)
    depth = np.ascontiguousarray(depth, dtype=np.float32)
    zm = float(np.median(depth))
    near = float(np.percentile(depth, 2))
    h, w = depth.shape
    if travel:
        half = travel * zm / 2
        corner = math.hypot(w / 2, h / 2)
        span = corner * (near / max(near - half, 0.05 * near) - near / (near + half))
    else:
        span = shift_px * zm / near
    n = frame_count(span)
    total = np.zeros(img.shape, np.float64)
    for o in offsets(n):
        total += frame(img, depth, o * shift_px * zm, o * travel * zm)
    return total / n
