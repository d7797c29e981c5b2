"""What every adapter gives: a :class:`Model`, and the checks of what it returns."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import RobodepthError


KINDS = ("disp", "sigmoid", "depth")  # what the maps hold, in robodepth evaluate's words


@dataclass
class Model:
    """A loaded model.

    ``predict(images)`` takes an ``N x H x W x 3`` uint8 RGB batch (one image size) and
    returns ``N`` maps as an ``N x h x w`` floating array, checked by :func:`check_maps`.
    ``kind`` is what the maps hold (``disp``: a disparity, ``sigmoid``: a raw sigmoid
    output that monodepth2's ``disp_to_depth`` turns into one, ``depth``); ``metric`` says
    whether they are in metres (else they are right only up to a scale, or a scale and a
    shift); ``align`` and ``align_space`` are the alignment ``robodepth evaluate`` uses by
    default for them; ``input_size`` the network's input (H, W) when fixed (else None, or
    what the model's processor says); ``identity`` what tells this model's weights apart
    (compared when a run resumes).
    """

    spec: str
    adapter: str
    kind: str
    metric: bool
    align: str
    align_space: str
    input_size: object
    identity: dict
    run: Callable[[np.ndarray], object] = field(repr=False)
    device: str = "cpu"
    options: dict = field(default_factory=dict)
    # A multi-frame model: the neighbour offsets it takes besides the frame (e.g. (-1, 1));
    # its batches are then N x F x H x W x 3, the frame first (see models/pycall.py).
    frames: tuple[int, ...] = ()
    # The torch modules whose parameters and FLOPs are counted (models/size.py); () when
    # the model exposes none.
    modules: tuple = field(default=(), repr=False)

    def predict(self, images: np.ndarray) -> np.ndarray:
        return check_maps(self.run(images), len(images), self.spec)

    def record(self) -> dict:
        """What ``PRED/predictions.json`` says about the model."""
        return {"model": self.spec, "adapter": self.adapter,
                "output": "depth" if self.kind == "depth" else "disparity",
                "scale": "metric" if self.metric else "relative",
                "input_size": self.input_size, "options": self.options,
                "identity": self.identity, **({"frames": list(self.frames)} if self.frames else {}),
                "evaluate": {"kind": self.kind, "align": self.align,
                             "align_space": self.align_space}}


def default_alignment(metric: bool) -> tuple[str, str]:
    """``(align, align_space)`` for a model's maps: none for metric ones, a least-squares
    scale and shift of the disparity for relative ones (as MiDaS and Depth Anything are
    judged)."""
    return ("none", "depth") if metric else ("scale-shift", "disparity")


def check_maps(out, n: int, spec: str) -> np.ndarray:
    """A model's output for a batch of ``n`` images as an ``n x h x w`` floating array, or
    :class:`RobodepthError` saying what is wrong (shape, dtype, NaN or infinity)."""
    if hasattr(out, "detach"):  # a torch tensor, perhaps on a GPU
        out = out.detach().float().cpu().numpy() if out.dtype.is_floating_point else out.cpu().numpy()
    elif isinstance(out, (list, tuple)):
        try:
            out = np.stack([np.asarray(o.detach().cpu().numpy() if hasattr(o, "detach") else o)
                            for o in out])
        except ValueError:
            raise RobodepthError(f"{spec}: returned maps of different sizes for one batch; expected "
                                 f"an array of {n} x h x w") from None
    if not isinstance(out, np.ndarray):
        raise RobodepthError(f"{spec}: returned a {type(out).__name__}; expected an array of "
                             f"{n} x h x w maps")
    if out.ndim == 4 and out.shape[1] == 1:
        out = out[:, 0]
    if out.ndim != 3 or out.shape[0] != n:
        raise RobodepthError(f"{spec}: returned shape {out.shape} for a batch of {n} images; "
                             f"expected {n} x h x w (one 2-D map per image)")
    if out.dtype.kind != "f":
        raise RobodepthError(f"{spec}: returned dtype {out.dtype}; expected floating-point maps "
                             "(float16, float32 or float64)")
    if 0 in out.shape[1:]:
        raise RobodepthError(f"{spec}: returned empty maps (shape {out.shape})")
    if out.dtype == np.float16:
        out = out.astype(np.float32)
    bad = ~np.isfinite(out)
    if bad.any():
        what = "NaN" if np.isnan(out).any() else "infinity"
        raise RobodepthError(f"{spec}: its output holds {what} ({int(bad.sum())} values in a batch "
                             f"of {n} images); nothing written for this variant")
    return out


def torch_device(device: str) -> str:
    """``auto`` -> ``cuda`` when torch sees a GPU, else ``cpu``; ``cuda`` without one is a
    :class:`RobodepthError`."""
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cuda" and not torch.cuda.is_available():
        build = "a CPU-only build" if torch.version.cuda is None else "no GPU visible"
        raise RobodepthError(f"--device cuda: CUDA is not available (torch {torch.__version__}: "
                             f"{build}); use --device cpu or auto")
    if device not in ("cpu", "cuda"):
        raise RobodepthError(f"--device {device!r}: valid: auto, cpu, cuda")
    return device
