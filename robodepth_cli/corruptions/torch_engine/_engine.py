"""The torch engine's registry and entry points (reached through the package)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ...errors import InvalidValueError
from .. import _engine as numpy_engine
from ..chains import Chain, looks_like_chain, parse_chain
from . import _pointwise, _spatial, _weather  # noqa: F401  (imported for registration)
from ._tops import implemented

# Inherently sequential or a codec: these run through the numpy engine, image by image, on
# the CPU (the batch goes there and back).
ON_CPU = ("glass_blur", "jpeg_compression")

_TORCH = implemented()
REGISTRY: dict[str, object] = {name: _TORCH.get(name) for name in numpy_engine.NAMES}
if sorted(n for n, fn in REGISTRY.items() if fn is None) != sorted(ON_CPU):
    raise AssertionError("every corruption has a torch function except those run on the CPU")

DEVICES = ("auto", "cpu", "cuda")


def resolve_device(device: str = "auto") -> torch.device:
    """``auto``: CUDA when torch sees a GPU, else the CPU; ``cpu``; ``cuda`` (or
    ``cuda:N``), refused when no GPU is available."""
    text = str(device)
    if text == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if text == "cpu":
        return torch.device("cpu")
    if text == "cuda" or text.startswith("cuda:"):
        if not torch.cuda.is_available():
            raise InvalidValueError(f"device {text!r}: torch sees no CUDA GPU here; use cpu or auto")
        return torch.device(text)
    raise InvalidValueError(f"device {text!r}: expected auto, cpu or cuda")


def to_batch(images: Sequence[np.ndarray], device) -> torch.Tensor:
    """H x W x 3 uint8 arrays of one size as an N x 3 x H x W tensor on ``device``."""
    return torch.from_numpy(np.stack(images)).permute(0, 3, 1, 2).contiguous().to(device)


def from_batch(batch: torch.Tensor) -> list[np.ndarray]:
    """An N x 3 x H x W uint8 tensor as N H x W x 3 arrays on the CPU."""
    return list(batch.permute(0, 2, 3, 1).contiguous().cpu().numpy())


def _check_batch(x) -> torch.Tensor:
    if not isinstance(x, torch.Tensor) or x.dtype != torch.uint8 or x.ndim != 4 or x.shape[1] != 3:
        shown = f"{x.dtype} {tuple(x.shape)}" if isinstance(x, torch.Tensor) else type(x).__name__
        raise InvalidValueError(f"expected an N x 3 x H x W uint8 tensor, got {shown}")
    if x.shape[2] < 32 or x.shape[3] < 32:
        raise InvalidValueError(f"images must be at least 32 x 32, got {x.shape[2]} x {x.shape[3]}")
    return x


# Pixels per piece of a batch. On a GPU, large pieces keep it busy while the float64
# temporaries stay within a few GB (brightness holds ~15 per pixel and channel). On the CPU,
# pieces of an image or two are several times faster per image than whole batches: their
# temporaries stay in cache and in reused heap memory instead of fresh pages per operation.
CHUNK_PIXELS = 1 << 23
CPU_CHUNK_PIXELS = 1 << 18


def _apply(name: str, x: torch.Tensor, level, rngs: Sequence[np.random.Generator]) -> torch.Tensor:
    """``name`` on ``x``, in pieces of at most :data:`CHUNK_PIXELS` pixels (on the CPU
    :data:`CPU_CHUNK_PIXELS`), in item order
    (every draw is its item's, so the pieces change nothing but the memory held)."""
    budget = CPU_CHUNK_PIXELS if x.device.type == "cpu" else CHUNK_PIXELS
    step = max(1, budget // (x.shape[2] * x.shape[3]))
    if len(x) <= step:
        return _apply_all(name, x, level, rngs)
    return torch.cat([_apply_all(name, x[i:i + step], level, rngs[i:i + step]) for i in range(0, len(x), step)])


def _apply_all(name: str, x: torch.Tensor, level, rngs: Sequence[np.random.Generator]) -> torch.Tensor:
    fn = REGISTRY[name]
    if fn is None:
        arrays = from_batch(x)
        c = numpy_engine.get(name)
        return to_batch([numpy_engine._apply(c, a, level, rng, None) for a, rng in zip(arrays, rngs)], x.device)
    out = fn(x, level, rngs)
    if out.dtype != torch.uint8 or out.shape != x.shape:
        raise AssertionError(f"{name} returned {out.dtype} {tuple(out.shape)} for {tuple(x.shape)}")
    return out


def corrupt_batch(x: torch.Tensor, name: str, level, rngs: Sequence[np.random.Generator]) -> torch.Tensor:
    """Corruption ``name`` at ``level`` on every image of ``x`` (N x 3 x H x W uint8, any
    device), image ``i`` drawing from ``rngs[i]`` exactly what the numpy engine's
    :func:`~robodepth_cli.corruptions.corrupt` draws. Returns a new tensor on ``x``'s device."""
    c = numpy_engine.get(name)
    level = numpy_engine.check_level(c, level)
    rngs = _check_rngs(x, rngs)
    return _apply(c.name, _check_batch(x), level, rngs)


def corrupt_chain_batch(x: torch.Tensor, chain: Chain | str, rngs: Sequence[Sequence[np.random.Generator]]):
    """The steps of ``chain`` in order on every image, image ``i`` step ``k`` drawing from
    ``rngs[i][k]`` (as :func:`~robodepth_cli.corruptions.corrupt_chain` does)."""
    if not isinstance(chain, Chain):
        chain = parse_chain(chain)
    out = _check_batch(x)
    per_image = [list(r) for r in rngs]
    if len(per_image) != x.shape[0] or any(len(r) != len(chain.steps) for r in per_image):
        raise ValueError(f"chain {chain.text}: need {len(chain.steps)} generators for each of {x.shape[0]} images")
    for k, step in enumerate(chain.steps):
        out = _apply(step.name, out, step.level, _check_rngs(x, [r[k] for r in per_image]))
    return out


def render_batch(x: torch.Tensor, variant: str, level, *, seed: int, dataset: str, keys: Sequence[str]):
    """The images of one variant's jobs (one per key) from their clean images ``x``: the
    generators :func:`robodepth_cli.corruptions.render` uses, so the same pixels as the
    numpy engine gives, where the arithmetic allows (docs/torch-engine.md)."""
    from ... import seeding

    if looks_like_chain(variant):
        chain = parse_chain(variant)
        return corrupt_chain_batch(x, chain, [seeding.chain_rngs(seed, dataset, chain, k) for k in keys])
    return corrupt_batch(x, variant, level, [seeding.job_rng(seed, dataset, variant, level, k) for k in keys])


def _check_rngs(x, rngs) -> list:
    rngs = list(rngs)
    if len(rngs) != x.shape[0]:
        raise ValueError(f"{x.shape[0]} images but {len(rngs)} generators")
    for rng in rngs:
        numpy_engine._check_rng(rng)
    return rngs
