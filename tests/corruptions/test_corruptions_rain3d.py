"""rain_3d against scenes whose answer is known without robodepth: drops live between 0.5
and 10 m, so a wall nearer than 0.5 m sees no rain and every depth beyond 10 m the same
rain; each pixel shows the drops in front of its own surface only; the drop statistics are
Marshall-Palmer's and Atlas et al.'s formulas; heavier rain changes more pixels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robodepth_cli.corruptions import corrupt
from robodepth_cli.corruptions.rain_3d import drops

H, W = 96, 160


def image(seed=0):
    return (np.random.default_rng(seed).random((H, W, 3)) * 120).astype(np.uint8)  # darker than drops


def rain(depth, level=3, seed=0, x=None):
    return corrupt(image() if x is None else x, "rain_3d", level, np.random.default_rng(seed),
                   depth=np.broadcast_to(np.asarray(depth, float), (H, W)).copy())


def test_drop_statistics_are_the_formulas():
    # Marshall-Palmer at 25 mm/h: slope 4.1 * 25^-0.21 per mm; drops above 1 mm
    lam = 4.1 * 25 ** -0.21
    n, d, v = drops(25.0)
    assert n == pytest.approx(8000 / lam * math.exp(-lam))
    assert d == pytest.approx(1 + 1 / lam)  # the mean of an exponential tail above 1 mm
    assert v == pytest.approx(9.65 - 10.3 * math.exp(-0.6 * d))  # m/s, about 5.6
    assert 5.0 < v < 6.5 and 100 < n < 1000


def test_a_wall_nearer_than_every_drop_sees_no_rain():
    x = image()
    np.testing.assert_array_equal(rain(0.4, 5, x=x), x)


def test_depth_beyond_the_farthest_drop_changes_nothing():
    np.testing.assert_array_equal(rain(10.0), rain(40.0))
    np.testing.assert_array_equal(rain(10.0), rain(1000.0))
    assert not np.array_equal(rain(10.0), rain(3.0))


def test_each_pixel_sees_the_drops_in_front_of_its_own_surface():
    near, far = rain(1.0), rain(50.0)
    mixed = np.full((H, W), 50.0)
    mixed[:, : W // 2] = 1.0
    out = rain(mixed)
    np.testing.assert_array_equal(out[:, : W // 2], near[:, : W // 2])
    np.testing.assert_array_equal(out[:, W // 2:], far[:, W // 2:])


def test_more_rain_with_distance_and_with_level():
    """Drops per metre of depth grow as z^2 while each streak's ink (length x opacity x
    coverage) falls as 1/z^2: every metre of clear air adds about the same rain."""
    x = image()

    def brightening(out):
        return float(np.mean(out.astype(float) - x))

    by_depth = [brightening(rain(z, 3, x=x)) for z in (1.0, 3.0, 6.0, 10.0)]
    assert by_depth == sorted(by_depth) and by_depth[0] < 0.5 * by_depth[-1]
    by_level = [brightening(rain(20.0, lv, x=x)) for lv in (1, 2, 3, 4, 5)]
    assert by_level == sorted(by_level) and by_level[0] < 0.5 * by_level[-1]


def test_streaks_only_brighten_towards_the_drop_and_differ_by_seed():
    x = image()
    out = rain(20.0, 4, x=x)
    assert (out >= x).all()  # every pixel moves towards the drops' 204
    assert not np.array_equal(out, rain(20.0, 4, seed=1, x=x))
    np.testing.assert_array_equal(out, rain(20.0, 4, x=x))
