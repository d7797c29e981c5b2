"""Models made in the tests: monodepth2-format checkpoints with random weights."""

from __future__ import annotations

from pathlib import Path

import torch


NET_H, NET_W = 64, 128  # the test models' input size; the build is 64 x 96, so it is resized



RESNETS = {18: ((2, 2, 2, 2), False), 50: ((3, 4, 6, 3), True)}



def random_monodepth2(folder: Path, layers: int, seed: int = 0, height=NET_H, width=NET_W):
    """encoder.pth and depth.pth as monodepth2 saves them (its ResnetEncoder's and
    DepthDecoder's state dicts, torchvision's names; height/width/use_stereo in the
    encoder's), with random weights scaled so that activations stay in a useful range."""
    g = torch.Generator().manual_seed(seed)
    enc = {}

    def conv(name, cout, cin, k, gain=1.0):
        enc[f"{name}.weight"] = torch.randn(cout, cin, k, k, generator=g) * gain * (2 / (cin * k * k)) ** 0.5

    def bn(name, c, scale=1.0):
        enc[f"{name}.weight"] = scale * (0.5 + torch.rand(c, generator=g))
        enc[f"{name}.bias"] = 0.1 * torch.randn(c, generator=g)
        enc[f"{name}.running_mean"] = 0.1 * torch.randn(c, generator=g)
        enc[f"{name}.running_var"] = 0.5 + torch.rand(c, generator=g)
        enc[f"{name}.num_batches_tracked"] = torch.tensor(7)

    blocks, bottleneck = RESNETS[layers]
    conv("encoder.conv1", 64, 3, 7)
    bn("encoder.bn1", 64)
    cin = 64
    for s, (n, w) in enumerate(zip(blocks, (64, 128, 256, 512)), start=1):
        out = w * 4 if bottleneck else w
        for b in range(n):
            p = f"encoder.layer{s}.{b}"
            if bottleneck:
                conv(f"{p}.conv1", w, cin, 1)
                bn(f"{p}.bn1", w)
                conv(f"{p}.conv2", w, w, 3)
                bn(f"{p}.bn2", w)
                conv(f"{p}.conv3", out, w, 1)
                bn(f"{p}.bn3", out, 0.3)
            else:
                conv(f"{p}.conv1", w, cin, 3)
                bn(f"{p}.bn1", w)
                conv(f"{p}.conv2", w, w, 3)
                bn(f"{p}.bn2", w, 0.3)
            if b == 0 and (s > 1 or cin != out):
                conv(f"{p}.downsample.0", out, cin, 1)
                bn(f"{p}.downsample.1", out)
            cin = out
    enc["encoder.fc.weight"] = torch.randn(1000, cin, generator=g) * 0.01
    enc["encoder.fc.bias"] = torch.zeros(1000)
    enc.update(height=height, width=width, use_stereo=False)

    ch_enc = [64] + [w * (4 if bottleneck else 1) for w in (64, 128, 256, 512)]
    ch_dec = [16, 32, 64, 128, 256]
    dec = {}
    k = 0
    for i in range(4, -1, -1):
        for j in (0, 1):
            cin = (ch_enc[-1] if i == 4 else ch_dec[i + 1]) if j == 0 else \
                ch_dec[i] + (ch_enc[i - 1] if i > 0 else 0)
            dec[f"decoder.{k}.conv.conv.weight"] = torch.randn(ch_dec[i], cin, 3, 3, generator=g) * (1 / (cin * 9)) ** 0.5
            dec[f"decoder.{k}.conv.conv.bias"] = 0.05 * torch.randn(ch_dec[i], generator=g)
            k += 1
    for s in range(4):
        dec[f"decoder.{10 + s}.conv.weight"] = torch.randn(1, ch_dec[s], 3, 3, generator=g) * (3 / (ch_dec[s] * 9)) ** 0.5
        dec[f"decoder.{10 + s}.conv.bias"] = torch.zeros(1)
    folder.mkdir(parents=True, exist_ok=True)
    torch.save(enc, folder / "encoder.pth")
    torch.save(dec, folder / "depth.pth")
    return enc, dec
