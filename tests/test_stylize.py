"""KITTI-S around the engine: style directory, `robodepth stylize`, lazy torch import."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
import torch
from click.testing import CliRunner
from PIL import Image

from adain_fakes import reference_stylize, save_checkpoints, smooth_image
from conftest import REPO
from robodepth_cli import styles
from robodepth_cli.cli import main
from robodepth_cli.imageio import load_clean

FRAME = "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


@pytest.fixture(scope="module")
def ckpt(tmp_path_factory):
    return save_checkpoints(tmp_path_factory.mktemp("ckpt"), seed=7)


def _run(args):
    return CliRunner().invoke(main, [str(a) for a in args])


# ---------------------------------------------------------------- style directory


def test_fixture_style_directory_has_every_style(fixtures_dir):
    found = styles.find_style_images(fixtures_dir / "styles")
    assert list(found) == list(styles.STYLES) and len(found) == 12
    assert all(p.name == f"{name}.png" for name, p in found.items())


def test_style_directory_problems_are_named(tmp_path):
    d = tmp_path / "styles"
    d.mkdir()
    img = Image.fromarray(smooth_image(np.random.default_rng(0), 40, 40))
    img.save(d / "cartoon.JPG", quality=90)
    img.save(d / "sketch.png")
    (d / "notes.txt").write_text("ignored")
    assert styles.find_style_images(d, ["sketch", "cartoon"]) == \
        {"sketch": d / "sketch.png", "cartoon": d / "cartoon.JPG"}
    with pytest.raises(styles.StyleError) as err:
        styles.find_style_images(d)
    msg = str(err.value)
    assert str(d) in msg and "digital_art" in msg and "water_color" in msg
    assert "cartoon," not in msg.split("no image for style(s)")[1].split(";")[0]
    with pytest.raises(styles.StyleError, match="unknown style 'comic'; valid: cartoon"):
        styles.find_style_images(d, ["comic"])
    img.save(d / "sketch.jpeg")
    with pytest.raises(styles.StyleError, match="several images for style 'sketch'"):
        styles.find_style_images(d, ["sketch"])
    with pytest.raises(styles.StyleError, match="does not exist"):
        styles.find_style_images(tmp_path / "absent")


# ------------------------------------------------------------------- stylize CLI


def test_stylize_command_matches_reference(tmp_path, fixtures_dir, ckpt):
    vgg_path, dec_path, vgg, dec = ckpt
    style = fixtures_dir / "styles" / "ink_painting.png"
    out = tmp_path / "o.png"
    r = _run(["stylize", fixtures_dir / FRAME, "--style", style, "--vgg", vgg_path,
              "--decoder", dec_path, "--size", "44x150", "--style-size", "64",
              "--alpha", "0.8", "--out", out])
    assert r.exit_code == 0, r.output
    got = np.asarray(Image.open(out))
    content = load_clean(fixtures_dir / FRAME, (44, 150))  # not divisible by 8: cropped
    style_img = np.asarray(Image.open(style).convert("RGB").resize((64, 64), Image.BILINEAR))
    ref = reference_stylize(vgg, dec, content, style_img, alpha=0.8)
    assert got.shape == (44, 150, 3)
    assert np.abs(got.astype(int) - ref.astype(int)).max() <= 1
    assert ((ref > 0) & (ref < 255)).mean() > 0.9  # not a trivially saturated comparison


@pytest.mark.parametrize("change,message", [
    ({"--style": "missing.png"}, "missing.png: no such file"),
    ({"--vgg": "none.pth"}, "none.pth: no such file (--vgg)"),
    ({"--alpha": "1.5"}, "--alpha: alpha must be between 0 and 1"),
    ({"--style-size": "8"}, "--style-size: style size must be 0"),
    ({"--out": "o.jpg"}, "give a .png file name"),
    ({"--decoder": "VGG"}, "this is the AdaIN vgg checkpoint, not the decoder one"),
    ({"--vgg": "BROKEN"}, "broken.pth: missing tensor '29.weight'"),
])
def test_stylize_refuses_bad_input(tmp_path, fixtures_dir, ckpt, change, message):
    vgg_path, dec_path, vgg, _ = ckpt
    state = {k: v for k, v in vgg.state_dict().items() if k != "29.weight"}
    torch.save(state, tmp_path / "broken.pth")
    named = {"VGG": vgg_path, "BROKEN": tmp_path / "broken.pth"}
    opts = {"--style": fixtures_dir / "styles" / "sketch.png", "--vgg": vgg_path,
            "--decoder": dec_path, "--out": tmp_path / "o.png", "--style-size": "32"}
    for k, v in change.items():
        opts[k] = named.get(v, tmp_path / v if k in ("--style", "--vgg", "--out") else v)
    r = _run(["stylize", fixtures_dir / FRAME, "--size", "32x96"] + [x for kv in opts.items() for x in kv])
    assert r.exit_code == 2
    assert message in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "o.png").exists() and not (tmp_path / "o.jpg").exists()


# ------------------------------------------------------------ torch stays unloaded


def test_help_and_kitti_c_build_do_not_import_torch(tmp_path, fixtures_dir):
    script = textwrap.dedent(f"""
        import sys
        from click.testing import CliRunner
        from robodepth_cli.cli import main
        r = CliRunner().invoke(main, ["--help"])
        assert r.exit_code == 0, r.output
        from robodepth_cli import builder, config, datasets, styles  # noqa: F401
        r = CliRunner().invoke(main, ["build", "kitti-c", "--root", {str(fixtures_dir / 'kitti_raw')!r},
                                      "--split", {str(fixtures_dir / 'kitti_split.txt')!r},
                                      "--out", {str(tmp_path / 'out')!r}, "--corruptions", "contrast",
                                      "--levels", "1", "--limit", "1", "--jobs", "1", "--no-progress"])
        assert r.exit_code == 0, r.output
        print("torch" in sys.modules)
    """)
    res = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "False"
    assert (tmp_path / "out" / "contrast" / "1").is_dir()
