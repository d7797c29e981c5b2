"""`robodepth stats`: pixel statistics of a build, against values computed here by hand on
tiny images and on the session build's PNGs (read with Pillow), SSIM against its formula."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from PIL import Image

from robodepth_cli.errors import RobodepthError
from robodepth_cli.report import pixels as X
from tests.helpers.messages import one_line_error


def test_histogram_and_moments_by_hand():
    img = np.zeros((2, 4, 3), np.uint8)
    img[..., 0] = [[0, 0, 10, 10], [10, 10, 10, 250]]  # R: two 0s, five 10s, one 250
    img[..., 1] = 7
    img[..., 2] = [[1, 2, 3, 4], [5, 6, 7, 8]]
    h = X.histogram(img)
    assert h.shape == (3, 256) and h.sum(axis=1).tolist() == [8, 8, 8]
    assert (h[0, 0], h[0, 10], h[0, 250]) == (2, 5, 1) and h[1, 7] == 8
    mean, std = X.moments(h)
    r = [0, 0, 10, 10, 10, 10, 10, 250]
    mr = sum(r) / 8  # 37.5
    assert mean.tolist() == pytest.approx([mr, 7.0, 4.5])
    assert std.tolist() == pytest.approx([math.sqrt(sum((v - mr) ** 2 for v in r) / 8), 0.0,
                                          math.sqrt(sum((v - 4.5) ** 2 for v in range(1, 9)) / 8)])


def test_psnr_pools_the_squared_differences():
    assert X.psnr(0.0, 10) is None
    # 12 values off by 5 (MSE 25) and 12 identical: MSE 12.5 over the pair
    assert X.psnr(12 * 25.0, 24) == pytest.approx(10 * math.log10(255 ** 2 / 12.5))


@pytest.mark.parametrize("a,b", [(40, 40), (40, 200), (0, 255), (128, 120)])
def test_ssim_of_flat_images_is_its_luminance_term(a, b):
    """Flat windows have no variance, so SSIM is (2ab + C1) / (a^2 + b^2 + C1), C1 =
    (0.01 * 255)^2 (the contrast-structure term is C2 / C2 = 1)."""
    c1 = (0.01 * 255) ** 2
    x = np.full((9, 11, 3), a, np.uint8)
    y = np.full((9, 11, 3), b, np.uint8)
    assert X.ssim(x, y) == pytest.approx((2 * a * b + c1) / (a * a + b * b + c1), rel=1e-9)


def test_ssim_of_a_textured_pair_by_its_formula():
    """On a 7 x 7 image (one window, uniform weights, sample covariances as scikit-image
    uses by default) SSIM is the formula over the whole image, channel by channel."""
    rng = np.random.default_rng(1)
    x = rng.integers(0, 256, (7, 7, 3), dtype=np.uint8)
    y = np.clip(x.astype(int) + rng.integers(-30, 30, x.shape), 0, 255).astype(np.uint8)
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    per = []
    for c in range(3):
        a, b = x[..., c].astype(float).ravel(), y[..., c].astype(float).ravel()
        ma, mb = a.mean(), b.mean()
        n = a.size
        va, vb = a.var() * n / (n - 1), b.var() * n / (n - 1)
        cov = ((a - ma) * (b - mb)).sum() / (n - 1)
        per.append((2 * ma * mb + c1) * (2 * cov + c2) / ((ma ** 2 + mb ** 2 + c1) * (va + vb + c2)))
    assert X.ssim(x, y) == pytest.approx(sum(per) / 3, rel=1e-9)


@pytest.mark.parametrize("shape", [(7, 7, 3), (9, 11, 3), (64, 96, 3), (375, 1242, 3)])
def test_ssim_is_scikit_images(shape):
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(shape[0])
    x = rng.integers(0, 256, shape, dtype=np.uint8)
    for y in (np.clip(x.astype(int) + rng.integers(-40, 40, shape), 0, 255).astype(np.uint8),
              rng.integers(0, 256, shape, dtype=np.uint8), (x // 2).astype(np.uint8)):
        assert X.ssim(x, y) == pytest.approx(structural_similarity(x, y, channel_axis=2, data_range=255),
                                             rel=1e-12, abs=1e-12)


def test_ssim_of_an_image_under_its_window_refused():
    with pytest.raises(RobodepthError, match="smaller than SSIM's 7x7 window"):
        X.ssim(np.zeros((6, 20, 3), np.uint8), np.zeros((6, 20, 3), np.uint8))


def test_chosen_images_are_spread_over_the_split():
    assert X.chosen(5, None) == [0, 1, 2, 3, 4] and X.chosen(5, 9) == [0, 1, 2, 3, 4]
    assert X.chosen(11, 3) == [0, 5, 10] and X.chosen(100, 1) == [0]


def _pngs(build, relpath):
    from robodepth_cli import open_dataset

    v = next(v for v in open_dataset(build).variants() if v.relpath == relpath)
    return [np.asarray(Image.open(p).convert("RGB")) for p in v.images()]


def test_stats_command_on_a_build(kitti_c_build, tmp_path, cli):
    res = cli("stats", kitti_c_build, "--out", tmp_path / "s", "--level", "1", "--no-progress")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "s" / "stats.json").read_text())
    for ext, magic in (("png", b"\x89PNG"), ("svg", b"<?xml"), ("pdf", b"%PDF")):
        assert (tmp_path / "s" / f"histograms.{ext}").read_bytes().startswith(magic)
    clean = _pngs(kitti_c_build, "clean")
    assert doc["images"] == doc["of"] == 2 and doc["schema"] == "robodepth-stats"
    want = np.stack([sum(np.bincount(im[..., c].ravel(), minlength=256) for im in clean)
                     for c in range(3)])
    assert doc["clean"]["histogram"] == want.tolist()
    assert [(v["corruption"], v["level"]) for v in doc["variants"]] == [
        ("brightness", 1), ("brightness", 3), ("contrast", 1), ("contrast", 3)]
    for v in doc["variants"]:
        imgs = _pngs(kitti_c_build, f"{v['corruption']}/{v['level']}")
        pix = np.concatenate([im.reshape(-1, 3) for im in imgs]).astype(float)
        ref = np.concatenate([im.reshape(-1, 3) for im in clean]).astype(float)
        assert v["mean"] == pytest.approx(pix.mean(axis=0).tolist(), rel=1e-12)
        assert v["mean_shift"] == pytest.approx((pix.mean(axis=0) - ref.mean(axis=0)).tolist(), abs=1e-9)
        assert v["std_ratio"] == pytest.approx((pix.std(axis=0) / ref.std(axis=0)).tolist(), rel=1e-9)
        assert v["psnr"] == pytest.approx(10 * math.log10(255 ** 2 / np.mean((pix - ref) ** 2)), rel=1e-12)
        from skimage.metrics import structural_similarity

        assert v["ssim"] == pytest.approx(np.mean([structural_similarity(c, im, channel_axis=2, data_range=255)
                                                   for c, im in zip(clean, imgs)]), rel=1e-12)
    assert next(v for v in doc["variants"] if v["corruption"] == "brightness" and v["level"] == 3)[
        "mean_shift"][0] > 0  # brighter: a sign that the comparison runs the right way round


def test_stats_reads_each_image_once(kitti_c_build, monkeypatch):
    """Streamed: image by image, each variant's file read once, nothing held between."""
    from robodepth_cli import api, open_dataset

    reads = []
    original = api.Variant.read
    monkeypatch.setattr(api.Variant, "read", lambda self, i: reads.append((self.relpath, i)) or original(self, i))
    ds = open_dataset(kitti_c_build)
    clean, sums = X.collect(ds, None)
    assert sorted(reads) == sorted({(v.relpath, i) for v in ds.variants() for i in range(2)})
    assert clean.images == 2 and all(s.images == 2 for _, s in sums)
    reads.clear()
    X.collect(ds, 1)
    assert {i for _, i in reads} == {0}


def test_stats_refusals(kitti_c_build, tmp_path, cli):
    one_line_error(cli("stats", kitti_c_build, "--out", tmp_path / "s", "--level", "5"),
                   "--level 5: the build has no variant at that level (it has 1, 3)")
    assert not (tmp_path / "s").exists()
    (tmp_path / "f").write_text("")
    one_line_error(cli("stats", kitti_c_build, "--out", tmp_path / "f"), "is a file")
    res = cli("stats", tmp_path, "--out", tmp_path / "s")
    assert res.exit_code == 2 and "Traceback" not in res.output
