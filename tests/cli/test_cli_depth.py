"""`corrupt` and `preview` with `--depth`: .npy in metres, 16-bit PNGs with --depth-scale,
and one-line refusals."""

from __future__ import annotations

import math

import numpy as np
from PIL import Image

from robodepth_cli.corruptions import DEPTH_NAMES

from tests.helpers.messages import one_line_error


def image(tmp_path, size=(48, 64)):
    arr = np.random.default_rng(3).integers(0, 256, (*size, 3), dtype=np.uint8)
    path = tmp_path / "img.png"
    Image.fromarray(arr).save(path)
    return path, arr


def fog_by_hand(arr, depth_m, visibility_m):
    t = math.exp(math.log(0.02) * depth_m / visibility_m)
    return np.floor(np.clip(arr * t + 204.0 * (1 - t), 0, 255) + 0.5).astype(np.uint8)


def test_npy_depth_in_metres(tmp_path, cli):
    src, arr = image(tmp_path)
    np.save(tmp_path / "d.npy", np.full((48, 64), 30.0, np.float32))
    res = cli("corrupt", src, "-c", "fog_3d", "-l", "2", "--depth", tmp_path / "d.npy", "--out", tmp_path / "f.png")
    assert res.exit_code == 0, res.output
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "f.png")), fog_by_hand(arr, 30.0, 150.0))


def test_16_bit_png_depth_with_scale(tmp_path, cli):
    src, arr = image(tmp_path)
    Image.fromarray(np.full((48, 64), 7680, np.uint16)).save(tmp_path / "d.png")  # 30 m at 256 per metre
    res = cli("corrupt", src, "-c", "fog_3d", "-l", "2", "--depth", tmp_path / "d.png", "--depth-scale", "256",
              "--out", tmp_path / "f.png")
    assert res.exit_code == 0, res.output
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "f.png")), fog_by_hand(arr, 30.0, 150.0))


def test_depth_follows_size(tmp_path, cli):
    src, _ = image(tmp_path, (96, 128))
    np.save(tmp_path / "d.npy", np.full((96, 128), 5.0))
    res = cli("corrupt", src, "-c", "near_focus,zoom_3d", "-l", "1", "--size", "48x64",
              "--depth", tmp_path / "d.npy", "--out", tmp_path / "o/")
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "o").rglob("*.png")) == ["1.png", "1.png"]


def test_preview_with_depth(tmp_path, cli):
    src, _ = image(tmp_path)
    np.save(tmp_path / "d.npy", np.linspace(1, 20, 48 * 64).reshape(48, 64))
    res = cli("preview", src, "-c", ",".join(DEPTH_NAMES) + ",fog_3d+gaussian_noise", "-l", "1,5",
              "--depth", tmp_path / "d.npy", "--out", tmp_path / "p.png", "--thumb-width", "64")
    assert res.exit_code == 0, res.output
    assert Image.open(tmp_path / "p.png").size[1] > 6 * 48


def test_refusals(tmp_path, cli):
    src, _ = image(tmp_path)
    out = tmp_path / "f.png"
    one_line_error(cli("corrupt", src, "-c", "fog_3d", "-l", "1", "--out", out), "--corruption fog_3d", "--depth")
    one_line_error(cli("corrupt", src, "-c", "brightness:1+motion_3d:2", "--out", out), "motion_3d", "--depth")
    one_line_error(cli("preview", src, "-c", "zoom_3d", "--out", out), "zoom_3d", "--depth")
    Image.fromarray(np.full((48, 64), 1000, np.uint16)).save(tmp_path / "d.png")
    one_line_error(cli("corrupt", src, "-c", "fog_3d", "-l", "1", "--depth", tmp_path / "d.png", "--out", out),
                   "d.png", "--depth-scale")
    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(tmp_path / "rgb.png")
    one_line_error(cli("corrupt", src, "-c", "fog_3d", "-l", "1", "--depth", tmp_path / "rgb.png",
                       "--depth-scale", "256", "--out", out), "rgb.png", "16-bit")
    np.save(tmp_path / "sq.npy", np.ones((48, 48)))
    one_line_error(cli("corrupt", src, "-c", "fog_3d", "-l", "1", "--depth", tmp_path / "sq.npy", "--out", out),
                   "--depth", "aspect ratio")
    one_line_error(cli("corrupt", src, "-c", "fog_3d", "-l", "1", "--depth", tmp_path / "none.npy", "--out", out),
                   "none.npy")
    one_line_error(cli("corrupt", src, "-c", "fog", "-l", "1", "--depth-scale", "256", "--out", out), "--depth-scale")
    assert not out.exists()


def test_depth_files_follow_one_scale_rule(tmp_path, cli):
    src, arr = image(tmp_path)
    out = tmp_path / "f.png"
    args = ("corrupt", src, "-c", "fog_3d", "-l", "2", "--out", out)
    np.save(tmp_path / "m.npy", np.full((48, 64), 30.0, np.float32))  # metres
    one_line_error(cli(*args, "--depth", tmp_path / "m.npy", "--depth-scale", "256"),
                   "m.npy", "float depth values are metres", "--depth-scale")
    np.save(tmp_path / "i.npy", np.full((48, 64), 7680, np.uint16))  # 30 m at 256 per metre
    one_line_error(cli(*args, "--depth", tmp_path / "i.npy"), "i.npy", "need a scale, --depth-scale")
    res = cli(*args, "--depth", tmp_path / "i.npy", "--depth-scale", "256")
    assert res.exit_code == 0, res.output
    np.testing.assert_array_equal(np.asarray(Image.open(out)), fog_by_hand(arr, 30.0, 150.0))


def test_a_garbage_npy_is_not_a_depth_array(tmp_path, cli):
    src, _ = image(tmp_path)
    out = tmp_path / "f.png"
    args = ("corrupt", src, "-c", "fog_3d", "-l", "2", "--out", out)
    (tmp_path / "g.npy").write_bytes(b"not numpy at all")
    res = cli(*args, "--depth", tmp_path / "g.npy")
    one_line_error(res, "g.npy", "not a depth array")
    assert "pickle" not in res.output
    np.save(tmp_path / "o.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    one_line_error(cli(*args, "--depth", tmp_path / "o.npy"), "o.npy", "not a depth array")
    assert not out.exists()


def test_an_all_nan_depth_map_is_refused_as_a_build_fails_it(tmp_path, cli):
    src, _ = image(tmp_path)
    out = tmp_path / "f.png"
    args = ("corrupt", src, "-c", "fog_3d", "-l", "2", "--out", out)
    np.save(tmp_path / "nan.npy", np.full((48, 64), np.nan, np.float32))  # a build fails this map
    one_line_error(cli(*args, "--depth", tmp_path / "nan.npy"), "nan.npy", "no valid depth")
    assert not out.exists()
