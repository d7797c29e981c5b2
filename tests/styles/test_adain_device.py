"""--device auto|cpu|cuda for KITTI-S (`build kitti-s`, `stylize`). This machine has no
GPU: the CPU runs the very code a GPU runs (batched decoding, device moves), and the choice
of device is tested with torch's CUDA queries answered both ways."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image

from tests.helpers.adain import reference_stylize, save_checkpoints, smooth_image
from robodepth_cli.errors import RobodepthError
from robodepth_cli.styles import adain

FRAME = "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


@pytest.fixture(scope="module")
def ckpt(tmp_path_factory):
    return save_checkpoints(tmp_path_factory.mktemp("ckpt"), seed=3)


@pytest.fixture()
def no_cuda(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)


def test_choose_device(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert adain.choose_device("cpu") == adain.choose_device("auto") == torch.device("cpu")
    with pytest.raises(RobodepthError, match=r"^--device cuda: no CUDA device \(.*\); use --device cpu or auto$"):
        adain.choose_device("cuda")
    with pytest.raises(RobodepthError, match="expected one of auto, cpu, cuda, got 'gpu'"):
        adain.choose_device("gpu")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "current_device", lambda: 1)
    assert adain.choose_device("auto") == adain.choose_device("cuda") == torch.device("cuda", 1)
    assert adain.choose_device("cpu") == torch.device("cpu")


@pytest.mark.slow
def test_gpu_batching_gives_the_cpu_bytes(ckpt):
    """All styles in one batch (as on a GPU) against one at a time (the CPU default), on
    the CPU: the same bytes, and each within one level of the per-pair reference."""
    vgg_path, dec_path, vgg, dec = ckpt
    rng = np.random.default_rng(5)
    content = smooth_image(rng, 64, 96)
    styles = [smooth_image(rng, 48, 48) for _ in range(5)]
    one = adain.Stylizer.from_files(vgg_path, dec_path, device="cpu")
    batched = adain.Stylizer.from_files(vgg_path, dec_path, device="cpu", chunk=adain.GPU_CHUNK)
    assert (one.chunk, batched.chunk) == (adain.DEFAULT_CHUNK, adain.GPU_CHUNK)
    feats = [one.style_features(s) for s in styles]
    assert all(f.mean.device.type == "cpu" for f in feats)  # can be sent to workers
    a, b = one.stylize(content, feats), batched.stylize(content, feats)
    for x, y, style in zip(a, b, styles):
        assert np.array_equal(x, y)
        assert np.abs(x.astype(int) - reference_stylize(vgg, dec, content, style).astype(int)).max() <= 1


def test_stylize_device(tmp_path, fixtures_dir, ckpt, cli, no_cuda):
    vgg_path, dec_path, _, _ = ckpt
    args = [fixtures_dir / FRAME, "--style", fixtures_dir / "styles" / "sketch.png", "--vgg", vgg_path,
            "--decoder", dec_path, "--size", "32x96", "--style-size", "32"]
    r = cli("stylize", *args, "--out", tmp_path / "auto.png")
    assert r.exit_code == 0 and "AdaIN on the CPU" in r.output, r.output
    r = cli("stylize", *args, "--device", "cpu", "--out", tmp_path / "cpu.png")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "auto.png").read_bytes() == (tmp_path / "cpu.png").read_bytes()
    r = cli("stylize", *args, "--device", "cuda", "--out", tmp_path / "cuda.png")
    assert r.exit_code == 2
    assert r.output.startswith("robodepth: error: --device cuda: no CUDA device")
    assert len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "cuda.png").exists()


def _kitti_s(fixtures_dir, ckpt, out, *more):
    vgg_path, dec_path, _, _ = ckpt
    return ["build", "kitti-s", "--root", fixtures_dir / "kitti_raw", "--split", fixtures_dir / "kitti_split.txt",
            "--styles", fixtures_dir / "styles", "--vgg", vgg_path, "--decoder", dec_path,
            "--size", "32x96", "--style-size", "32", "--only-styles", "sketch,murals", "--jobs", "1",
            "--out", out, *more]


def test_build_kitti_s_device(tmp_path, fixtures_dir, ckpt, cli, no_cuda):
    r = cli(*_kitti_s(fixtures_dir, ckpt, tmp_path / "auto"))
    assert r.exit_code == 0, r.output
    assert "kitti-s: AdaIN on the CPU (no CUDA device) (--device auto)" in r.output
    r = cli(*_kitti_s(fixtures_dir, ckpt, tmp_path / "cpu", "--device", "cpu"))
    assert r.exit_code == 0 and "AdaIN on the CPU (--device cpu)" in r.output, r.output
    pngs = sorted(p.relative_to(tmp_path / "cpu") for p in (tmp_path / "cpu").rglob("*.png"))
    assert len(pngs) == 6
    for p in pngs:
        a, b = Image.open(tmp_path / "auto" / p), Image.open(tmp_path / "cpu" / p)
        assert np.array_equal(np.asarray(a), np.asarray(b)), p

    r = cli(*_kitti_s(fixtures_dir, ckpt, tmp_path / "cuda", "--device", "cuda"))
    assert r.exit_code == 2
    assert r.output.startswith("robodepth: error: --device cuda: no CUDA device")
    assert len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "cuda").exists()

    r = cli(*_kitti_s(fixtures_dir, ckpt, tmp_path / "bad", "--device", "gpu"))
    assert r.exit_code == 2 and "--device: expected one of auto, cpu, cuda, got 'gpu'" in r.output
    # kitti-c takes --device for its torch engine; the numpy engine has no GPU path.
    r = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split", fixtures_dir / "kitti_split.txt",
            "--out", tmp_path / "c", "--device", "cuda")
    assert r.exit_code == 2 and "--device: cuda needs --engine torch" in r.output, r.output
    assert not (tmp_path / "c").exists()
