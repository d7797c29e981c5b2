"""The batch path of the :mod:`robodepth_cli.torch` transforms: an ``N x 3 x H x W`` tensor,
typically on the GPU after the ``DataLoader``, corrupted on its own device by the torch
engine (:mod:`robodepth_cli.corruptions.torch_engine`), each item with its own generator.

Each transform's ``__call__`` hands a 4-D tensor here. Items are grouped by what they get
(one corruption and level, or one chain), so each group runs as one batch.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from .. import seeding
from ..corruptions import torch_engine
from ..errors import InvalidValueError
from .errors import TorchAPIError


def is_batch(img) -> bool:
    return isinstance(img, torch.Tensor) and img.ndim == 4


def _as_uint8(batch: torch.Tensor) -> tuple[torch.Tensor, object]:
    """``(uint8 N x 3 x H x W on batch's device, function turning a result back)``: a
    floating batch in [0, 1] is rounded to uint8 levels and returned as floats again."""
    if batch.shape[1] != 3:
        raise TorchAPIError(f"expected an N x 3 x H x W batch, got shape {tuple(batch.shape)}")
    if batch.dtype == torch.uint8:
        return batch, lambda out: out
    if batch.is_floating_point():
        levels = (batch.detach().clamp(0, 1) * 255).round().to(torch.uint8)
        return levels, lambda out: out.to(batch.dtype) / 255
    raise TorchAPIError(f"expected a uint8 or floating-point batch, got {batch.dtype}")


def _keys(keys, n: int) -> list | None:
    if keys is None:
        return None
    if isinstance(keys, (str, bytes)) or not isinstance(keys, Sequence) or len(keys) != n:
        raise TorchAPIError(f"a batch of {n} needs a sequence of {n} keys (one per item), got {keys!r}")
    return list(keys)


def _run(batch: torch.Tensor, groups: dict) -> torch.Tensor:
    """``groups`` maps a variant (a corruption and level, or a chain) to its items and
    their generators; each group runs as one batch; the other items are left as they are."""
    out = batch.clone()
    try:
        for (name, level, chain), (index, rngs) in groups.items():
            idx = torch.tensor(index, device=batch.device)
            part = batch.index_select(0, idx)
            if chain is not None:
                done = torch_engine.corrupt_chain_batch(part, chain, rngs)
            else:
                done = torch_engine.corrupt_batch(part, name, level, rngs)
            out.index_copy_(0, idx, done)
    except InvalidValueError as exc:  # e.g. images below 32 x 32
        raise TorchAPIError(str(exc)) from None
    return out


def corrupt(t, batch: torch.Tensor, keys) -> torch.Tensor:
    """:class:`~robodepth_cli.torch.Corrupt` on a batch: with ``keys`` (one per item),
    item ``i`` draws what a build draws for ``keys[i]``, so it equals the single-image
    call with that key; without, the items draw in turn from the transform's generator."""
    from ..sourcekeys import seed_key

    x, back = _as_uint8(batch)
    keys = _keys(keys, len(x))
    if keys is not None:
        t.rng_for(keys[0])  # the refusal without a seed
    n = len(x)
    if t.chain is None:
        rngs = ([t.rng_for(k) for k in keys] if keys is not None else [t.rng_for(None)] * n)
        return back(_run(x, {(t.name, t.level, None): (list(range(n)), rngs)}))
    if keys is None:
        rngs = [[t.rng_for(None)] * len(t.chain.steps)] * n
    else:
        rngs = [seeding.chain_rngs(t.seed, t.dataset, t.chain, seed_key(t.dataset, k)) for k in keys]
    return back(_run(x, {(t.name, None, t.chain): (list(range(n)), rngs)}))


def random_corrupt(t, batch: torch.Tensor, keys, epoch: int):
    """:class:`~robodepth_cli.torch.RandomCorrupt` on a batch: ``(batch, applied)``,
    ``applied[i]`` the ``name:level`` item ``i`` got ("" when none). With ``keys`` item
    ``i``'s draws (whether, which, and the corruption's own) come from the generator of
    ``(seed, keys[i], epoch)``, the same in any process; without, from the transform's
    generator in turn."""
    from ..corruptions.chains import Step

    x, back = _as_uint8(batch)
    keys = _keys(keys, len(x))
    if keys is not None and t._gen.seed is None:
        raise TorchAPIError("keys= needs a seed: create the transform with seed=N")
    groups: dict = {}
    applied = []
    for i in range(len(x)):
        rng = (t._gen.get() if keys is None
               else seeding.sample_rng(t._gen.seed, "random-corrupt", epoch, str(keys[i])))
        if rng.random() >= t.p:
            applied.append("")
            continue
        name = t.names[rng.integers(len(t.names))]
        level = t.levels[rng.integers(len(t.levels))]
        applied.append(Step(name, level).text)
        index, rngs = groups.setdefault((name, level, None), ([], []))
        index.append(i)
        rngs.append(rng)
    return back(_run(x, groups)), applied


def random_chain(t, batch: torch.Tensor, keys, epoch):
    """:class:`~robodepth_cli.torch.RandomChain` on a batch: ``(batch, chains)``, item
    ``i`` corrupted exactly as ``t(item, keys[i], epoch)`` would corrupt it, ``chains[i]``
    the canonical text of its chain ("" when none)."""
    x, back = _as_uint8(batch)
    keys = _keys(keys, len(x))
    if keys is None:
        raise TorchAPIError("RandomChain needs one key per item of a batch (keys=[...])")
    e = t._epoch(epoch)
    groups: dict = {}
    applied = []
    for i, key in enumerate(keys):
        chain = t.draw(key, e)
        applied.append("" if chain is None else chain.text)
        if chain is None:
            continue
        index, rngs = groups.setdefault((chain.text, None, chain), ([], []))
        index.append(i)
        rngs.append(seeding.chain_rngs(t.seed, f"random-chain epoch {e}", chain, str(key)))
    return back(_run(x, groups)), applied

