"""zoom_blur, motion_blur and defocus_blur beyond the fidelity harness
(tests/corruptions/test_fidelity.py): their building blocks (clipped zoom, shift-and-add motion blur,
the anti-aliased disk kernel) against literal or SciPy/OpenCV formulations on small
images.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import scipy.ndimage

from robodepth_cli.corruptions import REGISTRY, corrupt
from robodepth_cli.corruptions import defocus_blur as defocus_mod
from robodepth_cli.corruptions import zoom_blur as zoom_mod
from robodepth_cli.corruptions.motion_blur import motion_taps, shift_blur

from tests.helpers.images import assert_close_uint8, smooth_image, truncate


# --- clipped zoom / zoom blur --------------------------------------------------------

def test_zoom_axis_sizes_round_half_to_even():
    # ceil(640 / 4.5) = 143 and 143 * 4.5 = 643.5: SciPy sizes with Python's round -> 644.
    assert zoom_mod.zoom_axis(640, 4.5) == ((640 - 143) // 2, 143, 644)
    # ceil(192 / 4.5) = 43 and 43 * 4.5 = 193.5 -> 194; ceil(192 / 2.5) = 77, 77 * 2.5 = 192.5 -> 192.
    assert zoom_mod.zoom_axis(192, 4.5) == (74, 43, 194)
    assert zoom_mod.zoom_axis(192, 2.5) == (57, 77, 192)


def centre_crop(img: np.ndarray, z: float) -> np.ndarray:
    h, w = img.shape[:2]
    ch, cw = math.ceil(h / z), math.ceil(w / z)
    top, left = (h - ch) // 2, (w - cw) // 2
    return img[top:top + ch, left:left + cw]


@pytest.mark.parametrize("shape", [(40, 52, 3), (33, 47), (37, 64, 1)])
@pytest.mark.parametrize("z", [1.0, 1.03, 1.3, 2.5, 4.5])
def test_linear_zoom_of_the_centre_crop_is_scipys(shape, z):
    img = np.random.default_rng(1).random(shape).astype(np.float32)
    h, w = shape[:2]
    crop = centre_crop(img, z)
    zooms = (z, z) + ((1,) if img.ndim == 3 else ())
    expected = scipy.ndimage.zoom(crop, zooms, order=1)
    (top, ch, _), (left, cw, _) = zoom_mod.zoom_axis(h, z), zoom_mod.zoom_axis(w, z)
    ours = zoom_mod.linear_zoom(img[top:top + ch, left:left + cw], z)
    assert ours.shape == expected.shape
    assert ours.shape[0] >= h and ours.shape[1] >= w
    np.testing.assert_allclose(ours, expected, atol=2e-6)


def test_zoom_levels_are_the_benchmark_factor_sets():
    sets = [zoom_mod.level_factors(level) for level in range(1, 6)]
    assert [len(f) for f in sets] == [12, 16, 11, 13, 11]
    assert [round(f[-1], 2) for f in sets] == [1.11, 1.15, 1.20, 1.24, 1.30]
    assert all(f[0] == 1.0 for f in sets)
    assert REGISTRY["zoom_blur"].params(3) == {"start": 1, "stop": 1.21, "step": 0.02}


@pytest.mark.parametrize("level", [1, 3, 5])
def test_zoom_blur_is_the_mean_of_the_clipped_zooms(level):
    x = smooth_image(44, 60)
    f = (x / 255.0).astype(np.float32)
    factors = zoom_mod.level_factors(level)
    acc = np.zeros_like(f)
    for z in factors:
        acc += scipy.ndimage.zoom(centre_crop(f, z), (z, z, 1), order=1)[:44, :60]
    expected = truncate((f + acc) / (len(factors) + 1))
    assert_close_uint8(corrupt(x, "zoom_blur", level, np.random.default_rng(0)), expected)


# --- motion blur ---------------------------------------------------------------------

def spec_shift(img: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """The shift rule literally: move by dx columns / dy rows, repeat the nearest moved-in edge."""
    out = np.array(img, dtype=np.float64)
    h, w = out.shape[:2]
    if dx > 0:
        out[:, dx:] = out[:, :w - dx].copy()
        out[:, :dx] = out[:, dx:dx + 1]
    elif dx < 0:
        out[:, :w + dx] = out[:, -dx:].copy()
        out[:, w + dx:] = out[:, w + dx - 1:w + dx]
    if dy > 0:
        out[dy:] = out[:h - dy].copy()
        out[:dy] = out[dy:dy + 1]
    elif dy < 0:
        out[:h + dy] = out[-dy:].copy()
        out[h + dy:] = out[h + dy - 1:h + dy]
    return out


def spec_motion_blur(img: np.ndarray, radius: int, sigma: float, angle: float) -> np.ndarray:
    width = 2 * radius + 1
    k = np.exp(-np.arange(width) ** 2 / (2 * sigma ** 2))
    k /= k.sum()
    py, px = width * math.sin(math.radians(angle)), width * math.cos(math.radians(angle))
    hyp = math.hypot(py, px)
    acc = np.zeros(img.shape)
    for i in range(width):
        dy = -math.ceil(i * py / hyp - 0.5)
        dx = -math.ceil(i * px / hyp - 0.5)
        if abs(dy) >= img.shape[0] or abs(dx) >= img.shape[1]:
            break
        acc += k[i] * spec_shift(img, dx, dy)
    return acc


@pytest.mark.parametrize("angle", [-135.0, -90.0, -45.0, -17.3, 0.0, 29.9, 45.0])
@pytest.mark.parametrize("shape,radius,sigma", [((36, 50, 3), 10, 3), ((32, 34, 3), 20, 15), ((40, 33), 12, 8)])
def test_shift_blur_equals_spec_shift_and_add(shape, radius, sigma, angle):
    img = np.random.default_rng(2).integers(0, 256, shape).astype(np.uint8)
    src = img if img.ndim == 3 else img.astype(np.float32) / 255
    expected = spec_motion_blur(src, radius, sigma, angle)
    np.testing.assert_allclose(shift_blur(src, radius, sigma, angle), expected, rtol=1e-5, atol=1e-3)


def test_motion_taps_stop_at_the_image_border():
    # Angle 0: tap i shifts by dx = -i; on a 32-pixel-wide image the 33rd tap (i = 32) ends it.
    dy, dx, k = motion_taps(20, 15, 0.0, (40, 32))
    assert len(k) == 32 and list(dx) == [-i for i in range(32)] and not dy.any()
    assert motion_taps(20, 15, 0.0, (40, 64))[2].size == 41


# --- defocus blur --------------------------------------------------------------------

def spec_disk(radius: int, alias: float) -> np.ndarray:
    coords, ksize = (np.arange(-8, 9), (3, 3)) if radius <= 8 else (np.arange(-radius, radius + 1), (5, 5))
    xx, yy = np.meshgrid(coords, coords)
    d = (xx ** 2 + yy ** 2 <= radius ** 2).astype(np.float32)
    d /= d.sum()
    return cv2.GaussianBlur(d, ksize, alias)


@pytest.mark.parametrize("level", [1, 2, 3, 4, 5])
def test_defocus_blur_is_filter2d_with_the_full_kernel(level):
    # Levels 1-2 take the direct path, 3-5 the FFT path.
    x = smooth_image(48, 70, seed=level)
    k = spec_disk(*defocus_mod.LEVELS[level - 1])
    f = x / 255.0
    exact = np.stack([cv2.filter2D(f[..., c], -1, k) for c in range(3)], axis=-1)
    ours = corrupt(x, "defocus_blur", level, np.random.default_rng(0))
    diff = ours.astype(int) - truncate(exact)
    # float32 arithmetic: a value may only land on the other side of an integer when the
    # float64 value is within float32 resolution of it (flat areas, where the kernel's
    # float64 sum of 1 - 4e-9 puts the formula a hair below the integer).
    near_integer = np.abs(exact * 255 - np.round(exact * 255)) < 1e-4
    assert np.abs(diff).max() <= 1
    assert not diff[~near_integer].any()
