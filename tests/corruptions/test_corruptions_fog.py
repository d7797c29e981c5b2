"""fog and its plasma fractal beyond the statistics of test_fidelity.py: the diamond-square
map against a point-by-point transcription of the written rule, its torus property, and its
law against the imagecorruptions oracle's fractal."""

from __future__ import annotations

import numpy as np
import pytest

from robodepth_cli.corruptions import corrupt
from robodepth_cli.corruptions.fog import next_power_of_two, plasma_fractal


def spec_plasma(n: int, decay: float, rng: np.random.Generator) -> np.ndarray:
    """SPEC definition 3 point by point, drawing the same uniforms (per step: square
    centres, then points (i s, h + j s), then (h + i s, j s), each in C order)."""
    a = np.zeros((n, n), dtype=np.float64)
    s, w = n, 100.0
    while s >= 2:
        h, k = s // 2, n // s

        def noise():
            return w * (rng.random((k, k), dtype=np.float32).astype(np.float64) * 2 * w - w)

        u = noise()
        for i in range(k):
            for j in range(k):
                r, c = h + i * s, h + j * s
                a[r, c] = (a[r - h, c - h] + a[(r + h) % n, c - h] + a[r - h, (c + h) % n]
                           + a[(r + h) % n, (c + h) % n]) / 4 + u[i, j]
        for offset in ((0, h), (h, 0)):
            u = noise()
            for i in range(k):
                for j in range(k):
                    r, c = offset[0] + i * s, offset[1] + j * s
                    a[r, c] = (a[(r - h) % n, c] + a[(r + h) % n, c] + a[r, (c - h) % n]
                               + a[r, (c + h) % n]) / 4 + u[i, j]
        s, w = h, w / decay
    a -= a.min()
    return a / a.max()


@pytest.mark.parametrize("n,decay", [(2, 2.0), (8, 2.0), (32, 1.4), (64, 1.7)])
def test_plasma_matches_point_by_point_spec(n, decay):
    ours = plasma_fractal(n, decay, np.random.default_rng(n))
    spec = spec_plasma(n, decay, np.random.default_rng(n))
    assert ours.dtype == np.float32 and ours.shape == (n, n)
    # float32 sums of values up to ~1e4 against float64: agreement to ~1e-6 of the range
    np.testing.assert_allclose(ours, spec, atol=2e-5)


def test_plasma_crop_is_the_top_left_of_the_full_map():
    full = plasma_fractal(128, 1.5, np.random.default_rng(3))
    crop = plasma_fractal(128, 1.5, np.random.default_rng(3), (37, 101))
    np.testing.assert_array_equal(crop, full[:37, :101])


def test_plasma_range_and_torus():
    p = plasma_fractal(256, 2.0, np.random.default_rng(0))
    assert p.min() == 0.0 and p.max() == 1.0
    # A torus has no seam: the wrap-around step (last row/column to the first) is as
    # smooth as any step inside the map.
    inner_rows = np.abs(np.diff(p, axis=0)).mean()
    inner_cols = np.abs(np.diff(p, axis=1)).mean()
    assert np.abs(p[-1] - p[0]).mean() < 3 * inner_rows
    assert np.abs(p[:, -1] - p[:, 0]).mean() < 3 * inner_cols


def test_plasma_rejects_bad_sizes():
    for n in (0, 1, 3, 100):
        with pytest.raises(ValueError):
            plasma_fractal(n, 2.0, np.random.default_rng(0))


def test_next_power_of_two():
    assert [next_power_of_two(v) for v in (1, 2, 3, 192, 480, 640, 1024, 1025)] == [
        1, 2, 4, 256, 512, 1024, 1024, 2048]


@pytest.mark.parametrize("decay", [2.0, 1.4])
def test_plasma_law_matches_oracle(decay):
    """Seed-to-seed statistics of our fractal against imagecorruptions' plasma_fractal."""
    from imagecorruptions.corruptions import plasma_fractal as oracle_plasma

    n, seeds = 128, 120
    ours, theirs = [], []

    def figures(p):
        return [p.std(), p[:40, :100].std(), np.abs(np.diff(p, axis=1)).mean()]

    for s in range(seeds):
        np.random.seed(s)
        theirs.append(figures(oracle_plasma(n, decay)))
        ours.append(figures(plasma_fractal(n, decay, np.random.default_rng(s))))
    ours, theirs = np.array(ours), np.array(theirs)
    se = np.sqrt((ours.var(0) + theirs.var(0)) / seeds)
    assert np.all(np.abs(ours.mean(0) - theirs.mean(0)) < 4 * se), (ours.mean(0), theirs.mean(0))


def test_fog_formula_with_a_known_map(monkeypatch):
    """fog = clip01((f + t P) * m / (m + t)) truncated, P the plasma crop."""
    import robodepth_cli.corruptions.fog as fog_module

    x = np.random.default_rng(0).integers(0, 200, (40, 70, 3), dtype=np.uint8)
    p = np.random.default_rng(1).random((40, 70)).astype(np.float32)
    seen = {}

    def fake_plasma(n, decay, rng, shape=None):
        seen.update(n=n, decay=decay, shape=shape)
        return p

    monkeypatch.setattr(fog_module, "plasma_fractal", fake_plasma)
    out = corrupt(x, "fog", 4, np.random.default_rng(0))
    t = 2.5
    f = x / 255.0
    m = f.max()
    expected = np.floor(np.clip((f + t * p[..., None]) * m / (m + t), 0, 1) * 255)
    assert seen == {"n": 128, "decay": 1.5, "shape": (40, 70)}
    diff = np.abs(out.astype(int) - expected)
    assert diff.max() <= 1 and (diff > 0).mean() < 0.01  # float32 vs float64 truncation
