"""KITTI-S around the engine: style directory, `robodepth stylize`, lazy torch import."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
import torch
from PIL import Image

from tests.helpers.adain import reference_stylize, save_checkpoints, smooth_image
from tests.helpers.paths import REPO
from robodepth_cli.styles import inputs as styles
from robodepth_cli.imageio import load_clean

FRAME = "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


@pytest.fixture(scope="module")
def ckpt(tmp_path_factory):
    return save_checkpoints(tmp_path_factory.mktemp("ckpt"), seed=7)


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


def test_stylize_command_matches_reference(tmp_path, fixtures_dir, ckpt, cli):
    vgg_path, dec_path, vgg, dec = ckpt
    style = fixtures_dir / "styles" / "ink_painting.png"
    out = tmp_path / "o.png"
    r = cli("stylize", fixtures_dir / FRAME, "--style", style, "--vgg", vgg_path,
            "--decoder", dec_path, "--size", "44x150", "--style-size", "64",
            "--alpha", "0.8", "--out", out)
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
    ({"--vgg": "none.pth"}, "none.pth: no such file"),
    ({"--alpha": "1.5"}, "--alpha: alpha must be between 0 and 1"),
    ({"--style-size": "8"}, "--style-size: style size must be 0"),
    ({"--out": "o.jpg"}, "give a .png file name"),
    ({"--decoder": "VGG"}, "this is the AdaIN vgg checkpoint, not the decoder one"),
    ({"--vgg": "BROKEN"}, "broken.pth: missing tensor '29.weight'"),
])
def test_stylize_refuses_bad_input(tmp_path, fixtures_dir, ckpt, change, message, cli):
    vgg_path, dec_path, vgg, _ = ckpt
    state = {k: v for k, v in vgg.state_dict().items() if k != "29.weight"}
    torch.save(state, tmp_path / "broken.pth")
    named = {"VGG": vgg_path, "BROKEN": tmp_path / "broken.pth"}
    opts = {"--style": fixtures_dir / "styles" / "sketch.png", "--vgg": vgg_path,
            "--decoder": dec_path, "--out": tmp_path / "o.png", "--style-size": "32"}
    for k, v in change.items():
        opts[k] = named.get(v, tmp_path / v if k in ("--style", "--vgg", "--out") else v)
    r = cli("stylize", fixtures_dir / FRAME, "--size", "32x96", *[x for kv in opts.items() for x in kv])
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
        from robodepth_cli.building import pipeline, config  # noqa: F401
        from robodepth_cli.sources import datasets  # noqa: F401
        from robodepth_cli.styles import inputs  # noqa: F401
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


# ------------------------------------------------------------------ kitti-s build


@pytest.fixture()
def build_kitti_s(cli):
    """``build_kitti_s(args)``: ``robodepth build kitti-s ARGS...``."""
    return lambda args: cli("build", "kitti-s", *args)


@pytest.fixture()
def kitti_s_args(fixtures_dir, ckpt):
    vgg_path, dec_path, _, _ = ckpt
    return ["--root", fixtures_dir / "kitti_raw", "--split", fixtures_dir / "kitti_split.txt",
            "--styles", fixtures_dir / "styles", "--vgg", vgg_path, "--decoder", dec_path,
            "--size", "48x160", "--style-size", "64"]


def _tree(out):
    return {p.relative_to(out).as_posix(): p.read_bytes()
            for p in sorted(out.rglob("*.png"))}


@pytest.mark.slow
def test_kitti_s_build_layout_pixels_resume_and_workers(tmp_path, fixtures_dir, ckpt, kitti_s_args, cli,
                                                        build_kitti_s):
    _, _, vgg, dec = ckpt
    chosen = ["sketch", "cartoon", "murals"]
    out1, out2 = tmp_path / "one", tmp_path / "two"
    r = build_kitti_s(kitti_s_args + ["--only-styles", ",".join(chosen), "--jobs", "1", "--out", out1])
    assert r.exit_code == 0, r.output
    files = _tree(out1)
    keys = [f"kitti_data/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/{f}.png"
            for f in ("0000000069", "0000000054")]
    assert set(files) == {f"{v}/{k}" for v in ["clean"] + chosen for k in keys}
    # Each output is the AdaIN stylisation of the resized clean image.
    for k, frame in zip(keys, ("0000000069", "0000000054")):
        clean = load_clean(fixtures_dir / FRAME.replace("0000000069", frame), (48, 160))
        assert np.array_equal(np.asarray(Image.open(out1 / "clean" / k)), clean)
        for style in chosen:
            style_img = np.asarray(Image.open(fixtures_dir / "styles" / f"{style}.png")
                                   .convert("RGB").resize((64, 64), Image.BILINEAR))
            ref = reference_stylize(vgg, dec, clean, style_img)
            got = np.asarray(Image.open(out1 / style / k))
            assert np.abs(got.astype(int) - ref.astype(int)).max() <= 1
    rows = (out1 / "manifest.csv").read_text().splitlines()
    assert len(rows) == 1 + len(files) and all(",," in row for row in rows[1:])  # no level
    assert cli("verify", out1).exit_code == 0
    # Two workers (one torch thread each) write the same bytes.
    r = build_kitti_s(kitti_s_args + ["--only-styles", ",".join(chosen), "--jobs", "2", "--out", out2])
    assert r.exit_code == 0, r.output
    assert _tree(out2) == files
    # A rerun has nothing to do.
    r = build_kitti_s(kitti_s_args + ["--only-styles", ",".join(chosen), "--out", out1])
    assert r.exit_code == 0 and "0 written, 8 skipped" in r.output


def test_kitti_s_rebuild_redoes_a_style_whose_inputs_changed(tmp_path, fixtures_dir, kitti_s_args, cli,
                                                             build_kitti_s):
    """Seed and size do not decide a stylised image: the checkpoints, the style image, alpha
    and the style size do, and a rebuild after any of them changed must not keep old pixels."""
    import shutil

    styles = tmp_path / "styles"
    shutil.copytree(fixtures_dir / "styles", styles)
    opts = dict(zip(kitti_s_args[::2], kitti_s_args[1::2]))
    opts["--styles"] = styles
    base = [x for kv in opts.items() for x in kv] + ["--only-styles", "sketch,murals", "--limit", "1",
                                                     "--out", tmp_path / "out"]
    assert build_kitti_s(base).exit_code == 0
    first = _tree(tmp_path / "out")

    r = build_kitti_s(base + ["--alpha", "0.5"])
    assert r.exit_code == 0 and "2 written, 1 skipped" in r.output, r.output
    half = _tree(tmp_path / "out")
    assert [k for k in first if first[k] != half[k]] == [k for k in first if not k.startswith("clean/")]

    r = build_kitti_s(base + ["--alpha", "0.5"])
    assert "0 written, 3 skipped" in r.output, r.output

    Image.open(styles / "sketch.png").transpose(Image.FLIP_LEFT_RIGHT).save(styles / "sketch.png")
    r = build_kitti_s(base + ["--alpha", "0.5"])
    assert r.exit_code == 0 and "1 written, 2 skipped" in r.output, r.output
    assert cli("verify", tmp_path / "out").exit_code == 0


@pytest.mark.parametrize("flag,value,message", [
    ("--only-styles", "sketch,comic", "--only-styles: unknown style 'comic'; valid: cartoon"),
    ("--styles", "EMPTY", "no image for style(s) cartoon, digital_art"),
    ("--vgg", None, "kitti-s needs --vgg vgg_normalised.pth"),
    ("--decoder", "VGG", "this is the AdaIN vgg checkpoint, not the decoder one"),
    ("--alpha", "2", "--alpha: alpha must be between 0 and 1"),
    ("--styles", "ABSENT", "the style directory does not exist"),
])
def test_kitti_s_problems_stop_before_any_work(tmp_path, ckpt, kitti_s_args, flag, value, message,
                                               build_kitti_s):
    (tmp_path / "empty").mkdir()
    named = {"EMPTY": tmp_path / "empty", "ABSENT": tmp_path / "absent", "VGG": ckpt[0]}
    opts = dict(zip(kitti_s_args[::2], kitti_s_args[1::2]))
    opts[flag] = named.get(value, value)
    args = [x for k, v in opts.items() if v is not None for x in (k, v)]
    r = build_kitti_s(args + ["--out", tmp_path / "out"])
    assert r.exit_code == 2, r.output
    assert message in r.output and "Traceback" not in r.output
    assert not (tmp_path / "out").exists()
