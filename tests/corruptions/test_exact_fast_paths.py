"""Fused numba passes that replace numpy expressions must give the same bits: the
uint8 truncation every blur and fog ends with, and fog's diamond-square steps (float32
arithmetic in a stated order, so any reordering would show here)."""

from __future__ import annotations

import numpy as np
import pytest

from robodepth_cli.corruptions._ops import truncate_to_uint8
from robodepth_cli.corruptions.fog import plasma_fractal


def numpy_truncate(v, scale):
    out = np.multiply(v, scale)
    np.clip(out, 0.0, 255.0, out=out)
    return out.astype(np.uint8)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("scale", [255.0, 1.0, np.float32(0.7), np.float32(1 / 3), np.float64(0.3)])
def test_truncate_matches_the_numpy_passes(dtype, scale):
    rng = np.random.default_rng(7)
    v = (rng.standard_normal((24, 40, 3)) * 300 + 100).astype(dtype)
    v.flat[:6] = [np.inf, -np.inf, -0.0, 254.99999, 255.0, 1e30]
    with_nan = v.copy()
    with_nan.flat[9] = np.nan
    for a in (v, v / 255, with_nan, v[3:20, 5:30], v[..., 0], v[0, :, 1], v.transpose(1, 0, 2)):
        with np.errstate(invalid="ignore"):
            want = numpy_truncate(a, scale)
            got = truncate_to_uint8(a, scale)
        assert got.dtype == np.uint8 and got.shape == want.shape
        np.testing.assert_array_equal(got, want)


def numpy_plasma(n, decay, rng, shape):
    """The diamond-square rule on the dense grid of each step with numpy float32 arrays: each
    new value ``(((a + b) + c) + d) * 0.25 + (u * 2w^2 - w^2)`` in that order, uniforms per
    step for the centres, then (i s, h + j s), then (h + i s, j s), in C order."""
    grid = np.zeros((1, 1), np.float32)
    wibble, step = 100.0, n
    while True:
        k = grid.shape[0]
        u = [rng.random((k, k), dtype=np.float32) for _ in range(3)]
        sc, sh, q = np.float32(2.0 * wibble * wibble), np.float32(-wibble * wibble), np.float32(0.25)
        down, right = np.roll(grid, -1, 0), np.roll(grid, -1, 1)
        centres = ((grid + down) + right) + np.roll(down, -1, 1)
        centres = centres * q + (u[0] * sc + sh)
        top = ((grid + right) + centres) + np.roll(centres, 1, 0)
        top = top * q + (u[1] * sc + sh)
        left = ((grid + down) + centres) + np.roll(centres, 1, 1)
        left = left * q + (u[2] * sc + sh)
        finer = np.empty((2 * k, 2 * k), np.float32)
        finer[0::2, 0::2], finer[0::2, 1::2] = grid, top
        finer[1::2, 0::2], finer[1::2, 1::2] = left, centres
        grid = finer
        if step == 2:
            break
        step //= 2
        wibble /= decay
    lo, hi = np.float32(grid.min()), np.float32(grid.max())
    out = grid[:shape[0], :shape[1]] - lo
    return out / (hi - lo)


@pytest.mark.parametrize("n,decay,shape", [(2, 2.0, (2, 2)), (8, 1.4, (5, 3)), (64, 1.7, (37, 53)),
                                           (256, 1.5, (48, 256))])
def test_plasma_matches_the_numpy_float32_steps_bit_for_bit(n, decay, shape):
    ours_rng, ref_rng = np.random.default_rng(n), np.random.default_rng(n)
    ours = plasma_fractal(n, decay, ours_rng, shape)
    ref = numpy_plasma(n, decay, ref_rng, shape)
    assert ours.dtype == np.float32 and ours.shape == shape
    np.testing.assert_array_equal(ours.view(np.uint32), ref.view(np.uint32))
    assert ours_rng.random() == ref_rng.random()  # the same number of draws


def test_defocus_direct_kernel_changes_no_byte():
    """Level 1's kernel has subnormal taps; the kernel filtered with instead raises them to
    the least normal float32. Every output float holding a normal term is the same, the rest
    are below 1e-30, so the truncated bytes are the same."""
    import cv2

    from robodepth_cli.corruptions.defocus_blur import direct_kernel, disk_kernel

    k, fast = disk_kernel(3, 0.1), direct_kernel(3, 0.1)
    tiny = np.finfo(np.float32).tiny
    assert ((k > 0) & (k < tiny)).any() and not ((fast > 0) & (fast < tiny)).any()
    assert np.array_equal(k != 0, fast != 0)  # the same taps, so OpenCV sums in the same order
    rng = np.random.default_rng(3)
    images = [rng.integers(0, 256, (48, 64, 3), dtype=np.uint8),
              (rng.random((40, 52, 3)) < 0.03).astype(np.uint8) * rng.integers(1, 256, (40, 52, 3), dtype=np.uint8),
              np.zeros((33, 35, 3), np.uint8)]
    for x in images:
        f = x.astype(np.float32)
        want = cv2.filter2D(f, -1, k, borderType=cv2.BORDER_REFLECT_101)
        got = cv2.filter2D(f, -1, fast, borderType=cv2.BORDER_REFLECT_101)
        differ = want != got
        assert not differ.any() or max(want[differ].max(), got[differ].max()) < 1e-30
        np.testing.assert_array_equal(numpy_truncate(got, 1.0), numpy_truncate(want, 1.0))
    assert direct_kernel(4, 0.5) is disk_kernel(4, 0.5)  # no subnormal taps: used as it is


@pytest.mark.parametrize("level", [1, 2.5, 5])
def test_fog_matches_the_numpy_float32_expression(level):
    """fog's last pass, fused, against ``uint8(clip((P * 255t + x) * m / (m + t)))`` in
    numpy float32 with the same map."""
    from robodepth_cli.corruptions.fog import LEVELS, fog, next_power_of_two
    from robodepth_cli.corruptions.severity import interpolate

    x = np.random.default_rng(5).integers(0, 250, (37, 70, 3), dtype=np.uint8)
    t, d = interpolate(LEVELS, level)
    plasma = plasma_fractal(next_power_of_two(70), d, np.random.default_rng(11), (37, 70))
    m = float(x.max()) / 255.0
    want = numpy_truncate(plasma[:, :, None] * np.float32(255.0 * t) + x, np.float32(m / (m + t)))
    np.testing.assert_array_equal(fog(x, level, np.random.default_rng(11)), want)


class _Uniforms:
    """Stands in for a generator whose float32 uniforms are given."""

    def __init__(self, u):
        self.u = u

    def random(self, shape, dtype=np.float64):
        assert self.u.dtype == dtype
        return self.u.reshape(shape)


@pytest.mark.parametrize("level", [1, 3, 4.2, 5])
def test_impulse_noise_matches_the_numpy_selects(level):
    """The fused select against numpy's ``where(u < a, where(u < a / 2, 0, 255), x)``,
    float32 uniforms compared with the Python thresholds as numpy does, on uniforms right
    at and beside those thresholds."""
    from robodepth_cli.corruptions.impulse_noise import LEVELS, impulse_noise
    from robodepth_cli.corruptions.severity import interpolate

    amount = interpolate(LEVELS, level)
    edges = [np.nextafter(np.float32(t), np.float32(d)) for t in (amount * 0.5, amount)
             for d in (0, t, 1)]
    rng = np.random.default_rng(2)
    x = rng.integers(0, 256, (24, 40, 3), dtype=np.uint8)
    u = rng.random(x.shape, dtype=np.float32)
    u.flat[:len(edges) * 40] = np.repeat(np.array(edges, np.float32), 40)
    want = np.where(u < amount, np.where(u < amount * 0.5, np.uint8(0), np.uint8(255)), x)
    np.testing.assert_array_equal(impulse_noise(x, level, _Uniforms(u.copy())), want)


@pytest.mark.parametrize("law", ["gaussian_noise", "shot_noise", "iso_noise", "dark"])
def test_noise_sampler_is_the_inverse_transform(law):
    """Each element is the first ``j`` with ``u < cdf[k, j]`` (searchsorted on its row),
    whatever guide the search starts from; uniforms at table values and bucket edges too."""
    import importlib

    module = importlib.import_module(f"robodepth_cli.corruptions.{law}")
    table = module.output_law(2, 0, 255) if law == "dark" else module.output_law(2)
    rng = np.random.default_rng(4)
    k = np.repeat(np.arange(256, dtype=np.uint8), 64)
    u = rng.random(k.size)
    u[0::4] = np.minimum(table.cdf[k[0::4], rng.integers(0, 255, k[0::4].size)], 1 - 2.0 ** -53)
    u[1::4] = rng.integers(0, 1024, k[1::4].size) / 1024
    want = np.array([np.searchsorted(table.cdf[a], b, side="right") for a, b in zip(k, u)])
    got = table.sample(k.reshape(128, 128), _Uniforms(u.copy()))
    np.testing.assert_array_equal(got.reshape(-1), want)
