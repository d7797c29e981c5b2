"""The robodepth_cli.torch transforms on a batch tensor (after the DataLoader, on its device):
each item gets what the single-image call (the numpy engine) gives it, and the transforms
say what each item got."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from robodepth_cli import corruptions, seeding
from robodepth_cli.torch import Corrupt, RandomChain, RandomCorrupt, TorchAPIError

from tests.helpers.images import smooth_image

# Corruptions whose torch engine output is the numpy engine's bytes on CPU torch.
IDENTICAL = ("fog", "gaussian_noise", "zoom_blur", "snow", "contrast", "glass_blur", "pixelate")
KEYS = ["d/0001.png", "d/0002.png", "d/0003.png", "d/0004.png"]


def items(n=4):
    return [torch.from_numpy(smooth_image(40, 56, seed=s)).permute(2, 0, 1).contiguous() for s in range(n)]


def test_corrupt_with_keys_equals_each_item_with_its_key():
    imgs = items()
    batch = torch.stack(imgs)
    for name in ("fog", "glass_blur", "fog:2+gaussian_noise:3.5"):
        t = Corrupt(name, None if ":" in name else 3, seed=5, dataset="kitti-c")
        out = t(batch, KEYS)
        assert out.shape == batch.shape and out.dtype == torch.uint8
        for i, img in enumerate(imgs):
            assert torch.equal(out[i], t(img, KEYS[i])), (name, i)


def test_corrupt_without_keys_draws_the_items_in_turn_from_its_generator():
    imgs = items(3)
    out = Corrupt("gaussian_noise", 2, seed=9)(torch.stack(imgs))
    one_by_one = Corrupt("gaussian_noise", 2, seed=9)
    for i, img in enumerate(imgs):
        assert torch.equal(out[i], one_by_one(img)), i


def test_a_float_batch_comes_back_as_floats():
    imgs = items(2)
    floats = torch.stack(imgs).to(torch.float32) / 255
    t = Corrupt("contrast", 4)
    out = t(floats, ["a.png", "b.png"])
    assert out.dtype == torch.float32
    assert torch.equal((out * 255).round().to(torch.uint8), t(torch.stack(imgs), ["a.png", "b.png"]))


def test_random_corrupt_says_what_each_item_got():
    imgs = items()
    t = RandomCorrupt(names=IDENTICAL, levels=(1, 2.5, 5), p=0.6, seed=3)
    out, applied = t(torch.stack(imgs), keys=KEYS, epoch=2)
    assert len(applied) == 4 and any(applied) and all(a == "" or ":" in a for a in applied)
    for img, key, got, what in zip(imgs, KEYS, out, applied):
        # The rule, replayed: the item's own generator decides, picks, then corrupts.
        rng = seeding.sample_rng(3, "random-corrupt", 2, key)
        if rng.random() >= 0.6:
            assert what == "" and torch.equal(got, img)
            continue
        name = IDENTICAL[rng.integers(len(IDENTICAL))]
        level = (1, 2.5, 5)[rng.integers(3)]
        assert what == f"{name}:{level}"
        expected = corruptions.corrupt(img.permute(1, 2, 0).numpy(), name, level, rng)
        assert np.array_equal(got.permute(1, 2, 0).numpy(), expected), what
    again, _ = t(torch.stack(imgs), keys=KEYS, epoch=2)
    assert torch.equal(again, out)  # per-item seeds: the same in any process or rerun


def test_random_chain_on_a_batch_equals_each_item():
    imgs = items()
    t = RandomChain(names=IDENTICAL, steps=(1, 3), p=0.8, seed=11)
    out, chains = t(torch.stack(imgs), KEYS, epoch=4)
    assert len(chains) == 4 and any(chains)
    for img, key, got, chain in zip(imgs, KEYS, out, chains):
        single, text = t(img, key, epoch=4)
        assert text == chain and torch.equal(got, single), (key, chain)


@pytest.mark.parametrize("call, message", [
    (lambda b: Corrupt("fog", 1)(b, ["only one"]), "a batch of 2 needs a sequence of 2 keys"),
    (lambda b: Corrupt("fog", 1, seed=None)(b, ["a", "b"]), "key= needs the build's seed"),
    (lambda b: RandomChain()(b, None), "RandomChain needs one key per item"),
    (lambda b: RandomCorrupt(seed=None)(b, keys=["a", "b"]), "keys= needs a seed"),
    (lambda b: RandomCorrupt(seed=1)(b[0], keys=["a"]), "keys= is for a batch"),
    (lambda b: Corrupt("fog", 1)(b[:, :, :20]), "at least 32 x 32"),
    (lambda b: Corrupt("fog", 1)(b.to(torch.int32)), "uint8 or floating-point"),
])
def test_bad_batches_are_refused(call, message):
    with pytest.raises(TorchAPIError, match=message):
        call(torch.stack(items(2)))


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_a_batch_on_the_gpu_stays_there_within_one_level():
    imgs = items()
    t = RandomChain(steps=(1, 2), seed=2)
    out, chains = t(torch.stack(imgs).cuda(), KEYS)
    assert out.is_cuda
    for img, key, got, chain in zip(imgs, KEYS, out.cpu(), chains):
        single, text = t(img, key)
        assert text == chain
        assert ((got.int() - single.int()).abs() <= 1).float().mean() >= 0.999
