"""AdaIN style transfer on the CPU or a CUDA GPU: the torch engine of KITTI-S, self-contained.

The encoder and decoder are ``nn.Sequential`` models whose module indices are those of the
public PyTorch AdaIN release, so its checkpoints (``vgg_normalised.pth``, ``decoder.pth``:
plain state_dicts with keys like ``2.weight``) load unchanged. Checkpoints are read with
``torch.load(..., weights_only=True)`` and validated tensor by tensor before use.

:class:`Stylizer` is the fast path used by builds: a style's feature statistics are
computed once (:meth:`Stylizer.style_features`), a content image is encoded once for all
of its styles, and decoding is batched over styles. The result equals stylising each
(content, style) pair on its own up to float rounding. The same code runs on either
device (:func:`choose_device`); on a GPU all the styles of an image are decoded in one
batch, in float32 (TF32 off).

This module imports torch at import time and nothing of the package's KITTI-S inputs
(:mod:`robodepth_cli.styles.inputs` imports it, never the reverse); import it only when style
work runs.
"""

from __future__ import annotations

import os
import pickle
import re
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from torch import nn

from ..imageio import as_rgb
from ..errors import RobodepthError, os_reason

EPS = 1e-5

# Styles decoded per batch. Larger batches do not pay on a CPU: the convolutions already
# run near its peak and larger activations spill the cache (bench/stylize.py times 1, 2, 4).
# A GPU is only kept busy by large batches: there every style of an image goes in one.
DEFAULT_CHUNK = 1
GPU_CHUNK = 64

DEVICES = ("auto", "cpu", "cuda")


# Layouts: one entry per module, in order, so list positions are the published indices.
# ("conv", in, out, kernel) | ("pad",) | ("relu",) | ("pool",) | ("up",)
_PAD, _RELU, _POOL, _UP = ("pad",), ("relu",), ("pool",), ("up",)


def _block(cin: int, cout: int, relu: bool = True) -> list[tuple]:
    return [_PAD, ("conv", cin, cout, 3)] + ([_RELU] if relu else [])


ENCODER_LAYOUT: tuple[tuple, ...] = tuple(
    [("conv", 3, 3, 1)]
    + _block(3, 64) + _block(64, 64) + [_POOL]
    + _block(64, 128) + _block(128, 128) + [_POOL]
    + _block(128, 256) + _block(256, 256) + _block(256, 256) + _block(256, 256) + [_POOL]
    + _block(256, 512)  # ends at relu4_1, index 30
)
DECODER_LAYOUT: tuple[tuple, ...] = tuple(
    _block(512, 256) + [_UP]
    + _block(256, 256) + _block(256, 256) + _block(256, 256) + _block(256, 128) + [_UP]
    + _block(128, 128) + _block(128, 64) + [_UP]
    + _block(64, 64) + _block(64, 3, relu=False)
)
ENCODER_LAST = len(ENCODER_LAYOUT) - 1  # 30: deeper layers of vgg_normalised.pth are ignored


class CheckpointError(RobodepthError):
    """A checkpoint that cannot be used; the message names the file and the tensor."""


def choose_device(choice: str) -> torch.device:
    """The device of ``--device`` ``choice``: ``cpu``; ``cuda`` (the current CUDA device,
    :class:`RobodepthError` if there is none); ``auto``: CUDA when there is a device, else
    the CPU."""
    if choice not in DEVICES:
        raise RobodepthError(f"--device: expected one of {', '.join(DEVICES)}, got {choice!r}")
    if choice == "cpu" or (choice == "auto" and not torch.cuda.is_available()):
        return torch.device("cpu")
    if not torch.cuda.is_available():
        why = ("this torch is a CPU-only build" if torch.version.cuda is None
               else "torch finds no CUDA device")
        raise RobodepthError(f"--device cuda: no CUDA device ({why}, torch {torch.__version__}); "
                             f"use --device cpu or auto")
    return torch.device("cuda", torch.cuda.current_device())


def describe_device(device: torch.device) -> str:
    """``device`` for messages: ``the CPU`` or ``cuda:0 (NVIDIA ...)``."""
    if device.type == "cuda":
        return f"{device} ({torch.cuda.get_device_name(device)})"
    return "the CPU"


# ---------------------------------------------------------------------------- models


def _module(spec: tuple) -> nn.Module:
    kind = spec[0]
    if kind == "conv":
        _, cin, cout, k = spec
        return nn.Conv2d(cin, cout, k)
    if kind == "pad":
        return nn.ReflectionPad2d(1)
    if kind == "relu":
        return nn.ReLU()
    if kind == "pool":
        return nn.MaxPool2d(2, 2, ceil_mode=True)
    if kind == "up":
        return nn.Upsample(scale_factor=2, mode="nearest")
    raise AssertionError(spec)


def sequential(layout: Sequence[tuple]) -> nn.Sequential:
    """An untrained ``nn.Sequential`` with one module per layout entry (eval mode)."""
    return nn.Sequential(*(_module(s) for s in layout)).eval()


def encoder() -> nn.Sequential:
    """The VGG-19 "normalised" encoder up to relu4_1 (modules 0..30), untrained."""
    return sequential(ENCODER_LAYOUT)


def decoder() -> nn.Sequential:
    """The AdaIN decoder (29 modules), untrained."""
    return sequential(DECODER_LAYOUT)


def expected_tensors(layout: Sequence[tuple]) -> dict[str, tuple[tuple[int, ...], str]]:
    """``{key: (shape, description)}`` of every parameter the layout needs."""
    out = {}
    for i, spec in enumerate(layout):
        if spec[0] == "conv":
            _, cin, cout, k = spec
            what = f"conv {cin}->{cout} {k}x{k}"
            out[f"{i}.weight"] = ((cout, cin, k, k), what)
            out[f"{i}.bias"] = ((cout,), what)
    return out


# ---------------------------------------------------------------------- checkpoints

_KEY = re.compile(r"^(\d+)\.(weight|bias)$")


def _shape(t) -> str:
    return "(" + ", ".join(str(d) for d in t) + ")"


def read_state_dict(path: str | os.PathLike) -> dict[str, torch.Tensor]:
    """Load ``path`` with ``weights_only=True`` and check it is a mapping of names to
    tensors; ``CheckpointError`` otherwise."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"{path}: no such file")
    if path.is_dir():
        raise CheckpointError(f"{path}: is a directory, not a checkpoint file")
    try:
        with warnings.catch_warnings():
            # torch warns about pickle protocols it does not expect; the checks below and
            # the error message say everything the user needs.
            warnings.simplefilter("ignore")
            obj = torch.load(path, map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, zipfile.BadZipFile, ValueError,
            AttributeError, TypeError, ImportError, IndexError, KeyError, OSError) as exc:
        # torch's own text advises turning weights_only off (which would run arbitrary code
        # from the file) and runs over several lines: say what is wrong in our own words.
        raise CheckpointError(f"{path}: not a PyTorch state_dict ({_load_problem(path, exc)}); "
                              f"expected a checkpoint of the AdaIN release such as "
                              f"vgg_normalised.pth or decoder.pth") from None
    if not isinstance(obj, dict):
        raise CheckpointError(
            f"{path}: expected a state_dict (tensor names -> tensors), got {type(obj).__name__}")
    for key, value in obj.items():
        if not isinstance(key, str) or not isinstance(value, torch.Tensor):
            raise CheckpointError(
                f"{path}: expected a state_dict (tensor names -> tensors); entry {key!r} "
                f"is a {type(value).__name__}")
    return obj


def _load_problem(path: Path, exc: BaseException) -> str:
    """What a failed ``torch.load`` means, in one short clause."""
    if isinstance(exc, EOFError):
        empty = path.stat().st_size == 0 if path.is_file() else False
        return "the file is empty" if empty else "the file ends too early"
    if isinstance(exc, zipfile.BadZipFile) or (isinstance(exc, RuntimeError) and "zip" in str(exc)):
        return "its zip archive is damaged or incomplete; download it again"
    if isinstance(exc, pickle.UnpicklingError):
        return "it holds Python objects besides tensors, which are never loaded"
    if isinstance(exc, OSError):
        return f"cannot read it: {os_reason(exc)}"
    return "the file is not in PyTorch's format"


def validate_state_dict(state: dict[str, torch.Tensor], layout: Sequence[tuple], *,
                        source: str, ignore_after: int | None = None) -> dict[str, torch.Tensor]:
    """Check ``state`` against ``layout`` and return exactly the tensors it needs, float32.

    Every conv weight and bias of the layout must be present with its exact shape, floating
    point and finite. Keys ``<i>.weight`` / ``<i>.bias`` with ``i > ignore_after`` are
    ignored (the deeper VGG layers); any other extra key is refused. Problems raise
    ``CheckpointError`` naming ``source`` and the first offending tensor.
    """
    need = expected_tensors(layout)
    problems = []
    for key, (shape, what) in need.items():
        if key not in state:
            problems.append(f"missing tensor '{key}' ({what}, shape {_shape(shape)})")
            continue
        t = state[key]
        if tuple(t.shape) != shape:
            problems.append(
                f"tensor '{key}' ({what}) has shape {_shape(t.shape)}, expected {_shape(shape)}")
        elif not t.is_floating_point():
            problems.append(f"tensor '{key}' has dtype {t.dtype}, expected floating point")
        elif not bool(torch.isfinite(t).all()):
            problems.append(f"tensor '{key}' contains NaN or infinite values")
    for key in state:
        if key in need:
            continue
        m = _KEY.match(key)
        if ignore_after is not None and m and int(m.group(1)) > ignore_after:
            continue
        problems.append(f"unexpected tensor '{key}'")
    if problems:
        more = f" (and {len(problems) - 1} more problem(s))" if len(problems) > 1 else ""
        raise CheckpointError(f"{source}: {problems[0]}{more}")
    return {k: state[k].detach().to(torch.float32) for k in need}


def _looks_like(state: dict, layout: Sequence[tuple]) -> bool:
    need = expected_tensors(layout)
    return all(k in state and tuple(state[k].shape) == s for k, (s, _) in need.items())


def load_model(path: str | os.PathLike, kind: str) -> nn.Sequential:
    """The encoder (``kind="vgg"``) or decoder (``kind="decoder"``) with the weights of the
    checkpoint at ``path``; ``CheckpointError`` naming the file and tensor otherwise."""
    if kind == "vgg":
        layout, ignore, other, other_name = ENCODER_LAYOUT, ENCODER_LAST, DECODER_LAYOUT, "decoder"
    elif kind == "decoder":
        layout, ignore, other, other_name = DECODER_LAYOUT, None, ENCODER_LAYOUT, "vgg"
    else:
        raise ValueError(f"kind must be 'vgg' or 'decoder', got {kind!r}")
    state = read_state_dict(path)
    try:
        tensors = validate_state_dict(state, layout, source=str(path), ignore_after=ignore)
    except CheckpointError as exc:
        if _looks_like(state, other):
            raise CheckpointError(
                f"{path}: this is the AdaIN {other_name} checkpoint, not the {kind} one "
                f"(were --vgg and --decoder swapped?)") from None
        raise exc from None
    model = sequential(layout)
    model.load_state_dict(tensors, strict=True)
    for p in model.parameters():
        p.requires_grad_(False)
    return model


# -------------------------------------------------------------------- the transform


def to_tensor(img: np.ndarray, *, channels_last: bool = False) -> torch.Tensor:
    """uint8 H x W x 3 -> float32 1 x 3 x H x W in [0, 1]."""
    with warnings.catch_warnings():
        # A read-only array (the builder's clean image) is only read: .to() copies it.
        warnings.simplefilter("ignore", UserWarning)
        x = torch.from_numpy(np.ascontiguousarray(as_rgb(img)))
    x = x.permute(2, 0, 1).unsqueeze(0).to(torch.float32).div_(255.0)
    return x.contiguous(memory_format=torch.channels_last if channels_last else torch.contiguous_format)


def round_to_uint8(out: torch.Tensor) -> np.ndarray:
    """N x 3 x H x W in [0, 1] (clamped) -> uint8 N x H x W x 3, rounded:
    ``uint8(v * 255 + 0.5)`` (the corruptions truncate instead, as their benchmark does)."""
    v = out.clamp(0.0, 1.0).mul_(255.0).add_(0.5).to(torch.uint8)
    return np.ascontiguousarray(v.permute(0, 2, 3, 1).cpu().numpy())


def mean_std(feat: torch.Tensor, eps: float = EPS) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-sample, per-channel mean and std over the spatial positions of an N x C x H x W
    tensor, each N x C x 1 x 1; std is ``sqrt(unbiased variance + eps)``."""
    n, c = feat.shape[:2]
    flat = feat.reshape(n, c, -1)
    var = flat.var(dim=2, unbiased=True) + eps
    return flat.mean(dim=2).view(n, c, 1, 1), var.sqrt().view(n, c, 1, 1)


def adain(content_feat: torch.Tensor, style_mean: torch.Tensor, style_std: torch.Tensor,
          alpha: float = 1.0) -> torch.Tensor:
    """``alpha * ((Fc - mean_c) / std_c * std_s + mean_s) + (1 - alpha) * Fc``.

    ``content_feat`` is 1 x C x h x w (or N x C x h x w); the style statistics are
    S x C x 1 x 1 and broadcast, giving one target feature map per style."""
    mc, sc = mean_std(content_feat)
    t = (content_feat - mc) / sc * style_std + style_mean
    if alpha != 1.0:
        t = alpha * t + (1.0 - alpha) * content_feat
    return t


# ----------------------------------------------------------------------- the engine


def pixel_affine(conv: nn.Conv2d, x: torch.Tensor) -> torch.Tensor:
    """A 1 x 1 convolution (the encoder's first module) as a fixed sequence of elementwise
    operations. oneDNN's 1 x 1 convolution rounds differently with 1 and 2 threads, which
    would make an image's bytes depend on the number of workers; every other module of the
    encoder and decoder gives the same bits for any thread count (tests/styles/test_adain.py)."""
    w, b = conv.weight[:, :, 0, 0], conv.bias
    y = x[:, :1] * w[:, 0].view(1, -1, 1, 1)
    for c in range(1, w.shape[1]):
        y = y + x[:, c:c + 1] * w[:, c].view(1, -1, 1, 1)
    return y + b.view(1, -1, 1, 1)


@dataclass(frozen=True)
class StyleFeatures:
    """Per-channel mean and std (each 1 x 512 x 1 x 1) of ``enc(style)``."""

    mean: torch.Tensor
    std: torch.Tensor


class Stylizer:
    """Batched AdaIN stylisation with one encoder/decoder pair.

    ``threads`` sets torch's intra-op thread count (None leaves it). ``chunk`` is how many
    styles are decoded in one batch (None: :data:`DEFAULT_CHUNK` on the CPU,
    :data:`GPU_CHUNK` on a GPU); on the CPU neither changes the bytes of the result.
    ``channels_last`` runs the convolutions in NHWC, which oneDNN executes faster on CPU
    than NCHW. ``device``: where the models run (a ``torch.device`` or its name; default
    the CPU); images come in and go out as numpy arrays either way, and style statistics
    are kept on the CPU so they can be sent to other processes.
    """

    def __init__(self, enc: nn.Sequential, dec: nn.Sequential, *, chunk: int | None = None,
                 channels_last: bool = True, threads: int | None = None,
                 device: torch.device | str | None = None):
        if threads is not None:
            torch.set_num_threads(int(threads))
        self.device = torch.device(device or "cpu")
        if self.device.type == "cuda":
            # float32 as on the CPU (TF32 would round the convolutions to 10-bit mantissas),
            # and the same algorithms on every run, so a rebuild gives the same bytes.
            torch.backends.cudnn.allow_tf32 = False
            torch.backends.cuda.matmul.allow_tf32 = False
            torch.backends.cudnn.benchmark = False
            torch.backends.cudnn.deterministic = True
        if chunk is None:
            chunk = GPU_CHUNK if self.device.type == "cuda" else DEFAULT_CHUNK
        if chunk < 1:
            raise ValueError(f"chunk must be >= 1, got {chunk}")
        fmt = torch.channels_last if channels_last else torch.contiguous_format
        self.enc = enc.eval().to(self.device, memory_format=fmt)
        self.dec = dec.eval().to(self.device, memory_format=fmt)
        self.chunk = int(chunk)
        self.channels_last = channels_last

    @classmethod
    def from_files(cls, vgg: str | os.PathLike, dec: str | os.PathLike, **kwargs) -> "Stylizer":
        return cls(load_model(vgg, "vgg"), load_model(dec, "decoder"), **kwargs)

    def encode(self, img: np.ndarray) -> torch.Tensor:
        """``enc(img)``, 1 x 512 x h x w."""
        with torch.inference_mode():
            x = to_tensor(img, channels_last=self.channels_last).to(self.device)
            return self.enc[1:](pixel_affine(self.enc[0], x))

    def style_features(self, style: np.ndarray) -> StyleFeatures:
        """The statistics of a (resized) uint8 style image; compute once per style."""
        with torch.inference_mode():
            m, s = mean_std(self.encode(style))
        return StyleFeatures(m.cpu(), s.cpu())

    def stylize(self, content: np.ndarray, styles: Sequence[StyleFeatures],
                alpha: float = 1.0) -> list[np.ndarray]:
        """``content`` (uint8 H x W x 3) in every style of ``styles``: a list of uint8
        H x W x 3 images in the same order. The content is encoded once. ``alpha`` must
        lie in [0, 1] (``ValueError`` otherwise)."""
        if not 0.0 <= alpha <= 1.0:  # also refuses nan
            raise ValueError(f"alpha must be between 0 and 1, got {alpha!r}")
        content = as_rgb(content, what="content image")
        h, w = content.shape[:2]
        results: list[np.ndarray] = []
        if not styles:
            return results
        with torch.inference_mode():
            fc = self.encode(content)
            for i in range(0, len(styles), self.chunk):
                part = styles[i:i + self.chunk]
                t = adain(fc, torch.cat([s.mean for s in part]).to(self.device),
                          torch.cat([s.std for s in part]).to(self.device), alpha)
                if self.channels_last:
                    t = t.contiguous(memory_format=torch.channels_last)
                out = self.dec(t)[:, :, :h, :w]
                results.extend(round_to_uint8(out))
        return results
