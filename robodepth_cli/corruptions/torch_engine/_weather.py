"""fog and snow (frost, a per-pixel blend, is in ``_pointwise``)."""

from __future__ import annotations

import numpy as np
import torch

from .. import fog as _fog
from .. import snow as _snow
from ..severity import interpolate
from ._tops import drawn, f32, register, shift_blur, truncate, zoomed


@register
def fog(x, level, rngs):
    """The plasma fractal of each image is made by the numpy engine on the CPU (its draws
    and its float32 diamond-square steps), then added and scaled on the device."""
    t, d = interpolate(_fog.LEVELS, level)
    _, _, h, w = x.shape
    n = _fog.next_power_of_two(max(h, w))
    plasma = drawn(rngs, lambda rng: _fog.plasma_fractal(n, d, rng, (h, w)), x.device)
    m = x.amax(dim=(1, 2, 3)).tolist()
    out = []
    for img, plasma_i, top in zip(x, plasma, m):
        mm = top / 255.0
        g = plasma_i[None] * f32(255.0 * t) + img.to(torch.float32)
        out.append(truncate(g, f32(mm / (mm + t))))
    return torch.stack(out)


def _layer(shape, mu, sigma, z, tau, radius, s, rng, device) -> torch.Tensor:
    """The numpy engine's ``snow_layer``: the noise and the angle drawn on the CPU in its
    order, the zoom, threshold and motion blur on the device in float32."""
    noise = _snow.snow_noise(shape, mu, sigma, z, rng)
    layer = zoomed(torch.from_numpy(noise).to(device), z, crop=False)
    layer = torch.where(layer < tau, 0.0, layer).clamp_(0.0, 1.0)
    return shift_blur(layer, radius, s, rng.uniform(-135, -45))


@register
def snow(x, level, rngs):
    """Whitened image plus the snow layer and its 180-degree rotation, in float32."""
    mu, sigma, z, tau, radius, s, beta = interpolate(_snow.LEVELS, level, _snow.RULES)
    _, _, h, w = x.shape
    scale = f32(1.0 / 255.0)
    b, nb = f32(beta), f32(1.0 - np.float32(beta))
    out = []
    for img, rng in zip(x, rngs):
        layer = _layer((h, w), mu, sigma, z, f32(tau), radius, s, rng, x.device)[:h, :w]
        f = img.to(torch.float32) * scale
        lift = (f[0] * f32(0.299) + f[1] * f32(0.587) + f[2] * f32(0.114)) * f32(1.5) + f32(0.5)
        flakes = (torch.round(layer * f32(255)) + torch.round(layer.flip(0, 1) * f32(255))) * scale
        v = f * b + torch.maximum(f, lift) * nb + flakes
        out.append((v.clamp(0.0, 1.0) * f32(255)).to(torch.uint8))
    return torch.stack(out)
