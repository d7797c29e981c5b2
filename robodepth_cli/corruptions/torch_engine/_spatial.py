"""Corruptions that move or mix pixels: pixelate, defocus_blur, motion_blur, zoom_blur and
elastic_transform."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import torch

from .. import defocus_blur as _defocus
from .. import elastic_transform as _elastic
from .. import motion_blur as _motion
from .. import pixelate as _pixelate
from .. import zoom_blur as _zoom
from ..severity import BLEND, Blend, interpolate
from ._tops import drawn, f32, fma, register, shift_blur, tensor, truncate, zoomed

# Pillow's fixed-point precision of 8-bit resampling weights.
_PRECISION_BITS = 32 - 8 - 2


@lru_cache(maxsize=16)
def box_taps(n_in: int, n_out: int) -> tuple[np.ndarray, np.ndarray]:
    """Pillow's BOX reduction of one axis from ``n_in`` to ``n_out`` samples: per output the
    source indices and integer weights (``round(w * 2**22)`` of the normalised box weights,
    computed in double as Pillow computes them). Unused taps have weight 0."""
    scale = n_in / n_out
    support = 0.5 * scale
    ksize = math.ceil(support) * 2 + 1
    idx = np.zeros((n_out, ksize), np.int64)
    wts = np.zeros((n_out, ksize), np.int64)
    for xx in range(n_out):
        center = (xx + 0.5) * scale
        xmin = max(int(center - support + 0.5), 0)
        xmax = min(int(center + support + 0.5), n_in) - xmin
        k = [1.0 if -0.5 < (x + xmin - center + 0.5) / scale <= 0.5 else 0.0 for x in range(xmax)]
        total = sum(k)
        for x, v in enumerate(k):
            v = v / total if total != 0.0 else v
            idx[xx, x] = x + xmin
            wts[xx, x] = int(0.5 + v * (1 << _PRECISION_BITS)) if v >= 0 else int(-0.5 + v * (1 << _PRECISION_BITS))
    return idx, wts


def _box_axis(img: torch.Tensor, n_out: int, dim: int) -> torch.Tensor:
    """One Pillow BOX pass along ``dim``: integer sum plus half, shifted and clipped to uint8."""
    idx, wts = box_taps(img.shape[dim], n_out)
    dev = img.device
    src = img.to(torch.int64)
    acc = torch.full((), 1 << (_PRECISION_BITS - 1), dtype=torch.int64, device=dev)
    shape = [1] * img.ndim
    shape[dim] = n_out
    for t in range(idx.shape[1]):
        taps = src.index_select(dim, torch.from_numpy(idx[:, t]).to(dev))
        acc = acc + taps * torch.from_numpy(wts[:, t]).to(dev).reshape(shape)
    return (acc >> _PRECISION_BITS).clamp_(0, 255)


@lru_cache(maxsize=16)
def _nearest_index(n_in: int, n_out: int) -> np.ndarray:
    """Which source sample Pillow's NEAREST resize takes for each output, asked of Pillow
    itself (a row of indices resized), so its float stepping is reproduced exactly."""
    from PIL import Image

    row = Image.fromarray(np.arange(n_in, dtype=np.int32)[None, :])  # mode "I"
    return np.asarray(row.resize((n_out, 1), Image.NEAREST), dtype=np.int64)[0]


@register
def pixelate(x, level, rngs):
    """Pillow's BOX reduction to ``(int(W c), int(H c))`` (horizontal pass, then vertical,
    each in Pillow's fixed point) and NEAREST enlargement back, as integer arithmetic."""
    c = interpolate(_pixelate.LEVELS, level)
    h, w = x.shape[-2:]
    small = _box_axis(_box_axis(x, int(w * c), 3), int(h * c), 2)
    dev = x.device
    rows = torch.from_numpy(_nearest_index(small.shape[2], h)).to(dev)
    cols = torch.from_numpy(_nearest_index(small.shape[3], w)).to(dev)
    return small.index_select(2, rows).index_select(3, cols).to(torch.uint8)


@register
def defocus_blur(x, level, rngs):
    """The numpy engine's disk kernel, correlated in float32 with a reflect-101 border. The
    numpy engine filters large kernels (levels 3-5) through a float32 FFT, whose rounding
    differs: there a few pixels land one level apart."""
    radius, alias = interpolate(_defocus.LEVELS, level)
    kernel = _defocus.disk_kernel(radius, alias)
    k = tensor(kernel, x.device)
    r = k.shape[0] // 2
    n, ch, h, w = x.shape
    src = x.to(torch.float32).reshape(n * ch, 1, h, w)
    padded = torch.nn.functional.pad(src, (r, r, r, r), mode="reflect")
    # Full float32 on a GPU too: cuDNN would otherwise round the operands to TF32.
    with torch.backends.cudnn.flags(enabled=torch.backends.cudnn.enabled, benchmark=False,
                                    deterministic=True, allow_tf32=False):
        out = torch.nn.functional.conv2d(padded, k[None, None])
    return truncate(out.reshape(n, ch, h, w), 1.0)


@register
def motion_blur(x, level, rngs):
    """Each image's angle drawn from its generator; the shift-and-add in float32, tap by tap."""
    radius, sigma = interpolate(_motion.LEVELS, level, _motion.RULES)
    out = [truncate(shift_blur(img, radius, sigma, rng.uniform(-45, 45)), 1.0) for img, rng in zip(x, rngs)]
    return torch.stack(out)


def _zoom_average(f: torch.Tensor, level: int) -> torch.Tensor:
    h, w = f.shape[-2:]
    factors = _zoom.level_factors(level)
    acc = f.clone()
    for z in factors:
        layer = zoomed(f, z, crop=True)[..., :h, :w]
        acc[..., :layer.shape[-2], :layer.shape[-1]] += layer
    return acc / f32(len(factors) + 1)


@register
def zoom_blur(x, level, rngs):
    """The image and its clipped zooms averaged in float32, layer by layer in the numpy
    engine's order; between levels its blend of the two averages."""
    f = x.to(torch.float32) * f32(1 / 255)
    entry = interpolate(_zoom.LEVELS, level, (BLEND,))
    if not isinstance(entry, Blend):
        return truncate(_zoom_average(f, level))
    i, t = int(level), f32(entry.t)
    mixed = _zoom_average(f, i) * f32(1 - t)
    return truncate(mixed + _zoom_average(f, i + 1) * t)


def _smooth(u: torch.Tensor, sigma: float, dim: int) -> torch.Tensor:
    """scipy's ``gaussian_filter1d`` (truncate 3, mode reflect) along ``dim`` of float32 ``u``,
    summed as OpenCV's symmetric-kernel filter sums (centre tap, then each pair of mirrored
    taps added and multiply-added), which matches it on most elements (within 2e-7)."""
    from .._ops import gaussian_kernel_1d

    k = gaussian_kernel_1d(sigma, 3.0).astype(np.float32)
    r = k.size // 2
    n = u.shape[dim]
    src = u.index_select(dim, _fold(torch.arange(-r, n + r, device=u.device), n))
    out = src.narrow(dim, r, n) * float(k[r])
    for i in range(1, r + 1):
        out = fma(src.narrow(dim, r - i, n) + src.narrow(dim, r + i, n), float(k[r + i]), out)
    return out


@register
def elastic_transform(x, level, rngs):
    """Each image's uniforms drawn as the numpy engine draws them; smoothed in float32; then
    a bilinear resample as OpenCV's ``remap`` computes it, with a half-sample symmetric
    border."""
    n, ch, h, w = x.shape
    dev = x.device
    m_alpha = 0.005 * h * 250 * interpolate(_elastic.LEVELS, level)
    u = drawn(rngs, lambda rng: rng.random((2, h, w), dtype=np.float32), dev)
    u = _smooth(_smooth(u, 0.01 * h, 2), 0.01 * w, 3)
    u = u * f32(2 * m_alpha)
    gx = u[:, 0] + (torch.arange(w, device=dev, dtype=torch.float64) - m_alpha).to(torch.float32)
    gy = u[:, 1] + (torch.arange(h, device=dev, dtype=torch.float64)[:, None] - m_alpha).to(torch.float32)
    x0, y0 = torch.floor(gx), torch.floor(gy)
    ax, ay = (gx - x0)[:, None], (gy - y0)[:, None]
    x0, y0 = x0.to(torch.int64), y0.to(torch.int64)
    src = x.to(torch.float32).reshape(n, ch, h * w)

    def tap(dy, dx):
        flat = (_fold(y0 + dy, h) * w + _fold(x0 + dx, w)).reshape(n, 1, h * w).expand(n, ch, h * w)
        return torch.gather(src, 2, flat).reshape(n, ch, h, w)

    # OpenCV's remap: two horizontal lerps, then a vertical one, each a multiply-add.
    top, bottom = _lerp(tap(0, 0), tap(0, 1), ax), _lerp(tap(1, 0), tap(1, 1), ax)
    out = _lerp(top, bottom, ay)
    return truncate(out, 1.0)


def _fold(i: torch.Tensor, n: int) -> torch.Tensor:
    """Indices folded into ``0..n-1`` by half-sample symmetric reflection
    (``d c b a | a b c d | d c b a``), repeatedly for far ones."""
    period = 2 * n
    i = torch.remainder(i, period)
    return torch.where(i >= n, period - 1 - i, i)


def _lerp(a: torch.Tensor, b: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    return fma(b - a, t, a)
