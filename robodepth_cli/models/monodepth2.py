"""monodepth2-format checkpoints (MonoDepth2, Depth Hints, and the many models that share
the format): a folder with ``encoder.pth`` (monodepth2's ``ResnetEncoder``, a ResNet under
``encoder.`` (:mod:`.resnet`), plus ``height`` and ``width``, the network's input size)
and ``depth.pth`` (its ``DepthDecoder``, of which only scale 0 is used).

A prediction is what monodepth2's ``evaluate_depth.py --save_pred_disps`` saves, step by
step as docs/predict.md gives them (Lanczos resize, normalisation, ``disp_to_depth``, and
with ``--post-process`` its float64 mirror blend); the maps are at the network's size."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RobodepthError, os_reason
from ..files import sha256_file
from .base import Model, torch_device

MIN_DEPTH, MAX_DEPTH = 0.1, 100.0  # evaluate_depth.py's defaults (--min_depth, --max_depth)
MEAN, STD = 0.45, 0.225  # ResnetEncoder's input normalisation
DECODER_WIDTHS = (16, 32, 64, 128, 256)  # channels of the decoder's scales 0..4
N_BLOCKS = 10  # decoder.0 .. decoder.9: two blocks per scale, coarsest first


def load(arg: str, spec: str, *, device: str = "auto", post_process: bool = False) -> Model:
    """The monodepth2 model in folder ``arg``; :class:`RobodepthError` naming the file for a
    missing folder or file, an unreadable checkpoint or one of another architecture."""
    import torch

    folder = Path(arg).expanduser()
    if not folder.is_dir():
        raise RobodepthError(f"{spec}: {folder} is not a folder (expected a monodepth2 model "
                             "folder with encoder.pth and depth.pth)")
    enc_path, dec_path = folder / "encoder.pth", folder / "depth.pth"
    for path in (enc_path, dec_path):
        if not path.is_file():
            raise RobodepthError(f"{folder}: no {path.name} (a monodepth2 model folder holds "
                                 "encoder.pth and depth.pth)")
    enc = _read(enc_path)
    dec = _read(dec_path)
    height, width = _input_size(enc, enc_path)
    dev = torch_device(device)
    net = DepthNet.from_state_dicts(enc, dec, enc_path, dec_path).to(dev).eval()

    def run(images: np.ndarray):
        x = prepare(images, height, width).to(dev)
        with torch.no_grad():
            if post_process:
                # The mirror images go in the same batch, as evaluate_depth.py runs them.
                disp = net(torch.cat((x, torch.flip(x, [3])), 0))
            else:
                disp = net(x)
        disp = disp.cpu()[:, 0].numpy()
        if post_process:
            n = disp.shape[0] // 2
            return post_process_disparity(disp[:n], disp[n:, :, ::-1])
        return disp

    identity = {"encoder.pth": sha256_file(enc_path), "depth.pth": sha256_file(dec_path),
                "resnet": net.num_layers}
    return Model(spec=spec, adapter="monodepth2", kind="disp", metric=False, align="median",
                 align_space="depth", input_size=[height, width], identity=identity, run=run,
                 device=dev, options={"post_process": post_process},
                 modules=(net.encoder, net.decoder))


def _read(path: Path) -> dict:
    import torch

    try:
        # weights_only: tensors and plain values only, so a crafted file cannot run code.
        obj = torch.load(path, map_location="cpu", weights_only=True)
    except OSError as exc:
        raise RobodepthError(f"{path}: cannot read ({os_reason(exc)})") from None
    except Exception:  # torch fails on a foreign file in many ways (UnpicklingError, KeyError, ...)
        # Never torch's own text: it advises weights_only=False, which runs whatever the file holds.
        raise RobodepthError(f"{path}: not a PyTorch checkpoint of tensors ({_what_file(path)}); "
                             "monodepth2 folders hold state_dicts saved with torch.save") from None
    if not isinstance(obj, dict):
        raise RobodepthError(f"{path}: holds a {type(obj).__name__}; expected a state_dict (a dict "
                             "of tensors)")
    return obj


def _what_file(path: Path) -> str:
    """What the file is, as far as its first bytes tell: torch.save writes a zip archive
    (older versions, a pickle)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
    except OSError as exc:
        return os_reason(exc)
    if head.startswith(b"PK\x03\x04"):
        return "a zip archive holding objects other than tensors and plain values, or damaged"
    if head[:1] == b"\x80":
        return "a pickle holding objects other than tensors and plain values, or damaged"
    return "neither a zip archive nor a pickle" if head else "an empty file"


def _input_size(enc: dict, path: Path) -> tuple[int, int]:
    try:
        height, width = int(enc["height"]), int(enc["width"])
    except (KeyError, TypeError, ValueError):
        raise RobodepthError(f"{path}: no 'height' and 'width' entries (monodepth2 saves the "
                             "network's input size in encoder.pth)") from None
    if height <= 0 or width <= 0 or height % 32 or width % 32:
        raise RobodepthError(f"{path}: input size {height} x {width}; monodepth2's network needs "
                             "multiples of 32")
    return height, width


def prepare(images: np.ndarray, height: int, width: int):
    """An ``N x H x W x 3`` uint8 batch as the ``N x 3 x height x width`` float tensor in
    [0, 1] that monodepth2's data loader gives its encoder (Lanczos resize, ``/ 255``)."""
    import torch
    from PIL import Image

    out = np.empty((len(images), height, width, 3), np.uint8)
    for i, img in enumerate(images):
        im = Image.fromarray(img)
        if im.size != (width, height):
            im = im.resize((width, height), Image.LANCZOS)
        out[i] = np.asarray(im)
    x = torch.from_numpy(out).permute(0, 3, 1, 2)
    return x.float().div(255)


def post_process_disparity(disp: np.ndarray, flipped: np.ndarray) -> np.ndarray:
    """monodepth2's ``batch_post_process_disparity`` (see the module docstring): ``disp``
    and ``flipped`` (the mirror images' disparities, already flipped back) are N x h x w."""
    _, h, w = disp.shape
    mean = 0.5 * (disp + flipped)
    cols = np.broadcast_to(np.linspace(0, 1, w)[None, :], (h, w))
    left = (1.0 - np.clip(20 * (cols - 0.05), 0, 1))[None]
    right = left[:, :, ::-1]
    return right * disp + left * flipped + (1.0 - left - right) * mean


def _module_classes():
    """The network's modules, defined on first use so that importing this file does not
    import torch."""
    import torch
    from torch import nn
    from torch.nn import functional as F

    from .resnet import ResNet

    class Conv3x3(nn.Module):
        def __init__(self, cin: int, cout: int):
            super().__init__()
            self.pad = nn.ReflectionPad2d(1)
            self.conv = nn.Conv2d(cin, cout, 3)

        def forward(self, x):
            return self.conv(self.pad(x))

    class ConvBlock(nn.Module):
        def __init__(self, cin: int, cout: int):
            super().__init__()
            self.conv = Conv3x3(cin, cout)
            self.nonlin = nn.ELU(inplace=True)

        def forward(self, x):
            return self.nonlin(self.conv(x))

    class Decoder(nn.Module):
        """Upsampling decoder with skips: for scale i = 4..0, a block to scale i's width,
        nearest-neighbour x2 upsampling, the encoder's feature i-1 appended (i > 0), a second
        block; then scale 0's output convolution and a sigmoid. Output convolutions of the
        coarser scales are kept for the checkpoint's sake but not run."""

        def __init__(self, enc_channels, scales):
            super().__init__()
            blocks = []
            for i in range(4, -1, -1):
                cin = enc_channels[-1] if i == 4 else DECODER_WIDTHS[i + 1]
                blocks.append(ConvBlock(cin, DECODER_WIDTHS[i]))
                skip = enc_channels[i - 1] if i > 0 else 0
                blocks.append(ConvBlock(DECODER_WIDTHS[i] + skip, DECODER_WIDTHS[i]))
            blocks += [Conv3x3(DECODER_WIDTHS[s], 1) for s in range(scales)]
            self.decoder = nn.ModuleList(blocks)

        def forward(self, features):
            x = features[-1]
            for step, i in enumerate(range(4, -1, -1)):
                x = F.interpolate(self.decoder[2 * step](x), scale_factor=2, mode="nearest")
                if i > 0:
                    x = torch.cat((x, features[i - 1]), 1)
                x = self.decoder[2 * step + 1](x)
            return torch.sigmoid(self.decoder[N_BLOCKS](x))

    class Encoder(nn.Module):
        def __init__(self, num_layers):
            super().__init__()
            self.encoder = ResNet(num_layers)

        def forward(self, x):
            return self.encoder((x - MEAN) / STD)

    return Encoder, Decoder


class DepthNet:
    """Encoder + decoder -> monodepth2's scaled disparity, ``N x 1 x height x width``."""

    def __init__(self, encoder, decoder, num_layers: int):
        self.encoder, self.decoder, self.num_layers = encoder, decoder, num_layers

    @classmethod
    def from_state_dicts(cls, enc: dict, dec: dict, enc_path: Path, dec_path: Path) -> "DepthNet":
        from .resnet import depth_of

        Encoder, Decoder = _module_classes()
        enc_tensors = {k: v for k, v in enc.items()
                       if hasattr(v, "shape") and not k.startswith("encoder.fc.")}
        num_layers = depth_of(enc_tensors)
        if num_layers is None:
            raise RobodepthError(f"{enc_path}: not a monodepth2 ResNet encoder (its parameters match "
                                 "no ResNet-18/34/50/101/152 under 'encoder.')")
        conv1 = enc_tensors.get("encoder.conv1.weight")
        if conv1 is not None and conv1.ndim == 4 and conv1.shape[1] != 3:
            raise RobodepthError(f"{enc_path}: its first convolution takes {conv1.shape[1]} channels; a "
                                 "depth encoder takes one RGB image (is this a pose encoder?)")
        encoder = Encoder(num_layers)
        _load(encoder, enc_tensors, enc_path, f"a ResNet-{num_layers} encoder")
        dec_tensors = {k: v for k, v in dec.items() if hasattr(v, "shape")}
        scales = sum(f"decoder.{N_BLOCKS + s}.conv.weight" in dec_tensors for s in range(4))
        if scales == 0 or any(f"decoder.{N_BLOCKS + s}.conv.weight" not in dec_tensors
                              for s in range(scales)):
            raise RobodepthError(f"{dec_path}: not a monodepth2 DepthDecoder (no output convolution "
                                 f"decoder.{N_BLOCKS}.conv.weight)")
        decoder = Decoder(encoder.encoder.channels, scales)
        _load(decoder, dec_tensors, dec_path,
              f"the depth decoder of a ResNet-{num_layers} encoder")
        return cls(encoder, decoder, num_layers)

    def to(self, device) -> "DepthNet":
        self.encoder.to(device)
        self.decoder.to(device)
        return self

    def eval(self) -> "DepthNet":
        self.encoder.eval()
        self.decoder.eval()
        return self

    def __call__(self, x):
        sigmoid = self.decoder(self.encoder(x))
        min_disp, max_disp = 1 / MAX_DEPTH, 1 / MIN_DEPTH
        return min_disp + (max_disp - min_disp) * sigmoid


def _load(module, tensors: dict, path: Path, what: str) -> None:
    """Load ``tensors`` into ``module`` strictly, or say in one line how they differ."""
    expected = module.state_dict()
    missing = [k for k in expected if k not in tensors]
    extra = [k for k in tensors if k not in expected]
    wrong = [k for k in expected if k in tensors and tuple(tensors[k].shape) != tuple(expected[k].shape)]
    if missing or extra or wrong:
        parts = []
        if wrong:
            k = wrong[0]
            parts.append(f"{k} has shape {tuple(tensors[k].shape)}, expected "
                         f"{tuple(expected[k].shape)}" + (f" (+{len(wrong) - 1} more)" if len(wrong) > 1 else ""))
        if missing:
            parts.append(f"missing {missing[0]}" + (f" (+{len(missing) - 1} more)" if len(missing) > 1 else ""))
        if extra:
            parts.append(f"unexpected {extra[0]}" + (f" (+{len(extra) - 1} more)" if len(extra) > 1 else ""))
        raise RobodepthError(f"{path}: does not fit {what}: {'; '.join(parts)}")
    module.load_state_dict({k: v.float() if v.is_floating_point() else v
                           for k, v in tensors.items()}, strict=True)
