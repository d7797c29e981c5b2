"""What every registered corruption promises: input handling, purity, seeding."""

from __future__ import annotations

import numpy as np
import pytest

from robodepth_cli.corruptions import NAMES, REGISTRY, corrupt

RANDOM = [n for n in NAMES if not REGISTRY[n].deterministic]


def image(h=40, w=56, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


@pytest.mark.parametrize("name", NAMES)
def test_every_level_gives_uint8_of_the_input_shape_and_leaves_the_input_alone(name):
    x = image(32, 33)  # the smallest accepted height, an odd width
    before = x.copy()
    for level in range(1, REGISTRY[name].n_levels + 1):
        out = corrupt(x, name, level, np.random.default_rng(level))
        assert out.dtype == np.uint8 and out.shape == x.shape
        assert not np.shares_memory(out, x)
    assert np.array_equal(x, before)


@pytest.mark.parametrize("name", RANDOM)
def test_random_corruptions_follow_the_seed(name):
    x = image()
    a = corrupt(x, name, 3, np.random.default_rng(11))
    b = corrupt(x, name, 3, np.random.default_rng(11))
    c = corrupt(x, name, 3, np.random.default_rng(12))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("name", ["contrast", "gaussian_noise"])
def test_grayscale_and_rgba_are_converted(name):
    rgb = image()
    gray = rgb[..., 0]
    rgba = np.dstack([rgb, np.full(rgb.shape[:2], 7, np.uint8)])
    as_gray = corrupt(gray, name, 2, np.random.default_rng(1))
    assert np.array_equal(as_gray, corrupt(np.dstack([gray] * 3), name, 2, np.random.default_rng(1)))
    assert np.array_equal(corrupt(rgba, name, 2, np.random.default_rng(1)),
                          corrupt(rgb, name, 2, np.random.default_rng(1)))


@pytest.mark.parametrize("bad,message", [
    (np.zeros((40, 56, 3), np.float32), "uint8"),
    (np.zeros((40, 56, 2), np.uint8), "shape"),
    (np.zeros((2, 40, 56, 3), np.uint8), "shape"),
    (np.zeros((31, 56, 3), np.uint8), "too small"),
    ([[1, 2], [3, 4]], "numpy array"),
])
def test_other_inputs_are_a_value_error_saying_what_is_wrong(bad, message):
    with pytest.raises(ValueError, match=message):
        corrupt(bad, "contrast", 1, np.random.default_rng(0))


@pytest.mark.parametrize("name,level,rng,message", [
    ("fogg", 1, np.random.default_rng(0), "unknown corruption 'fogg'; valid: brightness"),
    ("fog", 0, np.random.default_rng(0), "out of range"),
    ("fog", 6, np.random.default_rng(0), "out of range"),
    ("fog", 5.01, np.random.default_rng(0), r"fog: level 5.01 is out of range; valid levels: 1..5"),
    ("fog", float("nan"), np.random.default_rng(0), "out of range"),
    ("fog", "two", np.random.default_rng(0), "not a number"),
    ("fog", True, np.random.default_rng(0), "not a number"),
    ("fog", 2, np.random.RandomState(0), "Generator"),
])
def test_bad_name_level_or_rng(name, level, rng, message):
    with pytest.raises(ValueError, match=message):
        corrupt(image(), name, level, rng)
