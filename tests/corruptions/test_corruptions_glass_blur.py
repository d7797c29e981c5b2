"""glass_blur beyond the statistics of test_fidelity.py: the numba shuffle against a literal
Python transcription of the benchmark's loop, and the whole pipeline against scikit-image's
gaussian with the same offsets."""

from __future__ import annotations

import numpy as np
import pytest

import robodepth_cli.corruptions.glass_blur as gb
from robodepth_cli.corruptions import corrupt


def literal_shuffle(x: np.ndarray, offsets: np.ndarray, delta: int) -> np.ndarray:
    """The benchmark's loop, statement for statement, consuming ``offsets`` in scan order
    (dx, then dy) instead of drawing them: the "swap" is a tuple assignment of numpy row
    views."""
    height, width = x.shape[:2]
    it = iter(offsets.reshape(-1, 2))
    for _ in range(offsets.shape[0]):
        for h in range(height - delta, delta, -1):
            for w in range(width - delta, delta, -1):
                dx, dy = (int(v) for v in next(it))
                h_prime, w_prime = h + dy, w + dx
                x[h, w], x[h_prime, w_prime] = x[h_prime, w_prime], x[h, w]
    assert next(it, None) is None  # every offset used exactly once
    return x


@pytest.mark.parametrize("level", [1, 2, 3, 4, 5])
def test_kernel_matches_literal_loop(level):
    _, delta, iterations = gb.LEVELS[level - 1]
    x = np.random.default_rng(level).integers(0, 256, (13, 17, 3), dtype=np.uint8)
    offsets = gb.swap_offsets(x.shape, delta, iterations, np.random.default_rng(100 + level))
    ours = gb.shuffle_pixels(x.copy(), offsets, delta)
    np.testing.assert_array_equal(ours, literal_shuffle(x.copy(), offsets, delta))


def test_benchmark_swap_copies_instead_of_exchanging():
    # Why the kernel copies (see glass_blur's docstring): with numpy row views the tuple
    # "swap" leaves both pixels equal to the second one.
    x = np.arange(2 * 2 * 3, dtype=np.uint8).reshape(2, 2, 3)
    x[0, 0], x[1, 1] = x[1, 1], x[0, 0]
    assert x[0, 0].tolist() == [9, 10, 11] and x[1, 1].tolist() == [9, 10, 11]


@pytest.mark.parametrize("delta,iterations", [(1, 2), (4, 1)])
def test_offsets_shape_and_range(delta, iterations):
    off = gb.swap_offsets((50, 60, 3), delta, iterations, np.random.default_rng(0))
    assert off.shape == (iterations, 50 - 2 * delta, 60 - 2 * delta, 2)
    assert set(np.unique(off).tolist()) == set(range(-delta, delta))


@pytest.mark.parametrize("level", [1, 3, 5])
def test_pipeline_matches_scikit_image_with_same_offsets(level, monkeypatch):
    from skimage.filters import gaussian as sk_gaussian

    sigma, delta, _ = gb.LEVELS[level - 1]
    # smooth content with flat areas (where truncation after the blur is delicate)
    rng = np.random.default_rng(level)
    x = np.repeat(np.repeat(rng.integers(0, 256, (8, 10, 3), dtype=np.uint8), 6, 0), 7, 1)
    x[:10] = 255
    drawn = []
    real = gb.swap_offsets
    monkeypatch.setattr(gb, "swap_offsets", lambda *a: drawn.append(real(*a)) or drawn[-1])
    ours = corrupt(x, "glass_blur", level, np.random.default_rng(9))

    y = np.uint8(sk_gaussian(x / 255.0, sigma=sigma, channel_axis=-1) * 255)
    y = literal_shuffle(y, drawn[0], delta)
    ref = np.uint8(np.clip(sk_gaussian(y / 255.0, sigma=sigma, channel_axis=-1), 0, 1) * 255)
    diff = np.abs(ours.astype(int) - ref)
    assert diff.max() <= 1 and (diff > 0).mean() < 0.001


# --- the numba cache fallback used by the kernels (corruptions/_jit.py) ------------------
# Only the last resort is offered (no NUMBA_CACHE_DIR, no package or user folder), pointed
# at a folder of the test's own; tests/test_warmup.py runs the whole order in subprocesses.

def _last_resort_only(monkeypatch, folder):
    from robodepth_cli.corruptions import _jit

    monkeypatch.setattr(_jit._Impl, "_locator_classes", [_jit._TempDirLocator])
    monkeypatch.setattr(_jit, "_fallback_cache_dir", lambda: str(folder))
    return _jit


def test_njit_caches_in_a_private_temporary_folder_when_nothing_else_is_writable(monkeypatch, tmp_path):
    _jit = _last_resort_only(monkeypatch, tmp_path / "cache")
    add_one = _jit.njit(lambda a: a + 1)
    assert add_one(1) == 2
    assert add_one.stats.cache_path.startswith(str(tmp_path / "cache"))
    assert (tmp_path / "cache").stat().st_mode & 0o777 == 0o700
    assert sorted(p.suffix for p in (tmp_path / "cache").rglob("*.nb*")) == [".nbc", ".nbi"]


def test_njit_compiles_without_cache_when_nothing_is_writable(monkeypatch, read_only_dir):
    _jit = _last_resort_only(monkeypatch, read_only_dir / "cache")
    add_one = _jit.njit(lambda a: a + 1)
    assert add_one(1) == 2
    assert add_one.stats.cache_path is None  # numba's NullCache: compiled once per process
