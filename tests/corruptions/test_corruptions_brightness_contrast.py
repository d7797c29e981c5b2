"""brightness and contrast against their formulas: brightness bit for bit with scikit-image's
HSV round trip on awkward pixels (grays, ties for the maximum, saturation), contrast within
one level on at most 0.1% of the values."""

from __future__ import annotations

import numpy as np
import pytest
import skimage.color

from robodepth_cli.corruptions import corrupt

from tests.helpers.images import assert_close_uint8, smooth_image, truncate


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
