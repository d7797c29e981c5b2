"""Random-weight AdaIN checkpoints in the published layout, and a per-pair reference.

Written independently of ``robodepth_cli.styles.adain``: the layouts below are spelled out module
by module from the public AdaIN ``net.py`` description, including the VGG
layers past relu4_1 that ``vgg_normalised.pth`` holds, and :func:`reference_stylize` is
the AdaIN stylisation rule taken literally, one content/style pair at a time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn


def _pad():
    return nn.ReflectionPad2d((1, 1, 1, 1))


def _conv(cin, cout):
    return nn.Conv2d(cin, cout, (3, 3))


def full_vgg() -> nn.Sequential:
    """All 53 modules of vgg_normalised (through relu5_4)."""
    pool = lambda: nn.MaxPool2d((2, 2), (2, 2), (0, 0), ceil_mode=True)  # noqa: E731
    return nn.Sequential(
        nn.Conv2d(3, 3, (1, 1)),
        _pad(), _conv(3, 64), nn.ReLU(),  # relu1_1
        _pad(), _conv(64, 64), nn.ReLU(),
        pool(),
        _pad(), _conv(64, 128), nn.ReLU(),  # relu2_1
        _pad(), _conv(128, 128), nn.ReLU(),
        pool(),
        _pad(), _conv(128, 256), nn.ReLU(),  # relu3_1
        _pad(), _conv(256, 256), nn.ReLU(),
        _pad(), _conv(256, 256), nn.ReLU(),
        _pad(), _conv(256, 256), nn.ReLU(),
        pool(),
        _pad(), _conv(256, 512), nn.ReLU(),  # relu4_1 = index 30
        _pad(), _conv(512, 512), nn.ReLU(),
        _pad(), _conv(512, 512), nn.ReLU(),
        _pad(), _conv(512, 512), nn.ReLU(),
        pool(),
        _pad(), _conv(512, 512), nn.ReLU(),  # relu5_1
        _pad(), _conv(512, 512), nn.ReLU(),
        _pad(), _conv(512, 512), nn.ReLU(),
        _pad(), _conv(512, 512), nn.ReLU(),
    )


def adain_decoder() -> nn.Sequential:
    up = lambda: nn.Upsample(scale_factor=2, mode="nearest")  # noqa: E731
    return nn.Sequential(
        _pad(), _conv(512, 256), nn.ReLU(),
        up(),
        _pad(), _conv(256, 256), nn.ReLU(),
        _pad(), _conv(256, 256), nn.ReLU(),
        _pad(), _conv(256, 256), nn.ReLU(),
        _pad(), _conv(256, 128), nn.ReLU(),
        up(),
        _pad(), _conv(128, 128), nn.ReLU(),
        _pad(), _conv(128, 64), nn.ReLU(),
        up(),
        _pad(), _conv(64, 64), nn.ReLU(),
        _pad(), _conv(64, 3),
    )


def _randomise(model: nn.Sequential, gen: torch.Generator) -> None:
    # Normal weights scaled by 1/sqrt(fan_in) keep activations of order one through the
    # stack, so the decoded image is neither all black nor all white and the comparison
    # below means something.
    for m in model:
        if isinstance(m, nn.Conv2d):
            fan_in = m.weight[0].numel()
            m.weight.data = torch.randn(m.weight.shape, generator=gen) * (1.4 / fan_in ** 0.5)
            m.bias.data = torch.randn(m.bias.shape, generator=gen) * 0.05


def random_models(seed: int = 0) -> tuple[nn.Sequential, nn.Sequential]:
    """(full VGG, decoder) with random weights whose decoded images sit mid-range."""
    gen = torch.Generator().manual_seed(seed)
    vgg, dec = full_vgg(), adain_decoder()
    _randomise(vgg, gen)
    _randomise(dec, gen)
    dec[28].weight.data *= 0.2
    dec[28].bias.data[:] = 0.5
    return vgg.eval(), dec.eval()


def save_checkpoints(directory: Path, seed: int = 0):
    """Write ``vgg_normalised.pth`` and ``decoder.pth`` (plain state_dicts) into
    ``directory``; return (vgg path, decoder path, vgg model, decoder model)."""
    vgg, dec = random_models(seed)
    vgg_path, dec_path = Path(directory) / "vgg_normalised.pth", Path(directory) / "decoder.pth"
    torch.save(vgg.state_dict(), vgg_path)
    torch.save(dec.state_dict(), dec_path)
    return vgg_path, dec_path, vgg, dec


def _image_tensor(img: np.ndarray) -> torch.Tensor:
    return torch.tensor(img, dtype=torch.float32).permute(2, 0, 1)[None] / 255.0


def _stats(feat: torch.Tensor):
    n, c = feat.shape[:2]
    flat = feat.view(n, c, -1)
    mean = flat.mean(dim=2).view(n, c, 1, 1)
    var = flat.var(dim=2, correction=1).view(n, c, 1, 1)
    return mean, torch.sqrt(var + 1e-5)


def reference_stylize(vgg: nn.Sequential, dec: nn.Sequential, content: np.ndarray,
                      style: np.ndarray, alpha: float = 1.0) -> np.ndarray:
    """The stylisation rule for one pair, literally: encode both, AdaIN, blend, decode, crop,
    clamp, ``uint8(out * 255 + 0.5)``. ``style`` is used at its given size."""
    enc = vgg[:31]
    with torch.no_grad():
        fc = enc(_image_tensor(content))
        fs = enc(_image_tensor(style))
        mc, sc = _stats(fc)
        ms, ss = _stats(fs)
        t = (fc - mc) / sc * ss + ms
        t = alpha * t + (1 - alpha) * fc
        out = dec(t)
    h, w = content.shape[:2]
    out = out[0, :, :h, :w].clamp(0, 1)
    return (out * 255 + 0.5).to(torch.uint8).permute(1, 2, 0).numpy()


def smooth_image(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A uint8 image with structure at several scales (a plain noise image would make every
    feature map look alike)."""
    out = np.zeros((h, w, 3))
    for cells in (2, 5, 13):
        coarse = rng.random((cells, cells, 3))
        ys = np.linspace(0, cells - 1, h).round().astype(int)
        xs = np.linspace(0, cells - 1, w).round().astype(int)
        out += coarse[ys][:, xs]
    out += 0.5 * rng.random((h, w, 3))
    return (out / out.max() * 255).astype(np.uint8)
