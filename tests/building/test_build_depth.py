"""`robodepth build custom --depth`: each image's depth map beside it in OUT/gt/, at its own
size, covered by verify, evaluated and scored (the loop on a folder of your own)."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from tests.helpers.depth_files import png16
from tests.helpers.manifest import manifest_by_output
from tests.helpers.trees import random_image, save

H, W = 48, 64




def _depth(seed):
    d = np.random.default_rng(seed).uniform(1.0, 20.0, (H, W)).astype(np.float32)
    d[:3, :7] = 0  # no measurement
    return d


@pytest.fixture
def folder(tmp_path):
    """Two images in two folders, each with a float .npy depth map in metres under depth/."""
    maps = {}
    for i, rel in enumerate(["street/a", "park/b"]):
        save(tmp_path / "img" / f"{rel}.jpg", random_image(H, W, seed=i))
        maps[rel] = _depth(i)
        (tmp_path / "depth" / rel).parent.mkdir(parents=True, exist_ok=True)
        np.save(tmp_path / "depth" / f"{rel}.npy", maps[rel])
    return tmp_path, maps


def _build(cli, tmp_path, *flags):
    return cli("build", "custom", "--root", tmp_path / "img", "--out", tmp_path / "out",
               "--corruptions", "fog,gaussian_noise", "--levels", "1,2", "--jobs", 1, *flags)


def test_depth_beside_the_images_verified(folder, cli):
    tmp_path, maps = folder
    res = _build(cli, tmp_path, "--depth", tmp_path / "depth")
    assert res.exit_code == 0, res.output
    out = tmp_path / "out"
    for rel, d in maps.items():
        gt = np.load(out / "gt" / f"{rel}.npy")
        want = d.copy()
        want[:3, :7] = np.nan  # 0 is "no depth"
        np.testing.assert_array_equal(gt, want)
        row = manifest_by_output(out)[f"gt/{rel}.npy"]
        assert (row["variant"], row["height"], row["width"], row["error"]) == ("gt", "48", "64", "")
    assert cli("verify", out).exit_code == 0
    res = _build(cli, tmp_path, "--depth", tmp_path / "depth")  # a rerun has nothing to do
    assert res.exit_code == 0 and "0 written" in res.output
    np.save(tmp_path / "depth" / "park" / "b.npy", maps["park/b"] * 2)  # a changed map is redone
    res = _build(cli, tmp_path, "--depth", tmp_path / "depth")
    assert res.exit_code == 0 and "1 written" in res.output
    assert np.nanmax(np.load(out / "gt" / "park" / "b.npy")) == np.max(maps["park/b"] * 2)
    np.save(out / "gt" / "park" / "b.npy", np.ones((H, W), np.float32))
    res = cli("verify", out)
    assert res.exit_code == 1 and "gt/park/b.npy" in res.output


def test_png_pattern_scale_and_mask_at_own_size(tmp_path, cli):
    save(tmp_path / "img" / "x" / "f_left.png", random_image(H, W, seed=3))
    raw = np.full((H // 2, W // 2), 512, np.uint16)
    raw[0, 0] = 0
    png16(tmp_path / "gtd" / "x" / "f_left_depth.png", raw)
    mask = np.ones((H // 2, W // 2), np.uint16)
    mask[1, 1] = 0
    png16(tmp_path / "gtd" / "x" / "f_left_valid.png", mask)
    flags = ("--depth", tmp_path / "gtd", "--depth-pattern", "{dir}/{stem}_depth.png",
             "--depth-mask", "{parts[0]}/{stem}_valid.png", "--depth-scale", 256)
    res = _build(cli, tmp_path, *flags)
    assert res.exit_code == 1, res.output  # a 24 x 32 map for a 48 x 64 image
    assert "depth map of 24 x 32, its image x/f_left.png is 48 x 64" in res.output
    res = _build(cli, tmp_path, *flags, "--depth-size", "any")
    assert res.exit_code == 0, res.output
    gt = np.load(tmp_path / "out" / "gt" / "x" / "f_left.npy")
    assert gt.shape == (24, 32)  # never resized
    assert np.isnan(gt[0, 0]) and np.isnan(gt[1, 1])
    assert gt[5, 5] == 2.0  # 512 / 256


def test_missing_invalid_and_unreadable_maps_are_listed(folder, cli):
    tmp_path, _ = folder
    save(tmp_path / "img" / "park" / "c.png", random_image(H, W, seed=9))  # no depth at all
    save(tmp_path / "img" / "park" / "d.png", random_image(H, W, seed=9))
    np.save(tmp_path / "depth" / "park" / "d.npy", np.zeros((H, W), np.float32))
    save(tmp_path / "img" / "park" / "e.png", random_image(H, W, seed=9))
    (tmp_path / "depth" / "park" / "e.npy").write_bytes(b"broken")
    res = _build(cli, tmp_path, "--depth", tmp_path / "depth")
    assert res.exit_code == 1
    rows = manifest_by_output(tmp_path / "out")
    assert "no depth file" in rows["gt/park/c.npy"]["error"]
    assert "no valid depth" in rows["gt/park/d.npy"]["error"]
    assert "not a depth array" in rows["gt/park/e.npy"]["error"]
    assert rows["gt/park/b.npy"]["error"] == rows["gt/street/a.npy"]["error"] == ""
    res = cli("verify", tmp_path / "out")
    assert "no depth file" in res.output


def test_refused_before_any_work(folder, cli):
    tmp_path, _ = folder
    res = _build(cli, tmp_path, "--depth", tmp_path / "nowhere")
    assert res.exit_code == 2 and "the depth directory (--depth) does not exist" in res.output
    assert not (tmp_path / "out").exists()
    res = _build(cli, tmp_path, "--depth", tmp_path / "depth", "--depth-pattern", "{dir}/{colour}.npy")
    assert res.exit_code == 2 and "unknown field {colour}" in res.output
    res = _build(cli, tmp_path, "--depth", tmp_path / "depth", "--depth-scale", "-3")
    assert res.exit_code == 2 and "--depth-scale" in res.output


def test_a_scale_on_float_depth_is_refused_before_any_work(folder, cli):
    # Float maps are metres: a scale is refused, never applied. Integer maps need one.
    tmp_path, maps = folder
    out = tmp_path / "out"
    res = _build(cli, tmp_path, "--depth", tmp_path / "depth", "--depth-scale", "100")
    assert res.exit_code == 2 and "float depth values are metres" in res.output, res.output
    assert "--depth-scale" in res.output and not out.exists()


def test_16_bit_depth_without_a_scale_is_refused_before_any_work(folder, cli):
    tmp_path, maps = folder
    out = tmp_path / "out"
    for rel, d in maps.items():
        png16(tmp_path / "d16" / f"{rel}.png", np.round(d * 256).astype(np.uint16))
    res = _build(cli, tmp_path, "--depth", tmp_path / "d16")
    assert res.exit_code == 2 and "integer depth values need a scale, --depth-scale" in res.output, res.output
    assert res.output.count("\n") == 1 and not out.exists()
    res = _build(cli, tmp_path, "--depth", tmp_path / "d16", "--depth-scale", "256")
    assert res.exit_code == 0, res.output
    np.testing.assert_allclose(np.load(out / "gt" / "street" / "a.npy")[5:, 8:], maps["street/a"][5:, 8:],
                               atol=1 / 512)


MODEL = '''
import numpy as np

def two_metres(images):
    return np.full(images.shape[:3], 2.0, np.float32)
'''


def test_evaluate_and_score_with_and_without_a_baseline(folder, cli, monkeypatch):
    tmp_path, maps = folder
    assert _build(cli, tmp_path, "--depth", tmp_path / "depth").exit_code == 0
    (tmp_path / "m.py").write_text(MODEL)
    out, pred = tmp_path / "out", tmp_path / "P"
    res = cli("predict", out, "-m", f"python:{tmp_path / 'm.py'}:two_metres", "--kind", "depth",
              "--metric", "-o", pred)
    assert res.exit_code == 0, res.output
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--max-depth", 15)
    assert res.exit_code == 0, res.output
    # By hand: valid pixels 0.001 < gt < 15 (no crop on a custom build); abs_rel and
    # delta1 of the constant 2 m, averaged over the two images (clean images first in key order).
    abs_rel, a1 = [], []
    for rel in ("park/b", "street/a"):
        g = maps[rel][(maps[rel] > 0.001) & (maps[rel] < 15)].astype(np.float64)
        abs_rel.append(np.mean(np.abs(g - 2) / g))
        a1.append(np.mean(np.maximum(g / 2, 2 / g) < 1.25))
    with open(tmp_path / "r.csv", newline="") as fh:
        rows = {(r["corruption"], r["level"]): r for r in csv.DictReader(fh)}
    for key in [("clean", "0"), ("fog", "2")]:  # the prediction ignores the image
        assert float(rows[key]["abs_rel"]) == pytest.approx(np.mean(abs_rel), rel=1e-5)
        assert float(rows[key]["a1"]) == pytest.approx(np.mean(a1), rel=1e-6)
    # Worker processes read the maps themselves: the same numbers to the last digit.
    monkeypatch.setattr("robodepth_cli.evaluation.evaluate.MAPS_PER_WORKER", 1)
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r2.csv", "--max-depth", 15,
              "--jobs", 2)
    assert res.exit_code == 0, res.output
    assert (tmp_path / "r2.csv").read_bytes() == (tmp_path / "r.csv").read_bytes()
    res = cli("score", tmp_path / "r.csv", "--benchmark", "custom")
    assert res.exit_code == 0, res.output
    assert "baseline: none" in res.output and "mCE n/a" in res.output and "mRR 100.00" in res.output
    res = cli("score", tmp_path / "r.csv", "--benchmark", "custom", "--baseline", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    assert "mCE 100.00" in res.output
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r3.csv", "--score")
    assert res.exit_code == 0, res.output
    assert "mCE n/a" in res.output


def test_depth_of_is_where_a_builds_depth_comes_from(folder):
    from robodepth_cli.sources.datasets import Options
    from robodepth_cli.sources.depth_pairs import depth_of

    tmp_path, maps = folder
    got = depth_of(Options(depth=str(tmp_path / "depth")), tmp_path / "img", False, "street/a.jpg")
    assert np.isnan(got[0, 0]) and got[10, 10] == maps["street/a"][10, 10]
    assert depth_of(Options(), tmp_path / "img", False, "street/a.jpg") is None  # no --depth


def test_a_depth_folder_inside_the_root_is_not_searched_for_images(tmp_path, cli):
    save(tmp_path / "data" / "a.png", random_image(H, W, seed=1))
    png16(tmp_path / "data" / "depth" / "a.png", np.full((H, W), 1000, np.uint16))
    res = cli("build", "custom", "--root", tmp_path / "data", "--depth", tmp_path / "data" / "depth",
              "--depth-scale", 1000, "--out", tmp_path / "out", "--corruptions", "fog", "--levels", 1)
    assert res.exit_code == 0, res.output
    assert [p.relative_to(tmp_path / "out").as_posix() for p in (tmp_path / "out").rglob("*.png")
            if "clean" in p.parts] == ["clean/a.png"]
    assert np.all(np.load(tmp_path / "out" / "gt" / "a.npy") == 1.0)
