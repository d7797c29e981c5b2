"""Corruptions that map each pixel on its own: brightness, contrast, color_quant and the
noises (dark, gaussian_noise, shot_noise, iso_noise, impulse_noise), with frost's blend.

The noises draw each image's uniforms from its own generator on the CPU, in the numpy
engine's order (C order of the H x W x 3 image), and sample the numpy engine's exact
output law (the same table) on the device: the same bytes on any device."""

from __future__ import annotations

import numpy as np
import torch

from .. import color_quant as _cq
from .. import contrast as _contrast
from .. import dark as _dark
from .. import frost as _frost
from .. import gaussian_noise as _gauss
from .. import impulse_noise as _impulse
from .. import iso_noise as _iso
from .. import shot_noise as _shot
from ..brightness import LEVELS as _BRIGHTNESS
from ..severity import BLEND, Blend, interpolate
from ._tops import drawn, hwc_order, register, sample_law, tensor, truncate


@register
def brightness(x, level, rngs):
    """scikit-image's HSV round trip with ``V + c`` clipped, in float64, elementwise as the
    numpy engine's per-pixel kernel computes it."""
    c = interpolate(_BRIGHTNESS, level)
    f = x.to(torch.float64) / 255.0
    r, g, b = f[:, 0], f[:, 1], f[:, 2]
    v = torch.maximum(torch.maximum(r, g), b)
    delta = v - torch.minimum(torch.minimum(r, g), b)
    flat = delta == 0.0
    s = torch.where(flat, 0.0, delta / v)
    hh = torch.where(b == v, 4.0 + (r - g) / delta,
                     torch.where(g == v, 2.0 + (b - r) / delta, (g - b) / delta))
    hue = torch.where(flat, 0.0, torch.remainder(hh / 6.0, 1.0))
    v2 = (v + c).clamp(0.0, 1.0)
    hi = torch.floor(hue * 6)
    fr = hue * 6 - hi
    p = v2 * (1 - s)
    q = v2 * (1 - fr * s)
    t = v2 * (1 - (1 - fr) * s)
    k = torch.remainder(hi.to(torch.int64), 6)
    choices = ((v2, t, p), (q, v2, p), (p, v2, t), (p, q, v2), (t, p, v2), (v2, p, q))
    out = []
    for ch in range(3):
        o = choices[5][ch]
        for sector in range(4, -1, -1):
            o = torch.where(k == sector, choices[sector][ch], o)
        out.append((o.clamp(0.0, 1.0) * 255).to(torch.uint8))
    return torch.stack(out, dim=1)


@register
def contrast(x, level, rngs):
    """``clip01((f - m) * c + m)`` truncated, ``m`` each image's per-channel mean, through
    the same 256-value float64 table per channel as the numpy engine."""
    c = interpolate(_contrast.LEVELS, level)
    n, _, h, w = x.shape
    # An exact integer sum; the mean as OpenCV's cv2.mean forms it (sum times 1/count).
    sums = x.to(torch.int64).sum(dim=(2, 3)).to(torch.float64)
    m = sums * (1.0 / (h * w)) / 255.0  # N x 3
    values = torch.arange(256, dtype=torch.float64, device=x.device) / 255.0
    table = truncate((values[None, None, :] - m[:, :, None]) * c + m[:, :, None])  # N x 3 x 256
    return torch.gather(table, 2, x.reshape(n, 3, -1).to(torch.int64)).reshape(x.shape)


def _lookup(x: torch.Tensor, table: np.ndarray) -> torch.Tensor:
    return tensor(table, x.device)[x.to(torch.int64)]


@register
def color_quant(x, level, rngs):
    """The top ``bits`` bits of every value; between levels the numpy engine's blend table."""
    bits = interpolate(_cq.LEVELS, level, (BLEND,))
    if not isinstance(bits, Blend):
        return x & ((0xFF << (8 - bits)) & 0xFF)
    values = np.arange(256, dtype=np.uint8)
    return _lookup(x, _cq.color_quant(values[:, None, None], level, None)[:, 0, 0])


def _uniforms(x, rngs):
    """One float64 uniform per element, each image's drawn in C order of H x W x 3."""
    _, _, h, w = x.shape
    return hwc_order(drawn(rngs, lambda rng: rng.random(h * w * 3).reshape(h, w, 3), x.device))


def _sampled(x, rngs, laws):
    u = _uniforms(x, rngs)
    if not isinstance(laws, list):
        return sample_law(x, laws, u)
    return torch.stack([sample_law(x[i], law, u[i]) for i, law in enumerate(laws)])


@register
def gaussian_noise(x, level, rngs):
    return _sampled(x, rngs, _gauss.output_law(level))


@register
def shot_noise(x, level, rngs):
    return _sampled(x, rngs, _shot.output_law(level))


@register
def iso_noise(x, level, rngs):
    return _sampled(x, rngs, _iso.output_law(level))


@register
def dark(x, level, rngs):
    """Each image's law depends on its own extremes."""
    lo = x.amin(dim=(1, 2, 3)).tolist()
    hi = x.amax(dim=(1, 2, 3)).tolist()
    return _sampled(x, rngs, [_dark.output_law(level, a, b) for a, b in zip(lo, hi)])


@register
def impulse_noise(x, level, rngs):
    """One float32 uniform per element: below ``amount / 2`` gives 0, below ``amount`` 255."""
    amount = interpolate(_impulse.LEVELS, level)
    _, _, h, w = x.shape
    u = hwc_order(drawn(rngs, lambda rng: rng.random((h, w, 3), dtype=np.float32), x.device))
    # numpy compares a float32 array with a Python float in float32.
    half, full = float(np.float32(amount * 0.5)), float(np.float32(amount))
    replaced = torch.where(u < half, 0, 255).to(torch.uint8)
    return torch.where(u < full, replaced, x)


@register
def frost(x, level, rngs):
    """Texture and crop drawn per image as the numpy engine draws them (texture, row,
    column), the crop moved to the device, then the exact blend table."""
    _, _, h, w = x.shape

    def crop(rng):
        tex = _frost.scaled_texture(int(rng.integers(len(_frost.TEXTURES))), (h, w))
        top = int(rng.integers(0, tex.shape[0] - h))
        left = int(rng.integers(0, tex.shape[1] - w))
        return tex[top:top + h, left:left + w]

    crops = hwc_order(drawn(rngs, crop, x.device)).to(torch.int64)
    table = tensor(_frost.blend_table(level), x.device).reshape(-1)
    return table[x.to(torch.int64) * 256 + crops]
