"""Single-image commands (corrupt, preview, score --plot, stylize): what --out means, which
inputs are read how, and what is printed."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from robodepth_cli.corruptions import corrupt
from robodepth_cli.imageio import ImageError, read_rgb
from robodepth_cli.seeding import job_rng

from tests.helpers.drawkey import pixels_key
from tests.helpers.messages import one_line_error



def image(tmp_path, name="img.png", size=(48, 64), seed=3):
    rng = np.random.default_rng(seed)
    path = tmp_path / name
    Image.fromarray(rng.integers(0, 256, (*size, 3), dtype=np.uint8)).save(path)
    return path


def files_under(d):
    return sorted(p.relative_to(d).as_posix() for p in d.rglob("*") if p.is_file())


def results_csv(tmp_path):
    from robodepth_cli.corruptions import NAMES

    rows = ["corruption,level,dee", "clean,0,0.1"]
    rows += [f"{n},{lv},0.2" for n in NAMES for lv in range(1, 6)]
    path = tmp_path / "model.csv"
    path.write_text("\n".join(rows) + "\n")
    return path


# --- --out ending with a separator is a directory ------------------------------------------

def test_corrupt_one_level_into_a_directory(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    src = image(tmp_path)
    res = cli("corrupt", src, "-c", "contrast", "-l", "2", "--out", "shots/")
    assert res.exit_code == 0, res.output
    assert files_under(tmp_path / "shots") == ["contrast/2.png"]
    # Height x width, as --size takes it.
    assert res.output.strip() == "wrote shots/contrast/2.png (48x64, HxW)"


def test_preview_into_a_directory(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    src = image(tmp_path, "frame.png")
    res = cli("preview", src, "-c", "contrast", "--thumb-width", "32", "--out", "sheets/")
    assert res.exit_code == 0, res.output
    assert files_under(tmp_path / "sheets") == ["frame_preview.png"]
    with Image.open(tmp_path / "sheets/frame_preview.png") as sheet:
        h, w = sheet.height, sheet.width
    assert h != w and res.output.strip() == f"wrote sheets/frame_preview.png ({h}x{w}, HxW)"
    # An existing directory without the separator means the same.
    assert cli("preview", src, "-c", "contrast", "--out", "sheets").exit_code == 0


def test_score_plot_into_a_directory(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = cli("score", results_csv(tmp_path), "-b", "kitti-c", "--plot", "plots/")
    assert res.exit_code == 0, res.output
    assert files_under(tmp_path / "plots") == ["model_ce.png"]
    assert Image.open(tmp_path / "plots" / "model_ce.png").format == "PNG"


def test_file_like_out_for_several_levels_is_refused(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = cli("corrupt", image(tmp_path), "-c", "fog", "--out", "fog.png")
    one_line_error(res, "--out fog.png: looks like a file name", "fog at levels 1,2,3,4,5",
                   "-c NAME -l N", "end the name with /")
    assert not (tmp_path / "fog.png").exists()
    # Without an extension it is a directory, as before.
    res = cli("corrupt", image(tmp_path), "-c", "contrast", "-l", "1,2", "--out", "contrasts")
    assert res.exit_code == 0, res.output
    assert files_under(tmp_path / "contrasts") == ["contrast/1.png", "contrast/2.png"]
    assert res.output.strip() == "wrote 2 images under contrasts"


@pytest.mark.parametrize("command", [
    ["corrupt", "-c", "contrast", "-l", "2"],
    ["preview", "-c", "contrast"],
])
@pytest.mark.parametrize("name", ["out.jpg", "out.JPEG", "out"])
def test_output_that_is_not_png_is_refused(cli, tmp_path, monkeypatch, command, name):
    monkeypatch.chdir(tmp_path)
    res = cli(command[0], image(tmp_path), *command[1:], "--out", name)
    one_line_error(res, f"--out {name}: the output is written as PNG; give a .png file name")
    assert not (tmp_path / name).exists()


def test_plot_that_is_not_png_svg_or_pdf_is_refused(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = cli("score", results_csv(tmp_path), "-b", "kitti-c", "--plot", "ce.jpg")
    one_line_error(res, "--plot ce.jpg: give a .png, .svg or .pdf file name")
    assert not (tmp_path / "ce.jpg").exists()


# --- inputs ---------------------------------------------------------------------------------

def test_float_tiff_in_0_1_is_scaled_to_0_255(cli, tmp_path):
    rng = np.random.default_rng(0)
    values = rng.random((40, 50)).astype(np.float32)
    values[0, 0], values[0, 1] = 0.0, 1.0
    path = tmp_path / "depthlike.tif"
    Image.fromarray(values, "F").save(path)
    got = np.asarray(read_rgb(path))
    expected = np.rint(values.astype(np.float64) * 255).astype(np.uint8)  # nearest integer
    assert got.shape == (40, 50, 3)
    assert np.array_equal(got[..., 0], expected) and np.array_equal(got[..., 2], expected)
    # The command line reads it the same way (it came out all black before).
    out = tmp_path / "o.png"
    res = cli("corrupt", path, "-c", "color_quant", "-l", "1", "--out", out)
    assert res.exit_code == 0, res.output
    assert np.array_equal(np.asarray(Image.open(out))[..., 1], expected & 0b11111000)


@pytest.mark.parametrize("values, problem", [
    (np.full((40, 50), 200.0, np.float32), "float pixels range over [200, 200]; only floats in 0..1"),
    (np.full((40, 50), -0.5, np.float32), "float pixels range over [-0.5, -0.5]"),
    (np.full((40, 50), np.nan, np.float32), "float pixels include NaN or infinity"),
])
def test_float_tiff_in_other_ranges_is_refused(cli, tmp_path, values, problem):
    path = tmp_path / "f.tif"
    Image.fromarray(values, "F").save(path)
    with pytest.raises(ImageError) as err:
        read_rgb(path)
    assert str(err.value).startswith(f"{path}: {problem}")
    res = cli("corrupt", path, "-c", "contrast", "-l", "1", "--out", tmp_path / "o.png")
    one_line_error(res, f"{path}: {problem}")


def test_exif_orientation_is_applied_to_single_images(cli, tmp_path):
    # Stored 64 wide x 48 high, tagged "rotate 90 clockwise to display" (orientation 6).
    stored = np.zeros((48, 64, 3), np.uint8)
    stored[:, :8] = 255  # a white band on the stored image's left edge
    exif = Image.Exif()
    exif[0x0112] = 6
    path = tmp_path / "phone.jpg"
    Image.fromarray(stored).save(path, exif=exif, quality=95)
    out = tmp_path / "o.png"
    res = cli("corrupt", path, "-c", "color_quant", "-l", "1", "--out", out)
    assert res.exit_code == 0, res.output
    shown = np.asarray(Image.open(out))
    assert shown.shape == (64, 48, 3)  # displayed upright: 48 wide, 64 high
    assert shown[:8, :, 0].mean() > 200 and shown[-8:, :, 0].mean() < 50  # band now on top
    # A build reads its benchmark sources as stored (they carry no tag).
    assert np.asarray(read_rgb(path)).shape == (48, 64, 3)


# --- what is printed; seeds -----------------------------------------------------------------

def test_single_corrupt_says_what_it_wrote(cli, tmp_path):
    out = tmp_path / "z.png"
    res = cli("corrupt", image(tmp_path), "-c", "contrast", "-l", "3", "--out", out)
    assert res.exit_code == 0
    assert res.output.strip() == f"wrote {out} (48x64, HxW)"


@pytest.mark.parametrize("command", [
    ["corrupt", "IMG", "-c", "contrast", "-l", "1", "-s", "-1", "--out", "o.png"],
    ["preview", "IMG", "-c", "contrast", "-s", "-1", "--out", "o.png"],
])
def test_negative_seed_is_refused_as_build_refuses_it(cli, tmp_path, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    src = image(tmp_path)
    res = cli(*[src if a == "IMG" else a for a in command])
    one_line_error(res, "--seed: expected an integer >= 0, got -1")
    assert not (tmp_path / "o.png").exists()
    build = cli("build", "kitti-c", "--root", tmp_path, "--out", tmp_path / "b", "--seed", "-1")
    one_line_error(build, "--seed: expected an integer >= 0, got -1")


def test_seed_zero_and_up_still_work(cli, tmp_path):
    src = image(tmp_path)
    out = tmp_path / "n.png"
    assert cli("corrupt", src, "-c", "gaussian_noise", "-l", "1", "-s", "7", "--out", out).exit_code == 0
    from robodepth_cli.imageio import load_clean

    clean = load_clean(src, None)
    expected = corrupt(clean, "gaussian_noise", 1, job_rng(7, "image", "gaussian_noise", 1, pixels_key(clean)))
    assert np.array_equal(np.asarray(Image.open(out)), expected)
