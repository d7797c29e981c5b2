"""Continuous severity: decimal levels between the five integer ones (issue 23)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from tests.helpers.paths import REFERENCE
from robodepth_cli import seeding
from robodepth_cli.corruptions import NAMES, REGISTRY, LevelError, corrupt, level_text, parse_level
from robodepth_cli.corruptions.severity import Blend
from robodepth_cli.errors import RobodepthError

GRID = [1 + 0.25 * i for i in range(17)]  # 1, 1.25, ..., 5


def frame() -> np.ndarray:
    return np.asarray(Image.open(REFERENCE / "kitti" / "kitti_like_md2__input.png").convert("RGB"))


def mad(clean: np.ndarray, out: np.ndarray) -> float:
    return float(np.abs(out.astype(np.float64) - clean).mean())


def structure_lost(clean: np.ndarray, out: np.ndarray) -> float:
    """1 - Pearson correlation of the output with the clean image."""
    return float(1 - np.corrcoef(clean.astype(np.float64).ravel(), out.astype(np.float64).ravel())[0, 1])


# Fog and frost also dim the image (fog divides by m + t, frost lowers the image's weight),
# so their distance from the clean image falls at the benchmark's own levels 3 -> 4; what
# grows with every level is how much of the image's structure is lost.
STATISTIC = {"fog": structure_lost, "frost": structure_lost}
# The benchmark's own glass blur is milder at level 4 than at 3 on this frame (two shuffle
# passes instead of three): its decimal levels must move monotonically from each integer
# level's effect to the next one's, whichever way that goes.
NOT_MONOTONE_AT_INTEGER_LEVELS = {"glass_blur"}
# Dips allowed, relative: one fixed seed serves every level, but a random corruption's draws
# still land differently as its parameters change, and pixelate's box sizes are truncated.
TOLERANCE = 0.02


@pytest.fixture(scope="module")
def effects():
    clean = frame()
    table = {}
    for name in NAMES:
        stat = STATISTIC.get(name, mad)
        table[name] = [stat(clean, corrupt(clean, name, s, np.random.default_rng(3))) for s in GRID]
    return table


@pytest.mark.parametrize("name", [n for n in NAMES if n not in NOT_MONOTONE_AT_INTEGER_LEVELS])
def test_effect_grows_with_the_level(name, effects):
    values = effects[name]
    assert values[-1] > values[0] * 1.2, f"{name}: level 5 barely differs from level 1: {values}"
    top = values[0]
    for s, v in zip(GRID, values):
        assert v >= top * (1 - TOLERANCE), f"{name} at {s}: {v:.4f} below {top:.4f} ({values})"
        top = max(top, v)


@pytest.mark.parametrize("name", sorted(NOT_MONOTONE_AT_INTEGER_LEVELS))
def test_effect_moves_from_each_level_to_the_next(name, effects):
    values = effects[name]
    for i in range(4):
        seg = values[4 * i:4 * i + 5]  # levels i+1, i+1.25, ..., i+2
        sign = 1 if seg[-1] >= seg[0] else -1
        for a, b in zip(seg, seg[1:]):
            assert sign * (b - a) >= -TOLERANCE * max(abs(a), 1e-9), (name, i + 1, seg)


@pytest.mark.parametrize("name", NAMES)
def test_whole_levels_given_as_floats_are_the_integer_levels(name):
    x = frame()[:64, :96]
    assert np.array_equal(corrupt(x, name, 4.0, np.random.default_rng(5)),
                          corrupt(x, name, 4, np.random.default_rng(5)))


@pytest.mark.parametrize("name", NAMES)
def test_a_decimal_level_is_reproducible_and_lies_between_its_neighbours(name):
    x = frame()[:96, :160]
    a = corrupt(x, name, 3.5, np.random.default_rng(9))
    assert np.array_equal(a, corrupt(x, name, 3.5, np.random.default_rng(9)))
    assert a.dtype == np.uint8 and a.shape == x.shape
    if REGISTRY[name].deterministic:
        lo, hi = (corrupt(x, name, lv, np.random.default_rng(0)) for lv in (3, 4))
        assert not np.array_equal(a, lo) or np.array_equal(lo, hi)


@pytest.mark.parametrize("name,level,expected", [
    ("brightness", 1.5, {"c": 0.15}),
    ("contrast", 4.5, {"c": 0.075}),
    ("fog", 2.5, {"t": 2.25, "d": 1.85}),
    ("shot_noise", 1.2, {"lambda": 53.0}),
    ("defocus_blur", 3.25, {"radius": 6.5, "alias": 0.5}),
    # integers rounded, halves up
    ("jpeg_compression", 1.5, {"quality": 22}),
    ("jpeg_compression", 4.4, {"quality": 9}),
    ("motion_blur", 1.5, {"radius": 13, "sigma": 4.0}),
    ("motion_blur", 1.4, {"radius": 12, "sigma": 3.8}),
    # glass blur's shuffle: the nearer level's pair, halves up
    ("glass_blur", 1.4, {"sigma": 0.78, "delta": 1, "iterations": 2}),
    ("glass_blur", 1.5, {"sigma": 0.8, "delta": 2, "iterations": 1}),
    ("snow", 4.5, {"mu": 0.55, "sigma": 0.3, "z": 3.5, "tau": 0.85, "r": 12, "s": 10.0, "beta": 0.6}),
])
def test_parameters_between_levels_follow_the_stated_rule(name, level, expected):
    got = REGISTRY[name].params(level)
    assert got.keys() == expected.keys()
    for k, v in expected.items():
        assert got[k] == pytest.approx(v), (k, got[k])
        assert type(got[k]) is type(v) or isinstance(v, float), (k, got[k])


def test_bit_depth_and_zoom_sets_are_blended():
    assert REGISTRY["color_quant"].params(2.25) == {"bits": Blend(4, 3, 0.25)}
    zb = REGISTRY["zoom_blur"].params(4.5)
    assert zb["stop"] == Blend(1.26, 1.31, 0.5)


def test_color_quant_between_levels_is_the_truncated_mix_of_its_neighbours():
    x = frame()[:40, :60]
    four = x & 0b11110000
    three = x & 0b11100000
    want = np.floor(0.75 * four + 0.25 * three).astype(np.uint8)
    assert np.array_equal(corrupt(x, "color_quant", 2.25, np.random.default_rng(0)), want)


def test_zoom_blur_between_levels_lies_between_its_neighbours():
    x = frame()[:96, :160]
    lo, mid, hi = (corrupt(x, "zoom_blur", s, np.random.default_rng(0)).astype(int) for s in (2, 2.5, 3))
    # mixed before the truncation: at most one level outside the neighbours' span
    assert (mid >= np.minimum(lo, hi) - 1).all() and (mid <= np.maximum(lo, hi) + 1).all()
    assert 0 < np.abs(mid - lo).mean() < np.abs(hi - lo).mean()


def test_a_fractional_disk_adds_whole_rings():
    from robodepth_cli.corruptions.defocus_blur import disk_kernel

    # radius 3 holds the points with X^2 + Y^2 <= 9; sqrt(10) adds the 8 points (+-1, +-3),
    # (+-3, +-1), which come in at radius 3.17 and not at 3.1
    def support(r):
        d = (np.add.outer(np.arange(-8, 9) ** 2, np.arange(-8, 9) ** 2) <= r * r)
        return int(d.sum())
    assert support(3) == 29 and support(3.1) == 29 and support(3.17) == 37
    # with no anti-aliasing the kernel is the normalised disk itself
    for r, n in ((3.1, 29), (3.17, 37), (8.5, support(8.5))):
        k = disk_kernel(r, 1e-9)
        assert np.count_nonzero(k > 1e-6) == n


@pytest.mark.parametrize("value,top,expected", [
    ("2.5", 5, 2.5), ("3", 5, 3), ("3.0", 5, 3), (" 4.25 ", 5, 4.25), (np.float32(1.5), 5, 1.5),
    (np.int64(2), 4, 2), (5, 5, 5), (1, 4, 1),
])
def test_levels_parse_to_int_when_whole(value, top, expected):
    got = parse_level(value, top=top)
    assert got == expected and type(got) is type(expected)


@pytest.mark.parametrize("value,top,message", [
    ("0.5", 5, "-l: level 0.5 is out of range; valid levels: 1..5"),
    (5.5, 5, "-l: level 5.5 is out of range; valid levels: 1..5"),
    ("4.5", 4, "-l: level 4.5 is out of range; valid levels: 1..4"),
    ("inf", 5, "-l: level inf is out of range; valid levels: 1..5"),
    ("two", 5, "-l: 'two' is not a number; levels are 1..5 (decimals allowed, e.g. 2.5)"),
    (None, 5, "-l: None is not a number; levels are 1..5 (decimals allowed, e.g. 2.5)"),
])
def test_bad_levels_are_one_line_refusals(value, top, message):
    with pytest.raises(LevelError) as info:
        parse_level(value, top=top, what="-l")
    assert str(info.value) == message
    assert isinstance(info.value, RobodepthError)


def test_level_names_are_canonical():
    assert [level_text(v) for v in (3, 3.0, 2.5, 1.25, np.float64(4.75))] == ["3", "3", "2.5", "1.25", "4.75"]


def test_decimal_levels_have_their_own_streams_and_integer_ones_keep_theirs():
    draw = lambda lv: seeding.job_rng(1, "kitti-c", "fog", lv, "a/b.png").random()
    assert draw(2) == draw(2.0)
    assert len({draw(2), draw(2.5), draw(2.25), draw(3)}) == 4
    # the stream of an integer level is keyed as it always was: by the level's digits
    import hashlib
    key = "\x1f".join(("1", "kitti-c", "fog", "2", "a/b.png")).encode()
    digest = hashlib.sha256(key).digest()
    entropy = [int.from_bytes(digest[i:i + 4], "little") for i in range(0, 32, 4)]
    assert draw(2) == np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy))).random()
