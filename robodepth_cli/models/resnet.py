"""The ResNet encoder of monodepth2-format checkpoints, written here because torchvision is
not a dependency (its registry builds need a CUDA torch).

Parameter names follow torchvision's ResNet, which monodepth2's ``ResnetEncoder`` wraps as
``encoder``: ``conv1``, ``bn1``, ``layer1``..``layer4`` of blocks numbered from 0, each block
``conv1``/``bn1``, ``conv2``/``bn2`` (and ``conv3``/``bn3`` in a bottleneck), and a
``downsample`` of ``0`` (1x1 convolution) and ``1`` (batch norm) where the block changes
the size or the width. A bottleneck strides in its 3x3 convolution (ResNet v1.5, as
torchvision). The classifier (``fc``) is never used by a depth encoder.
"""

from __future__ import annotations

import torch
from torch import nn

# blocks per stage, and whether the block is a bottleneck (width x 4 out)
DEPTHS = {18: ((2, 2, 2, 2), False), 34: ((3, 4, 6, 3), False), 50: ((3, 4, 6, 3), True),
          101: ((3, 4, 23, 3), True), 152: ((3, 8, 36, 3), True)}
WIDTHS = (64, 128, 256, 512)


def _conv(cin: int, cout: int, k: int, stride: int = 1) -> nn.Conv2d:
    return nn.Conv2d(cin, cout, k, stride=stride, padding=k // 2, bias=False)


class _Basic(nn.Module):
    expansion = 1

    def __init__(self, cin: int, width: int, stride: int):
        super().__init__()
        self.conv1 = _conv(cin, width, 3, stride)
        self.bn1 = nn.BatchNorm2d(width)
        self.conv2 = _conv(width, width, 3)
        self.bn2 = nn.BatchNorm2d(width)
        self.relu = nn.ReLU(inplace=True)
        self.downsample = _shortcut(cin, width, stride)

    def forward(self, x):
        skip = x if self.downsample is None else self.downsample(x)
        y = self.relu(self.bn1(self.conv1(x)))
        y = self.bn2(self.conv2(y))
        return self.relu(y + skip)


class _Bottleneck(nn.Module):
    expansion = 4

    def __init__(self, cin: int, width: int, stride: int):
        super().__init__()
        self.conv1 = _conv(cin, width, 1)
        self.bn1 = nn.BatchNorm2d(width)
        self.conv2 = _conv(width, width, 3, stride)
        self.bn2 = nn.BatchNorm2d(width)
        self.conv3 = _conv(width, width * 4, 1)
        self.bn3 = nn.BatchNorm2d(width * 4)
        self.relu = nn.ReLU(inplace=True)
        self.downsample = _shortcut(cin, width * 4, stride)

    def forward(self, x):
        skip = x if self.downsample is None else self.downsample(x)
        y = self.relu(self.bn1(self.conv1(x)))
        y = self.relu(self.bn2(self.conv2(y)))
        y = self.bn3(self.conv3(y))
        return self.relu(y + skip)


def _shortcut(cin: int, cout: int, stride: int):
    if stride == 1 and cin == cout:
        return None
    return nn.Sequential(_conv(cin, cout, 1, stride), nn.BatchNorm2d(cout))


class ResNet(nn.Module):
    """The convolutional trunk of a ResNet (no classifier). ``forward`` returns the five
    feature maps monodepth2's encoder hands to its decoder: after the stem's ReLU (1/2
    size), then after each of the four stages (1/4, 1/8, 1/16, 1/32)."""

    def __init__(self, num_layers: int, in_channels: int = 3):
        super().__init__()
        blocks, bottleneck = DEPTHS[num_layers]
        block = _Bottleneck if bottleneck else _Basic
        self.conv1 = nn.Conv2d(in_channels, 64, 7, stride=2, padding=3, bias=False)
        self.bn1 = nn.BatchNorm2d(64)
        self.relu = nn.ReLU(inplace=True)
        self.maxpool = nn.MaxPool2d(3, stride=2, padding=1)
        cin = 64
        for stage, (count, width) in enumerate(zip(blocks, WIDTHS), start=1):
            layers = []
            for b in range(count):
                layers.append(block(cin, width, 2 if b == 0 and stage > 1 else 1))
                cin = width * block.expansion
            setattr(self, f"layer{stage}", nn.Sequential(*layers))
        self.channels = (64,) + tuple(w * block.expansion for w in WIDTHS)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        f0 = self.relu(self.bn1(self.conv1(x)))
        f1 = self.layer1(self.maxpool(f0))
        f2 = self.layer2(f1)
        f3 = self.layer3(f2)
        return [f0, f1, f2, f3, self.layer4(f3)]


def depth_of(keys, prefix: str = "encoder.") -> int | None:
    """The ResNet depth (18, 34, 50, 101, 152) whose parameter names ``keys`` hold, from
    the number of blocks per stage and the kind of block; None when they match none."""
    counts = []
    for stage in range(1, 5):
        n = 0
        while f"{prefix}layer{stage}.{n}.conv1.weight" in keys:
            n += 1
        counts.append(n)
    bottleneck = f"{prefix}layer1.0.conv3.weight" in keys
    for depth, (blocks, is_bottleneck) in DEPTHS.items():
        if tuple(counts) == blocks and bottleneck == is_bottleneck:
            return depth
    return None
