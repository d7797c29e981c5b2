"""`robodepth build` with decimal levels and chains (--compose, compose:): layout, manifest,
pixels, resume, verify and refusals (issue 23)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from robodepth_cli import corruptions, seeding
from robodepth_cli.api import open_dataset
from robodepth_cli.corruptions.chains import parse_chain

from tests.helpers.manifest import manifest_by_output
from tests.helpers.trees import kitti_key, kitti_tree, tree

FRAMES = [(5, "l", ".png"), (7, "r", ".jpg")]
CHAINS = "fog:1+gaussian_noise:2.5,contrast:2 + pixelate:1.5"
FLAGS = ["--size", "48x80", "--corruptions", "gaussian_noise", "--levels", "2,2.50",
         "--compose", CHAINS, "--jobs", "1", "--seed", "7"]


def png(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


@pytest.fixture(scope="module")
def built(tmp_path_factory, build_kitti):
    tmp = tmp_path_factory.mktemp("chains")
    root = tmp / "kitti_raw"
    split = kitti_tree(root, FRAMES)
    out = tmp / "out"
    res = build_kitti(root, split, out, *FLAGS)
    assert res.exit_code == 0, res.output
    return root, split, out


def test_layout_and_manifest(built):
    _, _, out = built
    keys = [kitti_key(5, "l"), kitti_key(7, "r")]
    dirs = ["clean", "gaussian_noise/2", "gaussian_noise/2.5", "fog-1+gaussian_noise-2.5", "contrast-2+pixelate-1.5"]
    assert set(tree(out)) == {f"{d}/{k}" for d in dirs for k in keys}
    rows = manifest_by_output(out)
    assert set(rows) == set(tree(out))
    got = {(r["variant"], r["level"]) for r in rows.values()}
    assert got == {("clean", ""), ("gaussian_noise", "2"), ("gaussian_noise", "2.5"),
                   ("fog:1+gaussian_noise:2.5", ""), ("contrast:2+pixelate:1.5", "")}


def test_pixels_follow_the_chain_streams(built):
    _, _, out = built
    files = tree(out)
    key = kitti_key(7, "r")
    clean = png(files[f"clean/{key}"])
    chain = parse_chain("fog:1+gaussian_noise:2.5")
    want = corruptions.corrupt_chain(clean, chain, seeding.chain_rngs(7, "kitti-c", chain, key))
    assert np.array_equal(png(files[f"fog-1+gaussian_noise-2.5/{key}"]), want)
    # deterministic steps: the two corruptions one after the other
    step = corruptions.corrupt(clean, "contrast", 2, np.random.default_rng(0))
    assert np.array_equal(png(files[f"contrast-2+pixelate-1.5/{key}"]),
                          corruptions.corrupt(step, "pixelate", 1.5, np.random.default_rng(0)))
    # a decimal level draws from its own stream, keyed by "2.5"
    rng = seeding.job_rng(7, "kitti-c", "gaussian_noise", 2.5, key)
    assert np.array_equal(png(files[f"gaussian_noise/2.5/{key}"]),
                          corruptions.corrupt(clean, "gaussian_noise", 2.5, rng))


def test_resume_and_verify(built, build_kitti, cli):
    root, split, out = built
    victim = out / "fog-1+gaussian_noise-2.5" / kitti_key(5, "l")
    before = victim.read_bytes()
    victim.unlink()
    res = build_kitti(root, split, out, *FLAGS)
    assert res.exit_code == 0, res.output
    assert "1 written, 9 skipped" in res.output
    assert victim.read_bytes() == before
    assert cli("verify", out).exit_code == 0
    victim.write_bytes(before[:-8] + b"\0" * 8)
    res = cli("verify", out)
    assert res.exit_code != 0 and "fog-1+gaussian_noise-2.5" in res.output
    victim.write_bytes(before)


def test_open_dataset_lists_decimal_levels_and_chains(built):
    _, _, out = built
    ds = open_dataset(out)
    assert [(v.name, v.level) for v in ds.variants()] == [
        ("clean", None), ("gaussian_noise", 2), ("gaussian_noise", 2.5),
        ("contrast:2+pixelate:1.5", None), ("fog:1+gaussian_noise:2.5", None)]
    v = ds.variant("fog:1+gaussian_noise:2.5")
    assert v.relpath == "fog-1+gaussian_noise-2.5" and all(p.is_file() for p in v.images())
    assert ds.variant("gaussian_noise", 2.5).relpath == "gaussian_noise/2.5"


def test_only_chains_from_a_config_file(tmp_path, build_kitti):
    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, FRAMES[:1])
    cfg = tmp_path / "chains.yaml"
    cfg.write_text("corruptions: none\ncompose:\n  - brightness:1.5+color_quant:2\n  - contrast:1\n")
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--config", cfg, "--size", "48x80", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert {p.split("/")[0] for p in tree(out)} == {"clean", "brightness-1.5+color_quant-2", "contrast-1"}


@pytest.mark.parametrize("flags,message", [
    (["--compose", "fog:3+"], "--compose: chain 'fog:3+': step 2 is empty (a '+' with nothing on one side)"),
    (["--compose", "fog:3,smog:1"], "--compose: chain 'smog:1': step 1: unknown corruption 'smog'"),
    (["--compose", "fog:5.5"], "--compose: chain 'fog:5.5': step 1 (fog): level 5.5 is out of range; valid levels: 1..5"),
    (["--compose", "+".join(["fog:1"] * 9)], "9 steps; a chain has at most 8"),
    (["--compose", "fog3"], "--compose: chain 'fog3': step 1 'fog3' is not NAME:LEVEL (e.g. 'fog:3')"),
    (["--levels", "2,5.5"], "--levels: level 5.5 is out of range for kitti-c; valid levels: 1..5"),
    (["--corruptions", "none"], "--corruptions: nothing to build: corruptions none and no compose chains"),
])
def test_bad_chains_and_levels_are_refused_before_any_work(tmp_path, build_kitti, flags, message):
    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, FRAMES[:1])
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--size", "48x80", *flags)
    assert res.exit_code == 2
    assert message in res.output and len(res.output.strip().splitlines()) == 1
    assert not out.exists()


def test_nyu_keeps_its_own_corruptions_and_range(fixtures_dir, tmp_path, cli):
    base = ["build", "nyudepth2-c", "--root", fixtures_dir / "nyu", "--split", fixtures_dir / "nyu_split.txt"]
    res = cli(*base, "--out", tmp_path / "a", "--compose", "dark:4.5")
    assert res.exit_code == 2 and "step 1 (dark): level 4.5 is out of range; valid levels: 1..4" in res.output
    res = cli(*base, "--out", tmp_path / "b", "--compose", "dark:2+fog:1")
    assert res.exit_code == 2 and "chain 'dark:2+fog:1': step 2: nyudepth2-c has no corruption 'fog'" in res.output
    res = cli(*base, "--out", tmp_path / "c", "--corruptions", "none", "--compose", "dark:3.5+contrast:2",
              "--levels", "3.5", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert {p.split("/")[0] for p in tree(tmp_path / "c")} == {"clean", "dark-3.5+contrast-2", "gt"}


def test_kitti_s_takes_no_chains(tmp_path, cli):
    res = cli("build", "kitti-s", "--root", tmp_path, "--out", tmp_path / "o", "--compose", "fog:1")
    assert res.exit_code == 2 and "--compose does not apply to kitti-s" in res.output


# --- presets: configs/protocols/ ------------------------------------------------------------

def test_heldout_protocol_builds_the_test_side_and_trains_on_the_rest():
    from tests.helpers.paths import REPO
    from robodepth_cli.benchmark_facts import CATEGORY, WEATHER
    from robodepth_cli.building.config import resolve

    path = REPO / "configs" / "protocols" / "heldout-weather.yaml"
    cfg = resolve("kitti-c", path)
    assert cfg.variants == tuple(n for n, c in CATEGORY.items() if c == WEATHER)
    assert cfg.levels == (1, 2, 3, 4, 5)
    torch = pytest.importorskip("torch")  # noqa: F841
    from robodepth_cli.torch import RandomChain

    aug = RandomChain.from_protocol(path, seed=1)
    assert set(aug.names) == set(CATEGORY) - set(cfg.variants)
    drawn = {name for k in range(200) for name in aug.draw(k).names}
    assert drawn and not drawn & set(cfg.variants)
    assert all(1 <= len(aug.draw(k).steps) <= 3 for k in range(50))


def test_chain_set_preset_builds_only_its_chains():
    from tests.helpers.paths import REPO
    from robodepth_cli.building.config import ConfigError, resolve

    path = REPO / "configs" / "protocols" / "chains.yaml"
    cfg = resolve("kitti-c", path)
    assert len(cfg.variants) == 8 and all(len(parse_chain(v).steps) >= 2 for v in cfg.variants)
    assert all(parse_chain(v).text == v for v in cfg.variants)
    assert resolve("kitti-c", path, {"corruptions": "all"}).variants[:18] == resolve("kitti-c").variants
    with pytest.raises(ConfigError, match="nyudepth2-c has no corruption 'fog'"):
        resolve("nyudepth2-c", path)


@pytest.mark.parametrize("text,message", [
    ("train: [fog]\n", "train: expected a mapping with corruptions"),
    ("train: {corruptions: [fogg]}\n", "train: corruptions: unknown corruption 'fogg'"),
    ("train: {corruptions: [fog], steps: [0, 2]}\n", "steps: expected an integer or [min, max] within 1..8"),
    ("train: {corruptions: [fog], severity: [1, 6]}\n", "severity: level: level 6 is out of range for kitti-c"),
    ("train: {corruptions: [fog], epochs: 3}\n", "train: unknown key 'epochs'; valid: corruptions, steps, severity"),
    ("corruptions: [fog, snow]\ntrain: {corruptions: [snow, dark]}\n",
     "train: snow also built for testing; a held-out protocol trains on other corruptions"),
])
def test_bad_train_sections(tmp_path, text, message):
    from robodepth_cli.building.config import ConfigError, resolve

    path = tmp_path / "p.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        resolve("kitti-c", path)
    assert message in str(info.value)


@pytest.mark.parametrize("variant,level", [("fog:1+gaussian_noise:2.5", None), ("gaussian_noise", 2.5)])
def test_kittic_reads_chains_and_decimal_levels_from_disk_or_on_the_fly(built, variant, level):
    torch = pytest.importorskip("torch")
    from robodepth_cli.torch import KittiC

    _, _, out = built
    disk = KittiC(out, variant, level)
    fly = KittiC(out, variant, level, on_the_fly=True)
    assert len(disk) == len(fly) == 2
    for i in range(2):
        assert torch.equal(disk[i]["image"], fly[i]["image"])
