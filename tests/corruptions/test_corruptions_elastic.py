"""elastic_transform beyond the statistics of tests/corruptions/test_fidelity.py: the literal formula
for the same uniform draws, the identity for a centred field, very wide images, and the
Gaussian smoothing it relies on against scikit-image."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.ndimage
import skimage.filters

from robodepth_cli.corruptions import corrupt
from robodepth_cli.corruptions import elastic_transform as elastic_mod

from tests.helpers.images import ReplayRng, assert_close_uint8, smooth_image, truncate


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
