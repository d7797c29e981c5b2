"""Behaviour of the blur, snow, elastic, brightness and contrast corruptions that the
fidelity harness (tests/test_fidelity.py) does not pin down: the shared building blocks
(clipped zoom, shift-and-add motion blur) against SPEC-literal or SciPy/scikit-image
formulations on small images, the random ones against the oracle or the literal formula
for the same random draws, and determinism for a fixed seed.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import scipy.ndimage
import skimage.color
import skimage.filters

from robodepth_cli.corruptions import REGISTRY, corrupt
from robodepth_cli.corruptions import defocus_blur as defocus_mod
from robodepth_cli.corruptions import elastic_transform as elastic_mod
from robodepth_cli.corruptions import snow as snow_mod
from robodepth_cli.corruptions import zoom_blur as zoom_mod
from robodepth_cli.corruptions.motion_blur import motion_taps, shift_blur


def smooth_image(h: int, w: int, seed: int = 0) -> np.ndarray:
    """A photo-like uint8 test image: smooth random structure plus some edges."""
    rng = np.random.default_rng(seed)
    base = rng.random((h // 4 + 2, w // 4 + 2, 3))
    img = cv2.resize(base, (w, h), interpolation=cv2.INTER_CUBIC)
    img[h // 3:h // 2, w // 5:w // 2] = 0.9  # a flat patch with sharp borders
    return np.clip(img * 255, 0, 255).astype(np.uint8)


def truncate(v: np.ndarray) -> np.ndarray:
    return (np.clip(v, 0, 1) * 255).astype(np.uint8)


def assert_close_uint8(ours: np.ndarray, expected: np.ndarray, min_exact: float = 0.999) -> None:
    assert ours.shape == expected.shape and ours.dtype == np.uint8
    diff = np.abs(ours.astype(int) - expected.astype(int))
    assert diff.max() <= 1, f"max diff {diff.max()}"
    assert (diff == 0).mean() >= min_exact, f"only {(diff == 0).mean():.4%} exact"


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
def test_clipped_zoom_is_scipy_zoom_of_the_centre_crop(shape, z):
    img = np.random.default_rng(1).random(shape).astype(np.float32)
    h, w = shape[:2]
    crop = centre_crop(img, z)
    zooms = (z, z) + ((1,) if img.ndim == 3 else ())
    expected = scipy.ndimage.zoom(crop, zooms, order=1)
    ours = zoom_mod.clipped_zoom(img, z)
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
    """SPEC 9 literally: move by dx columns / dy rows, repeat the nearest moved-in edge."""
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


# --- snow ----------------------------------------------------------------------------

class ReplayRng:
    """Serves prescribed draws to code that asks a numpy Generator for them."""

    def __init__(self, **draws):
        self.draws = draws

    def standard_normal(self, shape, dtype=np.float64):
        out = self.draws["standard_normal"](shape)
        return out.astype(dtype)

    def uniform(self, low, high):
        return self.draws["uniform"]

    def random(self, shape, dtype=np.float64):
        return self.draws["random"].astype(dtype).reshape(shape)


@pytest.mark.parametrize("level", [1, 3, 4, 5])
def test_snow_equals_the_oracle_for_the_same_noise_and_angle(level):
    import imagecorruptions

    x = smooth_image(64, 96, seed=level)
    mu, sigma, z = snow_mod.LEVELS[level - 1][:3]
    np.random.seed(level)
    expected = imagecorruptions.corrupt(x, severity=level, corruption_name="snow")
    np.random.seed(level)
    noise = np.random.normal(size=x.shape[:2], loc=mu, scale=sigma)
    angle = np.random.uniform(-135, -45)

    def centre_block(shape):
        (top, ch, _), (left, cw, _) = zoom_mod.zoom_axis(64, z), zoom_mod.zoom_axis(96, z)
        assert shape == (ch, cw)
        return (noise[top:top + ch, left:left + cw] - mu) / sigma

    ours = snow_mod.snow(x, level, ReplayRng(standard_normal=centre_block, uniform=angle))
    assert_close_uint8(ours, expected)


# --- elastic transform ---------------------------------------------------------------

def test_elastic_transform_equals_the_literal_formula_for_the_same_uniforms():
    h, w, level = 60, 90, 5
    x = smooth_image(h, w, seed=3)
    u = np.random.default_rng(4).random((2, h, w), dtype=np.float32)
    m, alpha = 0.005 * h, 250 * elastic_mod.LEVELS[level - 1]
    dx, dy = (skimage.filters.gaussian(2 * m * u[i].astype(np.float64) - m, sigma=(0.01 * h, 0.01 * w),
                                       mode="reflect", truncate=3) * alpha for i in range(2))
    rows, cols = np.mgrid[0:h, 0:w]
    f = (x / 255.0).astype(np.float32)
    expected = truncate(np.stack([
        scipy.ndimage.map_coordinates(f[..., c], [rows + dy, cols + dx], order=1, mode="reflect")
        for c in range(3)], axis=-1))
    assert np.abs(dx).max() > 1  # the field really moves pixels at this size and level
    ours = elastic_mod.elastic_transform(x, level, ReplayRng(random=u))
    assert_close_uint8(ours, expected, 0.99)


def test_elastic_transform_with_a_centred_field_is_the_identity():
    x = smooth_image(40, 50)
    half = np.full((2, 40, 50), 0.5, np.float32)
    assert np.array_equal(elastic_mod.elastic_transform(x, 5, ReplayRng(random=half)), x)


# --- brightness / contrast -----------------------------------------------------------

def awkward_pixels() -> np.ndarray:
    """Random colours plus black, white, grays and every kind of tie for the maximum."""
    rng = np.random.default_rng(5)
    px = rng.integers(0, 256, (64, 64, 3)).astype(np.uint8)
    px[0, :, :] = px[0, :, :1]                         # grays, including 0 and 255
    px[0, 0], px[0, 1] = 0, 255
    px[1, :, 1] = px[1, :, 0]                          # red == green
    px[2, :, 2] = px[2, :, 1]                          # green == blue
    px[3, :, 2] = px[3, :, 0]                          # red == blue
    px[4, :, :2] = 255                                 # saturated
    return px


@pytest.mark.parametrize("level", [1, 2, 3, 4, 5])
def test_brightness_is_bit_identical_to_the_skimage_round_trip(level):
    x = awkward_pixels()
    hsv = skimage.color.rgb2hsv(x / 255.0)
    hsv[..., 2] = np.clip(hsv[..., 2] + (0.1, 0.2, 0.3, 0.4, 0.5)[level - 1], 0, 1)
    expected = truncate(skimage.color.hsv2rgb(hsv))
    assert np.array_equal(corrupt(x, "brightness", level, np.random.default_rng(0)), expected)


@pytest.mark.parametrize("level", [1, 5])
def test_contrast_equals_the_formula(level):
    x = smooth_image(50, 70)
    c = (0.4, 0.3, 0.2, 0.1, 0.05)[level - 1]
    f = x / 255.0
    m = f.mean(axis=(0, 1), keepdims=True)
    assert_close_uint8(corrupt(x, "contrast", level, np.random.default_rng(0)), truncate((f - m) * c + m))


@pytest.mark.parametrize("mode", ["reflect", "nearest", "mirror"])
def test_gaussian_matches_scikit_image_even_when_the_kernel_outgrows_the_image(mode):
    from skimage.filters import gaussian as sk_gaussian

    from robodepth_cli.corruptions._ops import gaussian

    a = np.random.default_rng(0).random((32, 40))
    ours = gaussian(a, (12, 3), truncate=4, mode=mode)
    assert np.abs(ours - sk_gaussian(a, sigma=(12, 3), mode=mode, truncate=4)).max() < 1e-12


def test_elastic_transform_on_a_very_wide_image():
    x = np.random.default_rng(1).integers(0, 256, (32, 4000, 3), dtype=np.uint8)
    assert corrupt(x, "elastic_transform", 5, np.random.default_rng(2)).shape == x.shape
