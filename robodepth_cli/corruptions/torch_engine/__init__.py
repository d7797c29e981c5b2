"""The torch engine of the corruptions: the same 18 corruptions, formulas and random draws as
the numpy engine, on a batch ``N x 3 x H x W`` uint8 tensor on any device; every draw is
made on the CPU from the image's own numpy generator, in the numpy engine's order
(docs/torch-engine.md says which corruptions give the numpy engine's bytes, and how far the
others are). Importing the package imports no torch: :func:`corrupt_batch`,
:func:`render_batch`, :func:`resolve_device` and ``REGISTRY`` load the engine on first use."""

from __future__ import annotations

import importlib

_ENGINE = ("REGISTRY", "ON_CPU", "corrupt_batch", "corrupt_chain_batch", "render_batch", "resolve_device",
           "to_batch", "from_batch")

__all__ = list(_ENGINE)


def __getattr__(name: str):
    if name in _ENGINE:
        return getattr(importlib.import_module("._engine", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_ENGINE))
