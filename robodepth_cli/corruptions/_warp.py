"""Camera motion during the exposure, shared by motion_3d and zoom_3d (the model and its
rules: docs/depth-aware-corruptions.md).

A pinhole camera at the image centre moves by ``(tx, 0, tz)`` metres, each path set in
pixels at the scene's median depth so that the focal length cancels. One frame is a
forward warp with a z-buffer, its cracks filled from the farthest reached neighbour and
every reached pixel sampled back bilinearly; a disocclusion (the source never saw it) is
not seen in that frame. The exposure is, per pixel, the mean of the ``n`` frames (odd, at
least 9, one per pixel of the longest path) that see it."""

from __future__ import annotations

import math

import numpy as np

from ._jit import njit

MIN_FRAMES = 9
LEAVE = 0.05  # a point nearer than this share of its depth after the move has passed the camera


@njit
def _splat(depth, a, tz, cx, cy, zbuf):
    h, w = depth.shape
    zbuf[:, :] = np.inf
    for y in range(h):
        for x in range(w):
            z = depth[y, x]
            zn = z - tz
            if zn < LEAVE * z:
                continue
            xt = cx + ((x - cx) * z - a) / zn
            yt = cy + (y - cy) * z / zn
            xi = int(math.floor(xt + 0.5))
            yi = int(math.floor(yt + 0.5))
            if 0 <= xi < w and 0 <= yi < h and zn < zbuf[yi, xi]:
                zbuf[yi, xi] = zn


@njit
def _sample(img, w, h, xs, ys, total, o):
    """Add the bilinear sample at ``(xs, ys)``, clamped to the W x H image, of ``img``
    (that image with a row and a column more, flattened) to ``total[o:o + 3]``."""
    xs = 0.0 if xs < 0.0 else (w - 1.0 if xs > w - 1.0 else xs)
    ys = 0.0 if ys < 0.0 else (h - 1.0 if ys > h - 1.0 else ys)
    x0 = min(int(xs), max(w - 2, 0))
    y0 = min(int(ys), max(h - 2, 0))
    fx, fy = xs - x0, ys - y0
    p00 = (y0 * (w + 1) + x0) * 3
    p10 = p00 + 3 * (w + 1)
    w00, w01, w10, w11 = (1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy
    for c in range(3):
        total[o + c] += img[p00 + c] * w00 + img[p00 + 3 + c] * w01 + img[p10 + c] * w10 + img[p10 + 3 + c] * w11


@njit
def _add_reached(img, zbuf, a, tz, cx, cy, total, ty, tx):
    """Add every reached pixel's sample; list the others in ``ty, tx``; return their count."""
    h, w = zbuf.shape
    n = 0
    for y in range(h):
        for x in range(w):
            zn = zbuf[y, x]
            if zn < np.inf:
                inv = 1.0 / (zn + tz)
                _sample(img, w, h, cx + ((x - cx) * zn + a) * inv, cy + (y - cy) * zn * inv, total, (y * w + x) * 3)
            else:
                ty[n], tx[n] = y, x
                n += 1
    return n


@njit
def _fill_cracks(zbuf, n, passes, ty, tx, src):
    """Give the ``n`` unreached pixels ``ty, tx`` of ``zbuf``, pass by pass (at most
    ``passes``), the depth of their farthest 8-neighbour that has one (before the pass);
    return how many were filled, listed first in ``ty, tx``."""
    h, w = zbuf.shape
    done = 0
    for _ in range(passes):
        for i in range(done, n):
            y, x = ty[i], tx[i]
            best, found = -1.0, -1
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < h and 0 <= xx < w and best < zbuf[yy, xx] < np.inf:
                        best, found = zbuf[yy, xx], yy * w + xx
            src[i] = found
        first = done
        for i in range(first, n):
            if src[i] >= 0:
                zbuf[ty[i], tx[i]] = zbuf[src[i] // w, src[i] % w]
                ty[done], ty[i] = ty[i], ty[done]  # filled: moved to the front
                tx[done], tx[i] = tx[i], tx[done]
                done += 1
        if done == first:
            break
    return done


@njit
def _add_cracks(img, depth, zbuf, n, holes, a, tz, cx, cy, total, missed, ty, tx):
    """Add the samples of the ``n`` filled pixels whose trace lands on the source surface
    they were given (within 5 % of its depth); count the other ``holes`` in ``missed``."""
    h, w = zbuf.shape
    for i in range(n, holes):
        missed[ty[i], tx[i]] += 1
    for i in range(n):
        y, x = ty[i], tx[i]
        zn = zbuf[y, x]
        z = zn + tz
        xs = cx + ((x - cx) * zn + a) / z
        ys = cy + (y - cy) * zn / z
        if 0.0 <= xs <= w - 1 and 0.0 <= ys <= h - 1:
            if abs(depth[int(math.floor(ys + 0.5)), int(math.floor(xs + 0.5))] - z) <= 0.05 * z:
                _sample(img, w, h, xs, ys, total, (y * w + x) * 3)
                continue
        missed[y, x] += 1


@njit
def _expose(img, depth, a, tz, n, passes, total, missed):
    h, w = depth.shape
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    zbuf = np.empty((h, w), np.float32)
    ty = np.empty(h * w, np.int64)
    tx = np.empty(h * w, np.int64)
    src = np.empty(h * w, np.int64)
    for i in range(n):
        o = i / (n - 1) - 0.5
        _splat(depth, o * a, o * tz, cx, cy, zbuf)
        holes = _add_reached(img, zbuf, o * a, o * tz, cx, cy, total, ty, tx)
        filled = _fill_cracks(zbuf, holes, passes, ty, tx, src)
        _add_cracks(img, depth, zbuf, filled, holes, o * a, o * tz, cx, cy, total, missed, ty, tx)


def path_lengths(depth: np.ndarray, a: float, tz: float) -> np.ndarray:
    """How far each pixel travels inside the image along the whole path (offsets -1/2 to
    1/2): the straight line between its two end points, clipped to the image (it is
    straight: the motion is sideways or radial). H x W, pixels."""
    h, w = depth.shape
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    z = depth.astype(np.float64)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    ends = []
    for o in (-0.5, 0.5):
        zn = np.maximum(z - o * tz, LEAVE * z)
        ends.append((cx + ((xs - cx) * z - o * a) / zn, cy + (ys - cy) * z / zn))
    (x0, y0), (x1, y1) = ends
    lo, hi = np.zeros_like(z), np.ones_like(z)
    for p0, p1, top in ((x0, x1, w - 1.0), (y0, y1, h - 1.0)):
        d = p1 - p0
        moving = d != 0
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = -p0 / d, (top - p0) / d
        lo = np.where(moving, np.maximum(lo, np.minimum(ta, tb)), lo)
        hi = np.where(moving, np.minimum(hi, np.maximum(ta, tb)), hi)
    return np.maximum(hi - lo, 0.0) * np.hypot(x1 - x0, y1 - y0)


def frame_count(depth: np.ndarray, a: float, tz: float) -> int:
    """One frame per pixel of the longest path inside the image, at least 9, odd."""
    n = max(MIN_FRAMES, math.ceil(float(path_lengths(depth, a, tz).max())) + 1)
    return n + 1 - n % 2


def crack_passes(depth: np.ndarray, tz: float) -> int:
    """Passes that fill the cracks of a surface magnified up to ``m`` times: ``m / 2 + 1``."""
    z = float(depth.min())
    m = z / max(z - abs(tz) / 2, LEAVE * z)
    return math.ceil(m / 2) + 1


def exposure(x: np.ndarray, depth: np.ndarray, *, shift_px: float = 0.0, travel: float = 0.0) -> np.ndarray:
    """The mean of the frames along a path centred on the capture: sideways by
    ``shift_px`` pixels at the median depth, forward by ``travel`` times the median depth."""
    # a row and a column more, so that an image 1 pixel wide or high has two to interpolate
    img = np.pad(x.astype(np.float32), ((0, 1), (0, 1), (0, 0)), mode="edge").ravel()
    depth = np.ascontiguousarray(depth, dtype=np.float32)
    zm = float(np.median(depth))
    a, tz = shift_px * zm, travel * zm
    total = np.zeros(x.size, np.float64)
    missed = np.zeros(depth.shape, np.int64)
    n = frame_count(depth, a, tz)
    _expose(img, depth, float(a), float(tz), n, crack_passes(depth, tz), total, missed)
    return total.reshape(x.shape) / (n - missed)[:, :, None]
