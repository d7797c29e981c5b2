"""Depth models behind ``robodepth predict``: a model spec (``monodepth2:DIR``,
``hf:PATH_OR_NAME``, ``python:MODULE:CALLABLE``; docs/predict.md) in, a
:class:`~robodepth_cli.models.base.Model` out, whose ``predict(images)`` maps an
``N x H x W x 3`` uint8 batch to ``N`` maps and which states what they hold. This module
imports nothing heavy: torch and transformers are imported only when a model is loaded."""

from __future__ import annotations

from ..errors import RobodepthError


ADAPTERS = ("monodepth2", "hf", "python")


def parse_spec(spec: str) -> tuple[str, str]:
    """``"monodepth2:DIR"`` -> ``("monodepth2", "DIR")``; :class:`RobodepthError` for a spec
    that names no known adapter or has nothing after the colon."""
    adapter, sep, arg = spec.partition(":")
    if not sep or adapter not in ADAPTERS:
        raise RobodepthError(f"--model {spec!r}: unknown model adapter; give "
                             "monodepth2:DIR, hf:PATH_OR_NAME or python:MODULE:CALLABLE")
    if not arg:
        raise RobodepthError(f"--model {spec!r}: nothing after '{adapter}:'")
    return adapter, arg


def load_model(spec: str, *, device: str = "auto", kind: str | None = None,
               metric: bool | None = None, post_process: bool = False):
    """Load the model ``spec`` names, ready to predict (see :mod:`.base` for the result).

    ``device`` (auto, cpu, cuda) applies to monodepth2 and hf models; ``kind`` and
    ``metric`` state what a python callable's maps hold (required there) or override an hf
    model's own; ``post_process`` is monodepth2's flip averaging.
    """
    adapter, arg = parse_spec(spec)
    if post_process and adapter != "monodepth2":
        raise RobodepthError("--post-process applies to monodepth2 models only (its flip averaging)")
    if adapter == "monodepth2":
        if kind is not None or metric is not None:
            raise RobodepthError("--kind/--metric: a monodepth2 model's output is known (a scaled "
                                 "disparity, up to scale); leave them out")
        from .monodepth2 import load

        return load(arg, spec, device=device, post_process=post_process)
    if adapter == "hf":
        from .hf import load

        return load(arg, spec, device=device, kind=kind, metric=metric)
    from .pycall import load

    return load(arg, spec, kind=kind, metric=metric)
