"""The depth-aware corruptions on analytic scenes whose result is known without robodepth:
a plane in fog is the transmission formula, a plane at the focal distance stays sharp and
blur grows with |d - f| / d, a fronto-parallel plane under forward motion is a pure zoom
and under sideways motion a pure shift; missing depth is filled, never NaN; same inputs,
same bytes in any process."""

from __future__ import annotations

import hashlib
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from robodepth_cli.corruptions import DEPTH_NAMES, REGISTRY, DepthError, corrupt, render
from robodepth_cli.corruptions.depth import scene_depth

RNG = np.random.default_rng


def smooth_image(h: int, w: int) -> np.ndarray:
    """A smooth colour pattern: bilinear resampling of it is exact to well under a level."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    r = 128 + 100 * np.sin(x / 7.0) * np.cos(y / 9.0)
    g = 128 + 90 * np.cos(x / 11.0 + y / 13.0)
    b = 60 + 2.0 * x % 190
    return np.stack([r, g, np.clip(b, 0, 255)], axis=-1).astype(np.uint8)


def noise_image(h: int, w: int, seed: int = 0) -> np.ndarray:
    return (RNG(seed).random((h, w, 3)) * 255).astype(np.uint8)


def expected_fog(x: np.ndarray, depth_m: float, visibility_m: float) -> np.ndarray:
    beta = -math.log(0.02) / visibility_m  # Koschmieder: 2 % contrast at the visibility
    t = math.exp(-beta * depth_m)
    v = x.astype(np.float64) * t + 0.8 * 255 * (1 - t)
    return np.floor(np.clip(v, 0, 255) + 0.5).astype(np.uint8)


@pytest.mark.parametrize("level,visibility", [(1, 300.0), (3, 75.0), (5, 20.0), (2.5, 112.5)])
def test_fog_on_a_plane_is_the_transmission_formula(level, visibility):
    x = noise_image(32, 48)
    depth = np.full((32, 48), 12.5)
    out = corrupt(x, "fog_3d", level, RNG(0), depth=depth)
    np.testing.assert_array_equal(out, expected_fog(x, 12.5, visibility))


def test_fog_thickens_with_depth_on_two_planes():
    x = noise_image(32, 48)
    depth = np.full((32, 48), 5.0)
    depth[:, 24:] = 60.0
    out = corrupt(x, "fog_3d", 4, RNG(0), depth=depth)
    np.testing.assert_array_equal(out[:, :24], expected_fog(x[:, :24], 5.0, 40.0))
    np.testing.assert_array_equal(out[:, 24:], expected_fog(x[:, 24:], 60.0, 40.0))


def stripes(depths, width: int, height: int = 48) -> np.ndarray:
    return np.repeat(np.asarray(depths, np.float64), width)[None, :].repeat(height, axis=0)


def sharpness(img: np.ndarray) -> float:
    """Mean absolute horizontal plus vertical difference: falls as blur grows."""
    f = img.astype(np.float64)
    return float(np.abs(np.diff(f, axis=1)).mean() + np.abs(np.diff(f, axis=0)).mean())


@pytest.mark.parametrize("name", ["near_focus", "far_focus"])
def test_focal_plane_is_exactly_sharp(name):
    x = noise_image(40, 64)
    out = corrupt(x, name, 5, RNG(0), depth=np.full((40, 64), 3.0))
    np.testing.assert_array_equal(out, x)


@pytest.mark.parametrize("name,depths", [
    # near focus at the 10th percentile: the first stripe (2 m) of eight equal ones
    ("near_focus", [2, 2.5, 3, 4, 5, 7, 10, 20]),
    # far focus at the 90th percentile: the last stripe (40 m)
    ("far_focus", [10, 15, 17, 20, 25, 30, 34, 40]),
])
def test_blur_grows_monotonically_with_distance_from_the_focal_plane(name, depths):
    width = 80  # 640 wide: the level's radius as tabled
    x = noise_image(48, 8 * width)
    depth = stripes(depths, width)
    focus = depths[0] if name == "near_focus" else depths[-1]
    out = corrupt(x, name, 5, RNG(0), depth=depth)
    ratio = [min(1.0, abs(d - focus) / d) for d in depths]
    inner = [slice(k * width + 12, (k + 1) * width - 12) for k in range(8)]
    sharp = [sharpness(out[8:-8, s]) for s in inner]
    order = np.argsort(ratio, kind="stable")
    # the focal stripe keeps its pixels; blur grows (sharpness falls) with |d - f| / d
    k0 = int(order[0])
    np.testing.assert_array_equal(out[:, inner[k0]], x[:, inner[k0]])
    ranked = [sharp[k] for k in order]
    gaps = np.diff([ratio[k] for k in order])
    for a, b, gap in zip(ranked, ranked[1:], gaps):
        if gap > 0.02:
            assert b < a, (name, ratio, sharp)
        else:  # the same radius (capped at R): the same blur
            assert b == pytest.approx(a, rel=0.1)


def test_sharp_near_object_does_not_bleed_over_blurred_background():
    # left: a bright textured plane at 2 m; right: a black wall at 30 m
    x = np.zeros((40, 128, 3), np.uint8)
    x[:, :64] = noise_image(40, 64)[:, :, :] // 2 + 128
    depth = np.full((40, 128), 30.0)
    depth[:, :64] = 2.0
    near = corrupt(x, "near_focus", 5, RNG(0), depth=depth)  # focused at 2 m
    np.testing.assert_array_equal(near[:, :64], x[:, :64])  # the hard edge stays
    assert near[:, 64:].max() == 0  # nothing of the near object spreads over the wall
    far = corrupt(x, "far_focus", 5, RNG(0), depth=depth)  # focused at 30 m, R = 2 px
    # the blurred near object spreads over the wall by at most its radius (+1 anti-alias)
    assert far[:, 64:66].max() > 0 and far[:, 68:].max() == 0


def bilinear(x: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    return np.stack([map_coordinates(x[:, :, c].astype(np.float64), [rows, cols], order=1, mode="nearest")
                     for c in range(3)], axis=-1)


def frames_for(ends0: np.ndarray, ends1: np.ndarray, h: int, w: int) -> int:
    """The documented frame count: one per pixel of the longest path any pixel travels
    inside the image (its straight path between the end positions ``ends0``, ``ends1``,
    (..., 2) arrays of (x, y), measured here by dense sampling), at least 9, odd."""
    t = np.linspace(0.0, 1.0, 4001)[:, None, None]
    longest = 0.0
    for (x0, y0), (x1, y1) in zip(ends0.reshape(-1, 2), ends1.reshape(-1, 2)):
        xs, ys = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
        inside = ((xs >= 0) & (xs <= w - 1) & (ys >= 0) & (ys <= h - 1)).mean()
        longest = max(longest, inside * math.hypot(x1 - x0, y1 - y0))
    n = max(9, math.ceil(longest) + 1)
    return n if n % 2 else n + 1


def test_forward_motion_of_a_fronto_parallel_plane_is_a_pure_zoom():
    h, w, z = 48, 64, 10.0
    x = smooth_image(h, w)
    out = corrupt(x, "zoom_3d", 3, RNG(0), depth=np.full((h, w), z))
    travel = 0.10 * z  # level 3: 0.10 of the median depth
    cy, cx = (h - 1) / 2, (w - 1) / 2
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    ends = [np.stack([cx + (cols - cx) * z / (z - o * travel), cy + (rows - cy) * z / (z - o * travel)], -1)
            for o in (-0.5, 0.5)]
    n = frames_for(*ends, h, w)
    acc = np.zeros((h, w, 3))
    for i in range(n):
        scale = z / (z - (i / (n - 1) - 0.5) * travel)  # a plane at z seen from tz nearer
        acc += bilinear(x, cy + (rows - cy) / scale, cx + (cols - cx) / scale)
    want = np.floor(acc / n + 0.5)
    inner = (slice(4, -4), slice(4, -4))  # zooming out leaves a border the warp fills
    diff = np.abs(out[inner].astype(np.float64) - want[inner])
    assert diff.max() <= 1.0
    assert sharpness(out) < sharpness(x)


def test_sideways_motion_of_a_plane_is_a_pure_shift():
    h, w, z = 48, 64, 7.0
    x = smooth_image(h, w)
    out = corrupt(x, "motion_3d", 2, RNG(0), depth=np.full((h, w), z))
    shift = 10.0 * w / 640  # level 2: 10 px at the median depth, at 640 wide
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    n = frames_for(*[np.stack([cols - o * shift, rows], -1) for o in (-0.5, 0.5)], h, w)
    acc = sum(bilinear(x, rows, cols + (i / (n - 1) - 0.5) * shift) for i in range(n))
    want = np.floor(acc / n + 0.5)
    diff = np.abs(out[:, 3:-3].astype(np.float64) - want[:, 3:-3])
    assert diff.max() <= 1.0


def test_nearer_things_move_more_under_sideways_motion():
    x = noise_image(40, 96)
    depth = np.full((40, 96), 40.0)
    depth[:, 32:64] = 4.0  # a near pillar in front of a far wall; median 40 m
    out = corrupt(x, "motion_3d", 5, RNG(0), depth=depth)
    # far wall: 28 * 96/640 = 4.2 px of motion; pillar 10x as much: far more smeared
    assert sharpness(out[:, 40:56]) < 0.6 * sharpness(out[:, 4:24])


def bands(h: int, w: int, across: bool) -> np.ndarray:
    """Three bands of depth, 2, 20 and 200 m: side by side (left to right) or stacked
    (bottom to top, as a road, a street and the sky are)."""
    depth = np.full((h, w), 200.0)
    if across:
        depth[:, : w // 3], depth[:, w // 3: 2 * w // 3] = 2.0, 20.0
    else:
        depth[2 * h // 3:], depth[h // 3: 2 * h // 3] = 2.0, 20.0
    return depth


@pytest.mark.parametrize("across", [True, False])
def test_sideways_motion_of_bands_smears_only_along_rows(across):
    # The near band moves 10x as far as the median: it uncovers background the source never
    # saw. Whatever fills that, sideways motion keeps every row to itself: changing one row
    # of the image changes only that row of the result.
    h, w = 96, 320
    depth = bands(h, w, across)
    x = noise_image(h, w)
    other = x.copy()
    other[70] = noise_image(1, w, seed=1)[0]  # a row of the near band (or beside it)
    diff = np.abs(corrupt(x, "motion_3d", 5, RNG(0), depth=depth).astype(int)
                  - corrupt(other, "motion_3d", 5, RNG(0), depth=depth).astype(int)).max(axis=(1, 2))
    assert diff[70] > 0
    assert np.flatnonzero(diff).tolist() == [70]


def test_forward_motion_of_bands_draws_one_unbroken_radial_streak():
    # A white 4 x 4 patch on the 2 m band, level 5: travel 0.16 x 20 m, so over the path
    # the patch is seen from 3.6 m down to 0.4 m: 0.56 to 5 times its distance from the
    # centre. Its streak must follow the ray from the centre through it, without gaps (no
    # separate copies) and without lines across it.
    h, w = 96, 320
    depth = bands(h, w, across=True)
    x = np.zeros((h, w, 3), np.uint8)
    x[28:32, 60:64] = 255
    out = corrupt(x, "zoom_3d", 5, RNG(0), depth=depth)[:, :, 0].astype(float)
    cy, cx = (h - 1) / 2, (w - 1) / 2
    py, px = 29.5 - cy, 61.5 - cx  # the patch's centre, from the image centre
    r0 = math.hypot(px, py)
    uy, ux = py / r0, px / r0
    rows, cols = np.mgrid[0:h, 0:w]
    along = (cols - cx) * ux + (rows - cy) * uy
    across = np.abs((cols - cx) * uy - (rows - cy) * ux)
    lit = out > 0
    # the patch, magnified s = along / r0 times, reaches 2 sqrt(2) s from the ray (its
    # half-diagonal), +1.5 for interpolation
    assert (across[lit] <= 2 * math.sqrt(2) * along[lit] / r0 + 1.5).all()
    assert along[lit].min() >= r0 * 2 / 3.6 - 3
    # unbroken: every pixel on the ray from the streak's inner end to the image edge is lit
    edge = min((cx + 0.5) / abs(ux), (cy + 0.5) / abs(uy))
    for r in np.arange(math.ceil(r0 * 2 / 3.6) + 2, edge - 2):
        assert out[int(round(cy + r * uy)), int(round(cx + r * ux))] > 0, r


@pytest.mark.parametrize("name", DEPTH_NAMES)
def test_missing_depth_is_filled_never_nan(name):
    x = noise_image(32, 48)
    depth = np.full((32, 48), 6.0)
    depth[:, 24:] = 18.0
    holey = depth.copy()
    holey[:, 20:24] = np.nan  # nearest valid: the 6 m side
    holey[:, 24:28] = 0.0  # nearest valid: the 18 m side
    holey[0, 0] = np.inf
    want = depth.copy()
    assert np.isfinite(scene_depth(holey, (32, 48))).all()
    np.testing.assert_array_equal(corrupt(x, name, 3, RNG(0), depth=holey),
                                  corrupt(x, name, 3, RNG(0), depth=want))
    none = corrupt(x, name, 3, RNG(0), depth=np.full((32, 48), np.nan))
    assert none.dtype == np.uint8


def test_no_valid_depth_is_a_scene_far_away():
    out = corrupt(noise_image(32, 48), "fog_3d", 1, RNG(0), depth=np.zeros((32, 48)))
    assert (out == 204).all()  # 1 km in 300 m visibility: only airlight


def test_depth_is_needed_and_must_fit():
    x = noise_image(32, 48)
    with pytest.raises(DepthError, match="needs the scene's depth"):
        corrupt(x, "fog_3d", 1, RNG(0))
    with pytest.raises(DepthError, match="aspect ratio"):
        corrupt(x, "fog_3d", 1, RNG(0), depth=np.ones((32, 32)))
    # same aspect ratio, half size: resized by nearest neighbour
    half = np.full((16, 24), 9.0)
    np.testing.assert_array_equal(corrupt(x, "fog_3d", 1, RNG(0), depth=half),
                                  corrupt(x, "fog_3d", 1, RNG(0), depth=np.full((32, 48), 9.0)))
    # the 18 ignore depth
    np.testing.assert_array_equal(corrupt(x, "fog", 1, RNG(0), depth=half), corrupt(x, "fog", 1, RNG(0)))


def test_chains_pass_the_depth_to_their_depth_aware_steps():
    x = noise_image(32, 48)
    depth = np.full((32, 48), 12.5)
    out = render(x, "fog_3d:3+brightness:2", None, seed=0, dataset="t", key="k", depth=depth)
    step = corrupt(expected_fog(x, 12.5, 75.0), "brightness", 2, RNG(0))
    np.testing.assert_array_equal(out, step)
    with pytest.raises(DepthError):
        render(x, "brightness:2+zoom_3d:1", None, seed=0, dataset="t", key="k")


def test_registered_as_depth_aware_with_five_levels():
    assert DEPTH_NAMES == ("fog_3d", "near_focus", "far_focus", "motion_3d", "zoom_3d", "rain_3d")
    for name in DEPTH_NAMES:
        c = REGISTRY[name]
        assert c.needs_depth and c.n_levels == 5
    assert not any(REGISTRY[n].needs_depth for n in list(REGISTRY)[:18])


_DIGESTS = """
import hashlib, numpy as np
from robodepth_cli.corruptions import DEPTH_NAMES, render
x = (np.random.default_rng(7).random((36, 52, 3)) * 255).astype(np.uint8)
d = np.linspace(1.5, 40, 36 * 52).reshape(36, 52); d[:5] = np.nan
for n in DEPTH_NAMES:
    print(n, hashlib.sha256(render(x, n, 2.5, seed=3, dataset="t", key="a", depth=d).tobytes()).hexdigest())
"""


def test_same_inputs_give_the_same_bytes_in_another_process():
    x = (np.random.default_rng(7).random((36, 52, 3)) * 255).astype(np.uint8)
    d = np.linspace(1.5, 40, 36 * 52).reshape(36, 52)
    d[:5] = np.nan
    here = "\n".join(f"{n} {hashlib.sha256(render(x, n, 2.5, seed=3, dataset='t', key='a', depth=d).tobytes()).hexdigest()}"
                     for n in DEPTH_NAMES)
    there = subprocess.run([sys.executable, "-c", _DIGESTS], capture_output=True, text=True, check=True).stdout
    assert there.strip() == here


def test_the_image_only_transforms_refuse_depth_aware_corruptions():
    from robodepth_cli.torch import Corrupt, RandomChain, RandomCorrupt, TorchAPIError

    for make in (lambda: Corrupt("fog_3d", 2), lambda: Corrupt("brightness:1+zoom_3d:2"),
                 lambda: RandomCorrupt(names=["fog", "near_focus"]), lambda: RandomChain(names=["motion_3d", "fog"])):
        with pytest.raises(TorchAPIError, match="needs the scene's depth"):
            make()
    Corrupt("fog", 2)  # the 18 as before
