"""encode_png / write_png: the speed-tuned encoder must give back exactly the pixels it got."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from robodepth_cli.imageio import encode_png, load_clean, read_rgb, write_png


def _decode(data: bytes) -> tuple[str, np.ndarray]:
    with Image.open(io.BytesIO(data)) as im:
        assert im.format == "PNG"
        return im.mode, np.asarray(im).copy()


def _images(fixtures_dir):
    rng = np.random.default_rng(7)
    noise = rng.integers(0, 256, (48, 80, 3), dtype=np.uint8)
    # Each channel different, so a red/blue swap cannot go unnoticed.
    ramp = np.stack([*np.meshgrid(np.arange(80), np.arange(48)), np.full((48, 80), 200)], axis=2)
    clean = load_clean(fixtures_dir / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png",
                       (192, 640))
    return {"noise": noise, "ramp": (ramp * 3).astype(np.uint8), "clean": clean,
            "constant": np.full((40, 40, 3), 17, np.uint8), "extremes": (noise > 127).astype(np.uint8) * 255,
            "view": clean[10:150:2, 600:5:-3]}  # strided, reversed: not contiguous


def test_rgb_round_trip_is_exact(fixtures_dir):
    for name, img in _images(fixtures_dir).items():
        mode, back = _decode(encode_png(img))
        assert mode == "RGB", name
        np.testing.assert_array_equal(back, img, err_msg=name)


def test_every_zlib_level_gives_the_same_pixels(fixtures_dir):
    img = _images(fixtures_dir)["clean"]
    sizes = []
    for level in (0, 1, 6, 9):
        data = encode_png(img, level)
        np.testing.assert_array_equal(_decode(data)[1], img)
        sizes.append(len(data))
    assert sizes[0] > sizes[1] >= sizes[3]  # the level is really applied


def test_gray_and_rgba(fixtures_dir):
    rng = np.random.default_rng(3)
    gray = rng.integers(0, 256, (33, 35), dtype=np.uint8)
    rgba = rng.integers(0, 256, (33, 35, 4), dtype=np.uint8)
    assert _decode(encode_png(gray))[0] == "L"
    np.testing.assert_array_equal(_decode(encode_png(gray))[1], gray)
    mode, back = _decode(encode_png(rgba))
    assert mode == "RGBA"
    np.testing.assert_array_equal(back, rgba)


def test_same_pixels_same_bytes(fixtures_dir):
    img = _images(fixtures_dir)["noise"]
    assert encode_png(img) == encode_png(img.copy())


@pytest.mark.parametrize("bad, message", [
    (np.zeros((40, 40, 3), np.float32), "float32"),
    (np.zeros((40, 40, 2), np.uint8), "shape"),
    (np.zeros((40,), np.uint8), "shape"),
])
def test_refuses_what_it_cannot_encode(bad, message):
    with pytest.raises(ValueError, match=message):
        encode_png(bad)


def test_write_png_reads_back_identical(fixtures_dir, tmp_path):
    img = _images(fixtures_dir)["clean"]
    target = tmp_path / "a" / "b.png"
    data = write_png(target, img)
    assert target.read_bytes() == data
    np.testing.assert_array_equal(np.asarray(read_rgb(target)), img)


# --- the two ways a build writes its PNGs ----------------------------------------------------

def _build_images(fixtures_dir):
    """What a build writes: the clean frame and corruptions of it (noise, blur, flat
    areas), plus the synthetic cases above."""
    from robodepth_cli.corruptions import corrupt

    imgs = _images(fixtures_dir)
    clean = imgs["clean"]
    for name in ("gaussian_noise", "defocus_blur", "fog", "dark", "color_quant", "jpeg_compression"):
        for level in (1, 5):
            imgs[f"{name}{level}"] = corrupt(clean, name, level, np.random.default_rng(level))
    return imgs


def test_fast_and_compact_decode_to_the_same_pixels(fixtures_dir):
    rng = np.random.default_rng(11)
    imgs = _build_images(fixtures_dir)
    imgs["rgba"] = rng.integers(0, 256, (37, 53, 4), dtype=np.uint8)
    imgs["gray"] = rng.integers(0, 256, (37, 53), dtype=np.uint8)
    for name, img in imgs.items():
        fast, compact = encode_png(img, method="fast"), encode_png(img, method="compact")
        (mode_f, px_f), (mode_c, px_c) = _decode(fast), _decode(compact)
        want_mode = "L" if img.ndim == 2 else {3: "RGB", 4: "RGBA"}[img.shape[2]]
        assert mode_f == mode_c == want_mode, name
        np.testing.assert_array_equal(px_f, img, err_msg=name)
        np.testing.assert_array_equal(px_f, px_c, err_msg=name)
        if img.ndim == 3:
            assert fast != compact, name  # really two encoders


def test_fast_bytes_are_deterministic(fixtures_dir):
    for name, img in _build_images(fixtures_dir).items():
        assert encode_png(img, method="fast") == encode_png(np.array(img, order="F"), method="fast"), name


def test_fast_files_are_larger_but_not_much(fixtures_dir):
    """The price of the fast path: larger files, within a factor 1.6 on what a build
    writes (about 1.25 measured on a whole frame's 91 images)."""
    imgs = _build_images(fixtures_dir)
    fast = sum(len(encode_png(i, method="fast")) for i in imgs.values())
    compact = sum(len(encode_png(i, method="compact")) for i in imgs.values())
    assert compact < fast < 1.6 * compact


def test_unknown_method_refused():
    with pytest.raises(ValueError, match="unknown PNG method 'tiny'"):
        encode_png(np.zeros((40, 40, 3), np.uint8), method="tiny")


def test_every_depth_png_goes_through_one_reader(tmp_path):
    """Ground truth, predictions, a dataset's depth maps and NYU's sync_depth files: the same
    8-bit PNG where a 16-bit one belongs is refused with the same words, naming the file."""
    from robodepth_cli.groundtruth.nyu import NyuError, sync_depth_file
    from robodepth_cli.groundtruth.read import GroundTruthError, load_ground_truth
    from robodepth_cli.sources.depth_io import read_depth

    bad = tmp_path / "d.png"
    Image.fromarray(np.zeros((4, 5), np.uint8)).save(bad)
    expected = f"{bad}: 8-bit; expected a 16-bit single-channel PNG"
    with pytest.raises(NyuError, match=f"^{expected} \\(depth\\)$"):
        sync_depth_file(bad)
    with pytest.raises(GroundTruthError, match=f"^{expected} \\(ground truth of image 0\\)$"):
        load_ground_truth(tmp_path, ["d.png"], "nyu", lambda gt: gt > 0)
    with pytest.raises(Exception, match=f"^{expected} \\(depth map\\)$"):
        read_depth(bad)
    good = tmp_path / "g.png"
    Image.fromarray(np.full((4, 5), 1234, np.uint16)).save(good)
    assert sync_depth_file(good)[1] == (4, 5) and read_depth(good, scale=1000.0).shape == (4, 5)
