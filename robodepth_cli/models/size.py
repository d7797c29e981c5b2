"""A torch model's size as ``robodepth predict`` measures it on the first batch: its
parameters (shared tensors once, buffers not counted) and its FLOPs per image, what
:class:`torch.utils.flop_counter.FlopCounterMode` counts over that batch divided by its
images (matrix products and convolutions, a multiply-add as 2 FLOPs: twice the "MACs" of
many papers), at the input size the network ran, the ``--post-process`` pass included."""

from __future__ import annotations

from typing import Sequence

import numpy as np

COUNTER = "torch.utils.flop_counter.FlopCounterMode"
CONVENTION = "a multiply-add counts 2 FLOPs; matrix products and convolutions only"


def parameters(modules: Sequence) -> int:
    """The number of parameter elements of ``modules`` (torch ``nn.Module``s), each tensor
    once however many modules share it."""
    seen: dict[int, int] = {}
    for m in modules:
        for p in m.parameters():
            seen.setdefault(id(p), p.numel())
    return sum(seen.values())


def measured(model, batch: np.ndarray) -> tuple[np.ndarray, dict | None]:
    """``model.predict(batch)`` and, for a model with torch modules (``model.modules``),
    its size: ``{"params", "flops" (per image), "image_size" [h, w] of the batch,
    "counter", "convention"}``; None for a model without modules (a ``python:`` callable
    that exposes none), whose FLOPs are not known."""
    modules = tuple(getattr(model, "modules", ()) or ())
    if not modules:
        return model.predict(batch), None
    from torch.utils.flop_counter import FlopCounterMode

    with FlopCounterMode(display=False) as counter:
        maps = model.predict(batch)
    size = {"params": parameters(modules), "flops": int(counter.get_total_flops()) // len(batch),
            "image_size": [int(batch.shape[-3]), int(batch.shape[-2])], "counter": COUNTER,
            "convention": CONVENTION}
    return maps, size


def modules_of(fn, spec: str) -> tuple:
    """The torch modules a ``python:`` callable exposes: what its ``robodepth_module``
    attribute names (a module, or a list of them), else itself when it is an ``nn.Module``,
    else the module it is a method of; () when it exposes none (torch is then not imported
    for it). :class:`RobodepthError` for a ``robodepth_module`` that is not a module."""
    import sys

    declared = getattr(fn, "robodepth_module", None)
    if "torch" not in sys.modules and declared is None:
        return ()  # torch never imported: nothing of it is a torch module
    import torch

    if declared is not None:
        found = list(declared) if isinstance(declared, (list, tuple)) else [declared]
        if not found or not all(isinstance(m, torch.nn.Module) for m in found):
            from ..errors import RobodepthError

            raise RobodepthError(f"{spec}: robodepth_module must be a torch.nn.Module or a list of "
                                 "them (the modules whose parameters and FLOPs are counted)")
        return tuple(found)
    for candidate in (fn, getattr(fn, "__self__", None)):
        if isinstance(candidate, torch.nn.Module):
            return (candidate,)
    return ()
