"""snow beyond the statistics of tests/corruptions/test_fidelity.py: with the oracle's own noise layer
and blur angle replayed, it gives the oracle's pixels."""

from __future__ import annotations

import numpy as np
import pytest

from robodepth_cli.corruptions import snow as snow_mod
from robodepth_cli.corruptions import zoom_blur as zoom_mod

from tests.helpers.images import ReplayRng, assert_close_uint8, smooth_image


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
