"""Per-element noise corruptions (dark, gaussian_noise, shot_noise, iso_noise, impulse_noise).

The four table-sampled corruptions draw each element from the exact law of their SPEC
formula (``corruptions._sampling``). These tests compare that law with a literal
Monte-Carlo run of the SPEC formula, written out here with numpy's own Poisson and normal
generators, value by value; the reference-statistics comparison is in test_fidelity.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from robodepth_cli.corruptions import corrupt
from robodepth_cli.corruptions._sampling import ValueTable

VALUES = np.array([0, 1, 9, 40, 128, 200, 254, 255], dtype=np.uint8)
N_PER_VALUE = 60_000


def _value_image(values=VALUES, n=N_PER_VALUE) -> np.ndarray:
    """An image whose elements are ``n`` copies of each value, in blocks of rows."""
    return np.repeat(values, n).reshape(-1, 64, 3)


def _trunc(v):
    return np.floor(np.clip(v, 0.0, 1.0) * 255.0).astype(np.uint8)


# The SPEC formulas, literally, on f = x / 255 (float64), with numpy's samplers.
def _spec_gaussian(f, level, rng):
    s = (.08, .12, .18, .26, .38)[level - 1]
    return _trunc(f + rng.normal(0.0, s, f.shape))


def _spec_shot(f, level, rng):
    lam = (60, 25, 12, 5, 3)[level - 1]
    return _trunc(rng.poisson(f * lam) / lam)


def _spec_iso(f, level, rng):
    s = 0.7 * (.08, .12, .18, .26, .38)[level - 1]
    u = np.clip(rng.poisson(f * 25) / 25, 0, 1)
    return _trunc(u + rng.normal(0.0, s, f.shape))


def _spec_dark(f, level, rng):
    i = level - 1
    c = (.6, .5, .4, .3, .2)[i]
    n = ((f - f.min()) / (f.max() - f.min())) ** 2 * c
    p = 10 * (60, 25, 12, 5, 3)[i]
    u = np.clip(rng.poisson(n * p) / p, 0, 1)
    g = 0.1 * (.08, .12, .18, .26, .38)[i]
    return _trunc(u + rng.normal(0.0, g, f.shape))


SPEC = {"gaussian_noise": _spec_gaussian, "shot_noise": _spec_shot, "iso_noise": _spec_iso,
        "dark": _spec_dark}


@pytest.mark.parametrize("name", sorted(SPEC))
@pytest.mark.parametrize("level", [1, 3, 5])
def test_law_matches_literal_spec_formula(name, level):
    _assert_same_law(name, level, VALUES)


@pytest.mark.parametrize("level", [1, 4])
def test_dark_law_on_a_narrow_range_image(level):
    # min 20 and max 90: the stretch to [0, 1] comes first
    _assert_same_law("dark", level, np.array([20, 21, 35, 60, 89, 90], dtype=np.uint8))


def _assert_same_law(name, level, values):
    x = _value_image(values)
    ours = corrupt(x, name, level, np.random.default_rng(1)).reshape(-1)
    spec = SPEC[name](x / 255.0, level, np.random.default_rng(2)).reshape(-1)
    flat = x.reshape(-1)
    for v in values:
        a = ours[flat == v].astype(np.float64)
        b = spec[flat == v].astype(np.float64)
        se = np.sqrt((a.var() + b.var()) / N_PER_VALUE) + 1e-9
        assert abs(a.mean() - b.mean()) < 5 * se + 1e-6, (v, a.mean(), b.mean())
        assert abs(a.std() - b.std()) < 0.05 * b.std() + 0.02, (v, a.std(), b.std())
        for edge in (0, 255):  # the clip mass at both ends
            pa, pb = (a == edge).mean(), (b == edge).mean()
            assert abs(pa - pb) < 5 * np.sqrt(pb * (1 - pb) * 2 / N_PER_VALUE) + 1e-4, (v, edge, pa, pb)


def test_value_table_samples_its_distribution():
    pmf = np.zeros((256, 256))
    pmf[:, 0] = 0.5
    pmf[:, 3] = 0.25
    pmf[:, 255] = 0.25
    pmf[7] = 0.0
    pmf[7, 100:110] = 0.1
    table = ValueTable(np.cumsum(pmf, axis=1))
    x = np.full((400, 500), 7, np.uint8)
    x[:200] = 3
    out = table.sample(x, np.random.default_rng(0))
    top, bottom = out[:200], out[200:]
    assert set(np.unique(top)) == {0, 3, 255}
    assert abs((top == 0).mean() - 0.5) < 0.01 and abs((top == 3).mean() - 0.25) < 0.01
    counts = np.bincount(bottom.ravel(), minlength=256)
    assert counts[:100].sum() == 0 and counts[110:].sum() == 0
    assert np.all(np.abs(counts[100:110] / bottom.size - 0.1) < 0.005)
    np.testing.assert_allclose(table.pmf, pmf, atol=1e-12)


def test_dark_depends_on_the_image_range_only():
    # dark stretches [min, max] to [0, 1] first: the same relative value gives the same law.
    x = np.full((64, 64, 3), 50, np.uint8)
    x[:32] = 200
    y = np.where(x == 200, 255, 0).astype(np.uint8)
    a = corrupt(x, "dark", 2, np.random.default_rng(5))
    b = corrupt(y, "dark", 2, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)


def test_dark_of_a_constant_image_is_read_noise_on_black():
    x = np.full((300, 300, 3), 77, np.uint8)
    out = corrupt(x, "dark", 5, np.random.default_rng(0))
    # n = 0, so v = clip01(Normal(0, g)): P(v >= 1/255) = P(z >= 1 / (255 g)), g = .038
    from math import erfc, sqrt
    expected = 0.5 * erfc(1 / (255 * 0.038) / sqrt(2))
    assert abs((out > 0).mean() - expected) < 0.01
    assert out.max() < 60


@pytest.mark.parametrize("level", [1, 5])
def test_impulse_noise_is_per_element_salt_and_pepper(level):
    amount = (.03, .06, .09, .17, .27)[level - 1]
    x = np.full((300, 400, 3), 100, np.uint8)
    out = corrupt(x, "impulse_noise", level, np.random.default_rng(3))
    salt, pepper = (out == 255), (out == 0)
    assert np.all(out[~(salt | pepper)] == 100)
    n = out.size
    tol = 5 * np.sqrt(amount / 2 / n)
    assert abs(salt.mean() - amount / 2) < tol and abs(pepper.mean() - amount / 2) < tol
    # channels are hit independently, not whole pixels
    all3 = (salt | pepper).all(axis=2).mean()
    assert abs(all3 - amount ** 3) < 5 * np.sqrt(amount ** 3 / (n / 3)) + 1e-4


def test_impulse_noise_matches_scikit_image_s_and_p():
    from skimage.util import random_noise

    x = np.random.default_rng(0).integers(1, 255, (200, 300, 3), dtype=np.uint8)
    ours = corrupt(x, "impulse_noise", 4, np.random.default_rng(1))
    ref = (random_noise(x / 255.0, mode="s&p", amount=0.17, rng=2) * 255).astype(np.uint8)
    for v in (0, 255):
        assert abs((ours == v).mean() - (ref == v).mean()) < 0.004
    assert abs(ours.mean() - ref.mean()) < 0.5
