"""Decimal levels and chains in `robodepth corrupt`, `preview` and robodepth_cli.torch (issue 23)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from robodepth_cli import seeding
from robodepth_cli.corruptions import corrupt, corrupt_chain
from robodepth_cli.corruptions.chains import parse_chain
from robodepth_cli.imageio import load_clean

from tests.helpers.drawkey import pixels_key


def small_png(tmp_path, name="img.png", size=(48, 64)):
    arr = np.random.default_rng(3).integers(0, 256, (*size, 3), dtype=np.uint8)
    path = tmp_path / name
    Image.fromarray(arr).save(path)
    return path


def load(path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).copy()


def test_corrupt_at_a_decimal_level_is_the_library_call(tmp_path, cli):
    src = small_png(tmp_path)
    res = cli("corrupt", src, "-c", "gaussian_noise", "-l", "2.50", "-s", "5", "--out", tmp_path / "a.png")
    assert res.exit_code == 0, res.output
    clean = load_clean(src, None)
    want = corrupt(clean, "gaussian_noise", 2.5, seeding.job_rng(5, "image", "gaussian_noise", 2.5, pixels_key(clean)))
    assert np.array_equal(load(tmp_path / "a.png"), want)


def test_corrupt_a_chain_into_one_file(tmp_path, cli):
    src = small_png(tmp_path)
    res = cli("corrupt", src, "-c", "fog:3 + gaussian_noise:2.5", "-s", "5", "--out", tmp_path / "c.png")
    assert res.exit_code == 0, res.output
    chain = parse_chain("fog:3+gaussian_noise:2.5")
    clean = load_clean(src, None)
    want = corrupt_chain(clean, chain, seeding.chain_rngs(5, "image", chain, pixels_key(clean)))
    assert np.array_equal(load(tmp_path / "c.png"), want)


def test_corrupt_names_and_chain_templates_into_a_directory(tmp_path, cli):
    src = small_png(tmp_path)
    out = tmp_path / "out"
    res = cli("corrupt", src, "-c", "contrast,contrast+pixelate:2,brightness:1+color_quant:5",
              "-l", "1,1.5", "--out", f"{out}/")
    assert res.exit_code == 0, res.output
    got = sorted(str(p.relative_to(out)) for p in out.rglob("*.png"))
    assert got == ["brightness-1+color_quant-5.png", "contrast-1+pixelate-2.png",
                   "contrast-1.5+pixelate-2.png", "contrast/1.5.png", "contrast/1.png"]
    # deterministic steps: the chain file is the two corruptions one after the other
    clean = load_clean(src, None)
    step = corrupt(clean, "contrast", 1.5, np.random.default_rng(0))
    assert np.array_equal(load(out / "contrast-1.5+pixelate-2.png"), corrupt(step, "pixelate", 2, np.random.default_rng(0)))


@pytest.mark.parametrize("args,message", [
    (["-c", "fog:3+", "-l", "1"], "--corruption: chain 'fog:3+': step 2 is empty"),
    (["-c", "fog:3+smog:1"], "--corruption: chain 'fog:3+smog:1': step 2: unknown corruption 'smog'"),
    (["-c", "fog:5.5+snow:1"], "--corruption: chain 'fog:5.5+snow:1': step 1 (fog): level 5.5 is out of range"),
    (["-c", "+".join(["fog:1"] * 9)], "9 steps; a chain has at most 8"),
    (["-c", "fog", "-l", "1,,2"], "--level: expected levels such as 2 or 1,2.5,4 or 'all'"),
    (["-c", "fog+snow"], "looks like a file name, but fog+snow at levels 1,2,3,4,5 make 5 images"),
])
def test_bad_levels_and_chains_exit_2_with_one_line(tmp_path, cli, args, message):
    res = cli("corrupt", small_png(tmp_path), *args, "--out", tmp_path / "o.png")
    assert res.exit_code == 2
    assert message in res.output and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "o.png").exists()


def test_preview_takes_decimal_columns_and_chain_rows(tmp_path, cli):
    out = tmp_path / "sheet.png"
    res = cli("preview", small_png(tmp_path), "-c", "contrast,contrast+color_quant", "-l", "1,2.5,5",
              "--thumb-width", "64", "--out", out)
    assert res.exit_code == 0, res.output
    sheet = load(out)
    # header + clean row + 2 rows of 48-pixel thumbnails; 3 columns of 64
    assert sheet.shape[0] > 3 * 48 and sheet.shape[1] > 3 * 64
    res = cli("preview", small_png(tmp_path), "-c", "contrast", "-l", "0.5", "--out", out)
    assert res.exit_code == 2 and "--levels: level 0.5 is out of range" in res.output


# --- torch --------------------------------------------------------------------------------

torch = pytest.importorskip("torch")


def test_random_chain_is_reproducible_per_sample_and_epoch():
    from robodepth_cli.torch import RandomChain

    img = np.random.default_rng(0).integers(0, 256, (40, 56, 3), dtype=np.uint8)
    t = RandomChain(names=["fog", "gaussian_noise", "contrast", "pixelate"], steps=(2, 3),
                    severity={"fog": (1, 2)}, seed=7)
    out, applied = t(img, key=3, epoch=1)
    again, same = RandomChain(names=["fog", "gaussian_noise", "contrast", "pixelate"], steps=(2, 3),
                              severity={"fog": (1, 2)}, seed=7)(img, key=3, epoch=1)
    assert applied == same and np.array_equal(out, again)
    chain = parse_chain(applied)
    assert 2 <= len(chain.steps) <= 3 and len(set(chain.names)) == len(chain.names)
    # what it says it applied is what it applied
    rngs = seeding.chain_rngs(7, "random-chain epoch 1", chain, "3")
    assert np.array_equal(out, corrupt_chain(img, chain, rngs))
    # each sample and each epoch draws its own chain
    drawn = {t.draw(k, e).text for k in range(20) for e in range(3)}
    assert len(drawn) > 40
    for text in drawn:
        for step in parse_chain(text).steps:
            assert (1 <= step.level <= 2) if step.name == "fog" else (1 <= step.level <= 5)
            assert round(step.level, 2) == step.level
    t.set_epoch(1)
    assert t(img, key=3)[1] == applied


def test_random_chain_levels_cover_the_range_continuously():
    from robodepth_cli.torch import RandomChain

    t = RandomChain(names=["contrast"], steps=1, severity=(1.5, 3.5), seed=0)
    levels = [t.draw(k).steps[0].level for k in range(400)]
    assert 1.5 <= min(levels) < 1.7 and 3.3 < max(levels) <= 3.5
    assert len(set(levels)) > 100  # decimals, not the integer levels


class _Images(torch.utils.data.Dataset):
    def __init__(self, transform):
        self.t = transform
        self.img = np.random.default_rng(1).integers(0, 256, (36, 40, 3), dtype=np.uint8)

    def __len__(self):
        return 4

    def __getitem__(self, i):
        out, applied = self.t(self.img, key=i)
        return torch.from_numpy(out.copy()), applied


def test_random_chain_in_dataloader_workers_matches_the_main_process():
    from robodepth_cli.torch import RandomChain

    t = RandomChain(names=["gaussian_noise", "contrast", "impulse_noise"], steps=(1, 2), seed=3)
    t.set_epoch(2)
    ds = _Images(t)
    here = [ds[i] for i in range(4)]
    loader = torch.utils.data.DataLoader(ds, batch_size=None, num_workers=2)
    there = list(loader)
    assert [a for _, a in there] == [a for _, a in here]
    for (x, _), (y, _) in zip(there, here):
        assert torch.equal(x, y)


class _Drawn(torch.utils.data.Dataset):
    """What the transform draws for each index (no image work: the epoch is what matters)."""

    def __init__(self, transform):
        self.t = transform

    def __len__(self):
        return 6

    def __getitem__(self, i):
        return self.t.draw(i).text


@pytest.mark.slow
@pytest.mark.parametrize("context,workers", [("fork", 2), ("spawn", 1)])
def test_random_chain_set_epoch_reaches_persistent_workers(context, workers):
    from robodepth_cli.torch import RandomChain

    t = RandomChain(names=["gaussian_noise", "contrast", "impulse_noise", "fog"], steps=(1, 3), seed=3)
    # fork: the workers inherit the transform; spawn: torch pickles it to them
    loader = torch.utils.data.DataLoader(_Drawn(t), batch_size=None, num_workers=workers,
                                         persistent_workers=True, multiprocessing_context=context)
    seen = []
    for epoch in range(3):
        t.set_epoch(epoch)  # in the main process, before the epoch's iterator
        seen.append(list(loader))
    want = [[t.draw(i, epoch).text for i in range(6)] for epoch in range(3)]
    assert seen == want
    assert want[0] != want[1] != want[2]


@pytest.mark.parametrize("kwargs,message", [
    ({"names": []}, "names must not be empty"),
    ({"names": ["fogg"]}, "unknown corruption 'fogg'"),
    ({"steps": (0, 2)}, "steps must be an integer or a range"),
    ({"steps": 9}, "within 1..8"),
    ({"names": ["fog"], "steps": 2}, "up to 2 distinct corruptions, but names has only 1"),
    ({"severity": (0.5, 2)}, "severity of brightness"),
    ({"severity": (3, 2)}, "low 3 above high 2"),
    ({"severity": {"smog": (1, 2)}}, "severity names smog, which are not among names"),
    ({"p": 2}, "p must be in [0, 1]"),
    ({"seed": -1}, "seed must be an integer >= 0"),
])
def test_random_chain_bad_arguments(kwargs, message):
    from robodepth_cli.torch import RandomChain, TorchAPIError

    with pytest.raises(TorchAPIError) as info:
        RandomChain(**kwargs)
    assert message in str(info.value)


def test_corrupt_transform_takes_decimal_levels_and_chains():
    from robodepth_cli.torch import Corrupt

    img = np.random.default_rng(2).integers(0, 256, (40, 56, 3), dtype=np.uint8)
    t = Corrupt("gaussian_noise", 2.5, seed=4, dataset="custom")
    assert np.array_equal(t(img, key="a/b.png"),
                          corrupt(img, "gaussian_noise", 2.5, seeding.job_rng(4, "custom", "gaussian_noise", 2.5, "a/b.png")))
    c = Corrupt("fog:2+gaussian_noise:1.5", seed=4, dataset="custom")
    chain = parse_chain("fog:2+gaussian_noise:1.5")
    assert np.array_equal(c(img, key="a/b.png"),
                          corrupt_chain(img, chain, seeding.chain_rngs(4, "custom", chain, "a/b.png")))


def test_random_corrupt_keeps_decimal_levels():
    from robodepth_cli.torch import RandomCorrupt

    img = np.random.default_rng(2).integers(0, 256, (40, 56, 3), dtype=np.uint8)
    t = RandomCorrupt(names=["contrast"], levels=[2.5], p=1.0, seed=0)
    assert t.levels == (2.5,)
    assert np.array_equal(t(img), corrupt(img, "contrast", 2.5, np.random.default_rng(0)))
