"""Fidelity of the 18 corruptions to the benchmark's formulas.

Two independent references:

* ``tests/data/reference/``: outputs and statistics made with the benchmark's own code on the
  two KITTI-like fixture frames (192 x 640) and two NYU frames (480 x 640), every level.
* the ``imagecorruptions`` package (the oracle for 15 of the 18), run here on other real
  photographs (scikit-image's bundled samples) resized as a build does (Pillow's Lanczos).

Deterministic corruptions are compared pixel for pixel: at least 99% of values within one
level and a mean absolute difference of at most 0.25. Random ones are compared by eight
statistics (per-channel mean and standard deviation of the output, mean absolute
difference from the clean image, standard deviation of the difference): each within
``max(5 * seed_sd, 0.25)`` of the reference mean over seeds.
"""

from __future__ import annotations

import json
from functools import lru_cache

import numpy as np
import pytest
from PIL import Image

from robodepth_cli.corruptions import NAMES, REGISTRY, corrupt
from robodepth_cli.imageio import resize_lanczos

from tests.helpers.paths import REFERENCE

KITTI_KEYS = ("kitti_like_md2", "kitti_like_newyork")
NYU_KEYS = ("nyu_1", "nyu_119")
# The benchmark's 18 (the depth-aware corruptions have their own tests: test_corruptions_depth.py).
DETERMINISTIC = tuple(n for n in NAMES if REGISTRY[n].deterministic)
RANDOM = tuple(n for n in NAMES if not REGISTRY[n].deterministic)

# The oracle implements these 15 of our 18 (dark, color_quant and iso_noise are the
# benchmark's own additions, covered by tests/data/reference only).
ORACLE_NAMES = (
    "brightness", "fog", "frost", "snow", "contrast", "defocus_blur", "glass_blur",
    "motion_blur", "zoom_blur", "elastic_transform", "gaussian_noise", "impulse_noise",
    "shot_noise", "pixelate", "jpeg_compression",
)
ORACLE_SEEDS = 6
# Our side of a statistics comparison is the mean over a few seeds: the reference's spread
# is estimated from only 6-8 seeds and is sometimes well below the true one (motion blur's
# angle, the noise figures), so a single draw of ours would fail by chance about once per
# few hundred figures even for an exact implementation.
OUR_SEEDS = 4


def _load(path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).copy()


def stats(out: np.ndarray, clean: np.ndarray) -> np.ndarray:
    """The eight figures of ``tests/data/README.md`` (reference statistics), in its order."""
    o = out.astype(np.float64)
    d = o - clean.astype(np.float64)
    return np.array([
        *o.mean(axis=(0, 1)), *o.std(axis=(0, 1)), np.abs(d).mean(), d.std(),
    ])


def our_stats(clean: np.ndarray, name: str, level: int, seed: int) -> np.ndarray:
    """Mean of the eight figures over ``OUR_SEEDS`` generators derived from ``seed``."""
    return np.mean([stats(corrupt(clean, name, level, np.random.default_rng([seed, k])), clean)
                    for k in range(OUR_SEEDS)], axis=0)


def assert_pixels_match(ours: np.ndarray, ref: np.ndarray, what: str) -> None:
    assert ours.shape == ref.shape, what
    diff = np.abs(ours.astype(np.int16) - ref.astype(np.int16))
    within = float((diff <= 1).mean())
    mad = float(diff.mean())
    assert within >= 0.99 and mad <= 0.25, (
        f"{what}: {within:.4%} of values within one level (need 99%), "
        f"mean abs diff {mad:.3f} (need <= 0.25), max diff {int(diff.max())}")


def assert_stats_match(ours: np.ndarray, mean, sd, what: str) -> None:
    mean, sd = np.asarray(mean, float), np.asarray(sd, float)
    tol = np.maximum(5 * sd, 0.25)
    bad = np.abs(ours - mean) > tol
    fields = ("mean_r", "mean_g", "mean_b", "std_r", "std_g", "std_b", "mad", "sd_diff")
    assert not bad.any(), what + ": " + "; ".join(
        f"{f} ours {o:.3f} ref {m:.3f} +- {t:.3f}"
        for f, o, m, t, b in zip(fields, ours, mean, tol, bad) if b)


def assert_matches(clean, name, level, what, *, expected_pixels, expected_stats, seed) -> None:
    """Pixels for a deterministic corruption, statistics over seeds for a random one."""
    if REGISTRY[name].deterministic:
        out = corrupt(clean, name, level, np.random.default_rng(seed))
        assert_pixels_match(out, expected_pixels(), what)
    else:
        mean, sd = expected_stats()
        assert_stats_match(our_stats(clean, name, level, seed), mean, sd, what)


# --- tests/data/reference -------------------------------------------------------------

@lru_cache(maxsize=None)
def _reference_stats(folder: str) -> dict:
    return json.loads((REFERENCE / folder / "stats.json").read_text())["stats"]


@lru_cache(maxsize=None)
def _reference_input(folder: str, key: str) -> np.ndarray:
    return _load(REFERENCE / folder / f"{key}__input.png")


def _reference_cases():
    for folder, keys, names, levels in (("kitti", KITTI_KEYS, NAMES, 5),
                                        # NYUDepth2-C uses 15 of them, but the
                                        # reference covers all 18 at levels 1..4.
                                        ("nyu", NYU_KEYS, NAMES, 4)):
        for name in names:
            for key in keys:
                for level in range(1, levels + 1):
                    yield pytest.param(folder, key, name, level, id=f"{name}-{key}-{level}")


@pytest.mark.parametrize("folder,key,name,level", list(_reference_cases()))
def test_matches_reference(folder, key, name, level):
    def reference_stats():
        ref = _reference_stats(folder)[f"{key}/{name}/{level}"]
        return ref["mean"], ref["sd"]

    assert_matches(_reference_input(folder, key), name, level, f"{name} level {level} on {key}",
                   expected_pixels=lambda: _load(REFERENCE / folder / f"{key}__{name}__{level}.png"),
                   expected_stats=reference_stats, seed=level * 1009 + len(key))


def test_reference_covers_every_corruption():
    kitti = {k.split("/")[1] for k in _reference_stats("kitti")}
    nyu = {k.split("/")[1] for k in _reference_stats("nyu")}
    assert kitti == set(NAMES)
    assert nyu == set(NAMES)


# --- the imagecorruptions oracle on other photographs ----------------------------------

# Other real photographs than the reference's, one per output size.
PHOTOS = (("coffee", (192, 640)), ("astronaut", (480, 640)))


@lru_cache(maxsize=None)
def _photo(sample: str, size_hw) -> np.ndarray:
    from skimage import data

    return resize_lanczos(Image.fromarray(getattr(data, sample)()).convert("RGB"), size_hw)


def _oracle_once(clean: np.ndarray, name: str, level: int, seed: int) -> np.ndarray:
    import imagecorruptions

    np.random.seed(seed)
    kwargs = {}
    if name in ("glass_blur", "impulse_noise"):
        # Neither follows numpy.random.seed (see DEVELOPERS.md): give them the seed directly.
        kwargs["seed"] = seed
    return imagecorruptions.corrupt(clean, severity=level, corruption_name=name, **kwargs)


@lru_cache(maxsize=None)
def _oracle_stats(sample: str, size_hw, name: str, level: int):
    clean = _photo(sample, size_hw)
    runs = np.array([stats(_oracle_once(clean, name, level, 1000 + s), clean)
                     for s in range(ORACLE_SEEDS)])
    # ddof=1: the spread of a small sample of seeds.
    return runs.mean(axis=0), runs.std(axis=0, ddof=1)


def _oracle_cases():
    for sample, size in PHOTOS:
        for name in ORACLE_NAMES:
            for level in range(1, 6):
                yield pytest.param(sample, size, name, level, id=f"{name}-{sample}-{size[0]}x{size[1]}-{level}")


@pytest.mark.parametrize("sample,size_hw,name,level", list(_oracle_cases()))
def test_matches_oracle(sample, size_hw, name, level):
    clean = _photo(sample, size_hw)
    assert_matches(clean, name, level,
                   f"{name} level {level} on {sample} at {size_hw[0]}x{size_hw[1]} vs imagecorruptions",
                   expected_pixels=lambda: _oracle_once(clean, name, level, 0),
                   expected_stats=lambda: _oracle_stats(sample, size_hw, name, level),
                   seed=7 * level)
