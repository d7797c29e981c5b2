"""The evaluation's fast paths against the way it was computed before them: the whole
prediction resized with cv2.resize (INTER_LINEAR), the valid pixels masked, aligned and
scored with numpy, step by step from the protocols' rules (monodepth2's evaluate_depth.py,
BTS's and AdaBins's evaluators). Every metric of every mode within 1e-6 relative, and the
threshold accuracies a1..a3 and the median-scaling ratio exactly, since the depths
compared are the same numbers; predictions are drawn with many pixels right next to the
thresholds, where one rounding differently would move a count."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from robodepth_cli.evaluation.image import image_errors
from robodepth_cli.evaluation.kernels import median, sample_linear
from robodepth_cli.evaluation.protocols import crop_box, make_setup
from tests.helpers.evaluation import ref_errors

METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3", "log10", "silog")


def reference_align(v, g, is_disp, align, space, stereo, lo, hi):
    """The alignment rules: p and g in depth or disparity space; none (x 5.4 stereo),
    median, least-squares scale, scale and shift (float64); back to depth (a
    non-positive disparity is max depth); clamped to [lo, hi]. Returns (d, ratio)."""
    p, gg = ((1 / v if is_disp else v), g) if space == "depth" else ((v if is_disp else 1 / v), 1 / g)
    ratio = None
    if align == "none":
        a = p * 5.4 if stereo else p
    elif align == "median":
        ratio = np.median(gg) / np.median(p)
        a = p * ratio
    elif align == "scale":
        p64, g64 = p.astype(np.float64), gg.astype(np.float64)
        a = p64 * (np.dot(p64, g64) / np.dot(p64, p64))
    else:
        p64, g64 = p.astype(np.float64), gg.astype(np.float64)
        dp = p64 - p64.mean()
        s = np.dot(dp, g64 - g64.mean()) / np.dot(dp, dp)
        a = p64 * s + (g64.mean() - s * p64.mean())
    if space == "disparity":
        a = np.where(a > 0, 1 / np.where(a > 0, a, 1), hi).astype(a.dtype)
    d = a.copy()
    d[d < lo] = lo
    d[d > hi] = hi
    return d, ratio


def reference_image(pred, gt, protocol, kind, stereo, align, space, crop, lo, hi):
    """The previous way: the whole map resized to the ground truth's size (kitti), then
    masked, aligned and scored."""
    h, w = gt.shape
    if kind == "sigmoid":
        pred = 1 / 100 + (1 / 0.1 - 1 / 100) * pred
    if protocol == "kitti" and pred.shape != gt.shape:
        pred = cv2.resize(pred, (w, h), interpolation=cv2.INTER_LINEAR)
    top, bottom, left, right = crop_box(crop, protocol, h, w)
    inside = np.zeros(gt.shape, bool)
    inside[top:bottom, left:right] = True
    mask = (gt > lo) & (gt < hi) & inside
    d, ratio = reference_align(pred[mask], gt[mask], kind != "depth", align, space, stereo, lo, hi)
    return ref_errors(gt[mask], d, protocol == "nyu"), ratio


def near_thresholds(gt, rng, factor=1.0):
    """Depths ``factor * gt * 1.25^k * (1 +- a few float32 steps)``, k in 0..3, on 60% of
    the pixels (the rest noisy): ratios on both sides of each threshold."""
    k = rng.integers(0, 4, gt.shape)
    steps = rng.integers(-3, 4, gt.shape) * np.float32(2 ** -23)
    d = (gt * np.float32(factor) * np.float32(1.25) ** k * (1 + steps)).astype(np.float32)
    noisy = rng.random(gt.shape) < 0.4
    d[noisy] = (gt[noisy] * rng.uniform(0.5, 2, noisy.sum())).astype(np.float32)
    return np.where(gt > 0, d, rng.uniform(1, 80, gt.shape)).astype(np.float32)


def lidar(shape, rng, density=0.08):
    g = rng.uniform(0.5, 90, shape).astype(np.float32)
    g[rng.random(shape) > density] = 0
    return g


def check(got, want, nyu):
    got, want = np.asarray(got, np.float64), np.asarray(want, np.float64)
    n = 9 if nyu else 7
    assert got.shape == want.shape == (n,)
    np.testing.assert_array_equal(got[4:7], want[4:7], err_msg="a1..a3")
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0, err_msg=str(METRICS[:n]))


# --------------------------------------------------------------------------- sampling

@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_sampling_is_cv2_resize_at_the_valid_pixels(dtype):
    """sample_linear at every pixel (edges included) against the whole resize: upsizing,
    downsizing, odd sizes and KITTI's; float32 bit for bit, float64 to 1e-12 (OpenCV rounds
    float64 weights otherwise in a few pixels, by a path of its own on small maps)."""
    rng = np.random.default_rng(3)
    sizes = [((192, 640), (375, 1242)), ((192, 640), (370, 1226)), ((1024, 2048), (375, 1242)),
             ((375, 1242), (375, 1242)), ((13, 17), (40, 33)), ((96, 320), (375, 1242)), ((3, 2), (7, 11))]
    sizes += [(tuple(rng.integers(2, 300, 2)), tuple(rng.integers(2, 300, 2))) for _ in range(8)]
    for (h, w), (H, W) in sizes:
        pred = rng.uniform(0.01, 0.3, (h, w)).astype(dtype)
        want = cv2.resize(pred, (int(W), int(H)), interpolation=cv2.INTER_LINEAR).reshape(-1)
        every = np.arange(H * W)
        got = sample_linear(pred, (H, W), every)
        assert got.dtype == dtype
        if dtype is np.float32:
            np.testing.assert_array_equal(got, want, err_msg=f"{h}x{w} -> {H}x{W}")
        else:
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
        some = np.sort(rng.choice(H * W, size=min(500, H * W), replace=False))
        np.testing.assert_array_equal(sample_linear(pred, (H, W), some), got[some])
        unsorted = rng.permutation(some)
        np.testing.assert_array_equal(sample_linear(pred, (H, W), unsorted), got[unsorted])


def test_median_is_numpys():
    rng = np.random.default_rng(0)
    for values in (rng.uniform(0, 1, 15001).astype(np.float32), rng.integers(0, 5, 4000).astype(np.float32),
                   rng.uniform(0, 1, 10).astype(np.float64), np.array([np.float32(3)]),
                   np.array([1, np.inf], np.float32), np.sort(rng.uniform(0, 1, 999)).astype(np.float32)):
        for n in (1, 2, 3, 4, len(values) - 1, len(values)):
            if n >= 1 and n <= len(values):
                got, want = median(values[:n]), np.median(values[:n])
                assert got == want and got.dtype == want.dtype, (values.dtype, n)


MEDIANS_ELSEWHERE = """
import numpy as np
from robodepth_cli.evaluation.kernels import median
rng = np.random.default_rng(7)
for values in (rng.uniform(0, 1, 20001), rng.integers(0, 4, 9000).astype(float), np.sort(rng.uniform(0, 1, 8193))):
    for dtype in (np.float32, np.float64):
        v = values.astype(dtype)
        assert median(v) == np.median(v), (v.size, dtype)
print("same")
"""


def test_the_median_is_numpys_on_a_cpu_without_avx512():
    # The cut to the middle values stores them with LLVM's masked compress-store, one
    # instruction with AVX-512; numba's generic CPU has it done lane by lane.
    import os
    import subprocess
    import sys

    from tests.helpers.paths import REPO
    from tests.helpers.simd import stand_ins

    done = subprocess.run([sys.executable, "-c", MEDIANS_ELSEWHERE], env={**os.environ, **stand_ins()["numba"]},
                          cwd=REPO, capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == "same", done.stderr[-2000:]


# --------------------------------------------------------------------------- kitti modes

KITTI_MODES = [  # (kind, stereo, align, space, crop, min, max)
    ("disp", False, None, "depth", None, None, None),  # mono: median scaling
    ("disp", True, None, "depth", None, None, None),  # stereo: x 5.4
    ("sigmoid", False, None, "depth", None, None, None),
    ("depth", True, None, "depth", None, None, None),
    ("depth", False, "median", "depth", None, None, None),
    ("disp", False, "none", "depth", "eigen", None, None),
    ("disp", False, "scale", "depth", "garg", None, None),
    ("disp", False, "scale-shift", "depth", "none", None, None),
    ("disp", False, "median", "disparity", "cityscapes", None, None),
    ("depth", False, "scale", "disparity", "garg", 0.5, 50.0),
    ("sigmoid", False, "scale-shift", "disparity", "eigen", None, None),
    ("disp", False, None, "depth", "none", 0.1, 30.0),
]


@pytest.mark.parametrize("mode", KITTI_MODES, ids=lambda m: "-".join(str(x) for x in m))
def test_kitti_modes_match_the_full_resize(mode):
    kind, stereo, align, space, crop, lo, hi = mode
    setup = make_setup("kitti", kind, stereo, align=align, align_space=space, crop=crop,
                       min_depth=lo, max_depth=hi)
    rng = np.random.default_rng(hash(mode) % 2 ** 32)
    for shape, size in (((375, 1242), (192, 640)), ((370, 1226), (375, 1242)), ((120, 200), (64, 96))):
        gt = lidar(shape, rng)
        depth = cv2.resize(near_thresholds(gt, rng), (size[1], size[0]), interpolation=cv2.INTER_NEAREST)
        if kind == "depth":
            pred = depth
        elif kind == "disp":
            pred = (1 / depth).astype(np.float32)
        else:
            pred = ((1 / depth - 0.01) / 9.99).clip(0, 1).astype(np.float32)
        for p in (pred, pred.astype(np.float64)):
            index = setup.valid(gt)
            got, ratio = image_errors(p, "p", (gt.shape, index, gt.reshape(-1)[index]), setup, None)
            want, want_ratio = reference_image(p, gt, "kitti", kind, stereo, setup.alignment, space,
                                               setup.crop_name, setup.min_depth, setup.depth_cap)
            check(got, want, False)
            assert ratio == want_ratio if setup.median_scaling else ratio is None


def test_kitti_at_the_ground_truth_size_counts_the_thresholds_as_before():
    """A prediction of the ground truth's size is not resized: depths a few float32 steps
    either side of each threshold count exactly as before (stereo, so no median moves them)."""
    rng = np.random.default_rng(7)
    gt = lidar((375, 1242), rng, 0.2)
    setup = make_setup("kitti", "depth", stereo=True)
    pred = (near_thresholds(gt, rng) / np.float32(5.4)).astype(np.float32)
    index = setup.valid(gt)
    got, _ = image_errors(pred, "p", (gt.shape, index, gt.reshape(-1)[index]), setup, None)
    want, _ = reference_image(pred, gt, "kitti", "depth", True, "none", "depth", "garg", 1e-3, 80)
    check(got, want, False)
    assert 0.3 < got[4] < 0.9  # many pixels right at the first threshold, on both sides


# --------------------------------------------------------------------------- nyu

@pytest.mark.parametrize("align, crop", [(None, None), (None, "none"), ("median", None), ("scale-shift", "garg")])
def test_nyu_whole_map_pass_matches_the_masked_arrays(align, crop):
    """The one-pass judgement of a map kept whole (16-bit millimetres, as NYU's PNGs), and
    the per-pixel path of the aligning setups, against the masked arrays: 1 mm (exactly
    the depth floor in float32, so invalid), holes, depths past 10 m, predictions past
    the clamp on both sides."""
    setup = make_setup("nyu", "depth", align=align, crop=crop)
    rng = np.random.default_rng(11)
    raw = rng.integers(0, 12000, (480, 640)).astype(np.uint16)
    raw[rng.random(raw.shape) < 0.1] = 0
    raw[rng.random(raw.shape) < 0.01] = 1
    gt = raw.astype(np.float32) / 1000.0
    pred = near_thresholds(np.maximum(gt, 0.01), rng)
    pred[rng.random(pred.shape) < 0.01] = 0.0005
    pred[rng.random(pred.shape) < 0.01] = 12.0
    want, _ = reference_image(pred, gt, "nyu", "depth", False, setup.alignment, "depth", setup.crop_name,
                              setup.min_depth, setup.depth_cap)
    got, ratio = image_errors(pred, "p", None, setup, None, whole=(raw, 1000.0))
    check(got, want, True)
    index = setup.valid(gt)
    again, _ = image_errors(pred, "p", (gt.shape, index, gt.reshape(-1)[index]), setup, None)
    check(again, want, True)


def test_a_prediction_with_nan_is_still_refused_in_the_one_pass():
    from robodepth_cli.evaluation.protocols import EvaluationError

    setup = make_setup("nyu")
    raw = np.full((480, 640), 2000, np.uint16)
    pred = np.full((480, 640), 2.0, np.float32)
    pred[100, 100] = np.nan
    with pytest.raises(EvaluationError, match="contains NaN"):
        image_errors(pred, "p.npy", None, setup, None, whole=(raw, 1000.0))


# --------------------------------------------------------------------------- predictions

def test_a_variants_npy_is_mapped_not_copied(tmp_path):
    """Each map of a variant's N x H x W .npy is a read-only view of the mapped file (no
    copy), the same values read in any order, including a map read again after its pages
    were released; a file shorter than its header says is refused before any map is read."""
    from robodepth_cli.predictions import ArrayPredictions, PredictionsError

    arr = np.random.default_rng(0).uniform(0, 1, (6, 48, 64)).astype(np.float32)
    np.save(tmp_path / "clean.npy", arr)
    variant = type("V", (), {"label": "clean", "__len__": lambda self: 6})()
    preds = ArrayPredictions(variant, tmp_path / "clean.npy")
    for i in (0, 1, 2, 5, 1, 0, 4):
        m, where, is_png = preds.read(i)
        assert not m.flags.writeable and not m.flags.owndata and isinstance(m.base, np.memmap)
        np.testing.assert_array_equal(m, arr[i])
    preds.close()
    data = (tmp_path / "clean.npy").read_bytes()
    (tmp_path / "cut.npy").write_bytes(data[:-100])
    with pytest.raises(PredictionsError, match=r"cut\.npy: the file ends early"):
        ArrayPredictions(variant, tmp_path / "cut.npy")


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_metrics_without_numba_are_the_kernels(dtype):
    """A scoring program on an image without numba (Codabench's) takes numpy's form of the
    metrics: the same terms and float64 sums, so the same numbers to far below 1e-6."""
    from robodepth_cli.evaluation import protocols as P

    rng = np.random.default_rng(3)
    gt = rng.uniform(1e-3, 80, 5000).astype(dtype)
    ratio = np.concatenate([rng.uniform(0.5, 2.0, 4000), np.repeat([1.25, 1.25 ** 2, 1.25 ** 3, 1.0], 250)])
    pred = (gt * ratio.astype(dtype)).astype(dtype)
    assert P._numpy_errors(gt, pred, True) == pytest.approx(P.nyu_errors(gt, pred), rel=1e-9)
    assert P._numpy_errors(gt, pred, False) == pytest.approx(P.depth_errors(gt, pred), rel=1e-9)


@pytest.mark.slow
def test_the_results_are_the_same_bytes_with_simd_switched_off(kitti_c, kitti_pred, cli, tmp_path):
    """The metrics are the same numbers on any CPU: the results CSV of an evaluation run with
    every library's SIMD paths off (and numba's generic CPU) is byte-equal to this CPU's."""
    import os
    import subprocess
    import sys

    from tests.helpers.paths import REPO
    from tests.helpers.simd import stand_ins

    build, _ = kitti_c
    here, there = tmp_path / "here.csv", tmp_path / "there.csv"
    assert cli("evaluate", build, "--pred", kitti_pred, "--out", here, "--jobs", "1").exit_code == 0
    done = subprocess.run([sys.executable, "-m", "robodepth_cli.cli", "evaluate", str(build), "--pred",
                           str(kitti_pred), "--out", str(there), "--jobs", "1"],
                          env={**os.environ, **stand_ins()["all"]}, cwd=REPO, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert there.read_bytes() == here.read_bytes()


# --------------------------------------------------------------------------- a variant's blocks

BLOCK_MODES = [  # (protocol, kind, stereo, align, crop, min, max)
    ("kitti", "disp", False, None, None, None, None),  # mono: median scaling
    ("kitti", "disp", True, None, None, None, None),
    ("kitti", "sigmoid", False, None, None, None, None),
    ("kitti", "depth", False, "none", "eigen", None, None),
    ("kitti", "disp", False, None, "none", 0.5, 30.0),  # a zero-shot preset's range, no crop
    ("nyu", "depth", False, None, None, None, None),
    ("nyu", "depth", False, None, "garg", None, 5.0),
]


@pytest.mark.parametrize("mode", BLOCK_MODES, ids=lambda m: "-".join(str(x) for x in m))
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_a_variants_maps_judged_in_blocks_are_the_reference_per_map(mode, dtype, tmp_path):
    """evaluate's block calls (a variant's mapped N x h x w array, several maps a call)
    against the reference, map by map: KITTI ground truth of two sizes with even and odd
    counts of valid pixels (the median's two rules), predictions right next to the
    thresholds; NYU's whole 16-bit maps, and one kept as its valid pixels. A map the block
    call refuses (a NaN) is refused with the per-map message, and the others still count."""
    from robodepth_cli.evaluation.batch import BLOCK, plan
    from robodepth_cli.evaluation.evaluate import _evaluate_variant
    from robodepth_cli.groundtruth.read import GroundTruth
    from robodepth_cli.predictions import ArrayPredictions

    protocol, kind, stereo, align, crop, lo, hi = mode
    setup = make_setup(protocol, kind, stereo, align=align, crop=crop, min_depth=lo, max_depth=hi)
    rng = np.random.default_rng(sum(map(ord, str(mode))))
    n = BLOCK + 5  # two blocks, the second short
    truth, maps = GroundTruth("gt", protocol, setup.valid), []
    size = (192, 640) if protocol == "kitti" else (480, 640)
    for i in range(n):
        if protocol == "kitti":
            gt = lidar((375, 1242) if i % 3 else (370, 1226), rng)
            index = setup.valid(gt)
            if index.size % 2 != i % 2:  # the even rule on every other map
                gt.reshape(-1)[index[0]] = 0
            truth.add(gt)
        else:
            raw = rng.integers(0, int(setup.depth_cap * 1200), size).astype(np.uint16)
            raw[rng.random(size) < (0.995 if i == 3 else 0.1)] = 0  # map 3: kept as its pixels
            gt = raw.astype(np.float32) / np.float32(1000)
            truth.add(gt, raw, 1000.0)
        depth = near_thresholds(np.where(gt > 0, gt, 1).astype(np.float32), rng)
        depth = cv2.resize(depth, (size[1], size[0]), interpolation=cv2.INTER_NEAREST)
        pred = {"disp": 1 / depth, "depth": depth, "sigmoid": ((1 / depth - 0.01) / 9.99).clip(0, 1)}[kind]
        maps.append((pred.astype(dtype), gt))
    assert truth.dense(3) is None and (protocol == "kitti" or truth.dense(4) is not None)
    np.save(tmp_path / "v.npy", np.stack([p for p, _ in maps]))
    variant = type("V", (), {"label": "v", "__len__": lambda self: n})()
    preds = ArrayPredictions(variant, tmp_path / "v.npy")
    blocks = plan(preds, truth, setup, {})
    ok, out, ratios = blocks.judge(preds.block(0, n), 0, n)
    assert ok.all()
    for i, (pred, gt) in enumerate(maps):
        want, want_ratio = reference_image(pred, gt, protocol, kind, stereo, setup.alignment, "depth",
                                           setup.crop_name, setup.min_depth, setup.depth_cap)
        check(out[i, :len(setup.metrics)], want, protocol == "nyu")
        if setup.median_scaling:
            assert ratios[i] == want_ratio
    # The whole variant as evaluate judges it, with a NaN in map 6: refused by name.
    bad = np.stack([p for p, _ in maps])
    bad[6, 5, 5] = np.nan
    np.save(tmp_path / "bad.npy", bad)
    with pytest.raises(Exception, match=r"bad\.npy: prediction 6 contains NaN"):
        _evaluate_variant(variant, ArrayPredictions(variant, tmp_path / "bad.npy"), truth, setup, None, None)
    result = _evaluate_variant(variant, preds, truth, setup, None, None)
    want = np.mean([reference_image(p, g, protocol, kind, stereo, setup.alignment, "depth", setup.crop_name,
                                    setup.min_depth, setup.depth_cap)[0] for p, g in maps], axis=0)
    np.testing.assert_allclose([result.metrics[m] for m in setup.metrics], want, rtol=1e-6, atol=0)


def test_the_median_of_many_values_is_numpys():
    """The median's cut to the values near the middle (arrays of 4096 values and more) and
    its selection, against numpy: even and odd counts, ties, sorted and reversed values, a
    strided pattern that puts the sample's values far from the middle (the whole array is
    then selected), infinities; the input is left as it was."""
    rng = np.random.default_rng(5)
    arrays = [rng.uniform(0, 1, 20000), rng.integers(0, 4, 9001).astype(float), np.sort(rng.uniform(0, 1, 8192)),
              np.sort(rng.uniform(0, 1, 8193))[::-1].copy(), np.where(rng.random(6000) < 0.5, 0.0, np.inf),
              np.tile([0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 9.0, 9.0], 1024)]
    strided = np.full(8192, 5.0)
    strided[::16] = 0.0  # every sampled value is the smallest
    arrays.append(strided)
    for values in arrays:
        for dtype in (np.float32, np.float64):
            for v in (values.astype(dtype), values[1:].astype(dtype)):
                before = v.copy()
                got, want = median(v), np.median(v)
                assert got == want and got.dtype == want.dtype, (v.size, v[:4])
                np.testing.assert_array_equal(v, before)
