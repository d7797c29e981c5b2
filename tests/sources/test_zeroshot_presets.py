"""The zero-shot presets (diode-c, sintel-c, eth3d-c): a small tree in each official layout
and units, written here from the dataset's documentation, then the whole loop build ->
predict -> evaluate -> score, with the ground truth and the metrics worked out by hand."""

from __future__ import annotations

import csv
import struct

import numpy as np
import pytest
from tests.helpers.depth_files import png16
from tests.helpers.trees import random_image, save
from tests.helpers.messages import one_line_error

H, W = 48, 64
PREDICTED = 2.0  # metres: the model below predicts this everywhere

MODEL = f'''
import numpy as np

def constant(images):
    return np.full(images.shape[:3], {PREDICTED}, np.float32)
'''


def _depth(seed, low, high):
    return np.random.default_rng(seed).uniform(low, high, (H, W)).astype(np.float32)


def diode_tree(root):
    """DIODE val: <split>/scene_*/scan_*/<id>.png, <id>_depth.npy (H x W x 1, metres),
    <id>_depth_mask.npy (H x W, 1 valid). Returns {image key: expected ground truth}."""
    want = {}
    for i, (split, name) in enumerate([("indoors", "00019_00183_indoors_000_010"),
                                       ("outdoor", "00022_00193_outdoor_000_000")]):
        folder = root / split / f"scene_000{19 + 3 * i}" / f"scan_00{183 + 10 * i}"
        save(folder / f"{name}.png", random_image(H, W, seed=i))
        d = _depth(i, 0.1, 400.0)
        mask = np.ones((H, W), np.float32)
        mask[10:14, 20:30] = 0
        np.save(folder / f"{name}_depth.npy", d[:, :, None])
        np.save(folder / f"{name}_depth_mask.npy", mask)
        gt = d.copy()
        gt[mask == 0] = np.nan
        want[f"{folder.relative_to(root).as_posix()}/{name}.png"] = gt
    return want


def sintel_tree(root):
    """MPI Sintel training: final/<scene>/frame_NNNN.png and depth/<scene>/frame_NNNN.dpt
    (tag 202021.25, width, height, float32 rows); the clean pass beside it is not built."""
    want = {}
    for i in (1, 2):
        name = f"frame_{i:04d}"
        save(root / "training" / "final" / "alley_1" / f"{name}.png", random_image(H, W, seed=i))
        save(root / "training" / "clean" / "alley_1" / f"{name}.png", random_image(H, W, seed=9))
        d = _depth(i, 0.5, 100.0)  # beyond 70 m is out of the evaluation's range
        path = root / "training" / "depth" / "alley_1" / f"{name}.dpt"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(struct.pack("<fii", 202021.25, W, H) + d.astype("<f4").tobytes())
        want[f"training/final/alley_1/{name}.png"] = d
    return want


def eth3d_tree(root):
    """ETH3D multi-view DSLR: <scene>/images/dslr_images/DSC_NNNN.JPG and, under the same
    name, <scene>/ground_truth_depth/dslr_images/DSC_NNNN.JPG: float32 row-major, the image's
    size, no header, infinity where there is no ground truth."""
    want = {}
    for i, scene in enumerate(["courtyard", "facade"]):
        name = f"DSC_{286 + i:04d}.JPG"
        save(root / scene / "images" / "dslr_images" / f"{name[:-4]}.jpg", random_image(H, W, seed=i))
        (root / scene / "images" / "dslr_images" / f"{name[:-4]}.jpg").rename(
            root / scene / "images" / "dslr_images" / name)
        d = _depth(i, 0.5, 30.0)
        d[:5] = np.inf
        path = root / scene / "ground_truth_depth" / "dslr_images" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(d.astype("<f4").tobytes())
        gt = d.copy()
        gt[:5] = np.nan
        want[f"{scene}/images/dslr_images/{name[:-4]}.png"] = gt
    return want


def scannet_tree(root):
    """ScanNet as SensReader exports a scan: <scene>/color/<n>.jpg and, smaller,
    <scene>/depth/<n>.png (16-bit millimetres, 0 = no depth)."""
    want = {}
    for i, n in enumerate((0, 20)):
        save(root / "scene0707_00" / "color" / f"{n}.jpg", random_image(2 * H, 2 * W, seed=i))
        raw = np.random.default_rng(i).integers(1200, 4000, (H, W)).astype(np.uint16)
        raw[0, :9] = 0
        raw[1, :9] = 15000  # beyond the evaluation's 10 m
        png16(root / "scene0707_00" / "depth" / f"{n}.png", raw)
        gt = raw / 1000.0
        gt[raw == 0] = np.nan
        want[f"scene0707_00/color/{n}.png"] = gt
    return want


def vkitti2_tree(root):
    """Virtual KITTI 2, the RGB and depth downloads in two trees:
    <Scene>/<variation>/frames/rgb/Camera_0/rgb_NNNNN.jpg and
    <Scene>/<variation>/frames/depth/Camera_0/depth_NNNNN.png (16-bit centimetres, 65535
    for the sky); only the clone variation is built."""
    want = {}
    for i, scene in enumerate(["Scene01", "Scene20"]):
        for variation in ("clone", "fog"):
            rgb = root / scene / variation / "frames" / "rgb" / "Camera_0" / f"rgb_{i:05d}.jpg"
            save(rgb, random_image(H, W, seed=i))
        raw = np.random.default_rng(i).integers(50, 12000, (H, W)).astype(np.uint16)
        raw[:4] = 65535
        png16(root.parent / "depth" / scene / "clone" / "frames" / "depth" / "Camera_0"
              / f"depth_{i:05d}.png", raw)
        want[f"{scene}/clone/frames/rgb/Camera_0/rgb_{i:05d}.png"] = raw / 100.0
    return want


def cityscapes_tree(root):
    """Cityscapes val: leftImg8bit/val/<city>/<id>_leftImg8bit.png,
    disparity/val/<city>/<id>_disparity.png (16-bit; disparity (p - 1) / 256 where p > 0) and
    camera/val/<city>/<id>_camera.json (extrinsic.baseline, intrinsic.fx). A train frame
    beside them is not built."""
    want = {}
    for i, (city, frame) in enumerate([("frankfurt", "000000_000294"), ("lindau", "000001_000019")]):
        name = f"{city}_{frame}"
        save(root / "leftImg8bit" / "val" / city / f"{name}_leftImg8bit.png", random_image(H, W, seed=i))
        raw = np.random.default_rng(i).integers(2000, 30000, (H, W)).astype(np.uint16)
        raw[0, :6], raw[1, :6] = 0, 1  # no disparity; a disparity of 0
        png16(root / "disparity" / "val" / city / f"{name}_disparity.png", raw)
        (root / "camera" / "val" / city).mkdir(parents=True, exist_ok=True)
        baseline, fx = 0.209313 + 0.01 * i, 2262.52
        (root / "camera" / "val" / city / f"{name}_camera.json").write_text(
            f'{{"extrinsic": {{"baseline": {baseline}, "pitch": 0.038}}, '
            f'"intrinsic": {{"fx": {fx}, "fy": {fx}, "u0": 1096.98, "v0": 513.137}}}}')
        with np.errstate(divide="ignore"):
            gt = baseline * fx / ((raw.astype(np.float64) - 1) / 256)
        gt[raw <= 1] = np.nan
        want[f"leftImg8bit/val/{city}/{name}_leftImg8bit.png"] = gt
    save(root / "leftImg8bit" / "train" / "aachen" / "aachen_000000_000019_leftImg8bit.png",
         random_image(H, W, seed=7))
    return want


def drivingstereo_tree(root):
    """DrivingStereo's weather sets, each in its folder: <weather>/left-image-full-size/<frame>.jpg
    and <weather>/depth-map-full-size/<frame>.png (16-bit, depth x 256, 0 = none). Returns
    the expected ground truth of the foggy frames, which --split foggy builds."""
    want = {}
    for i, weather in enumerate(("sunny", "cloudy", "foggy", "rainy")):
        for j in range(2 if weather == "foggy" else 1):
            name = f"2018-10-25-07-37-26_2018-10-25-07-4{j}-0{i}-500"
            save(root / weather / "left-image-full-size" / f"{name}.jpg", random_image(H, W, seed=i + j))
            raw = np.random.default_rng(i + j).integers(256, 256 * 6, (H, W)).astype(np.uint16)
            raw[20:, :3] = 0  # no lidar return
            png16(root / weather / "depth-map-full-size" / f"{name}.png", raw)
            gt = raw / 256.0
            gt[raw == 0] = np.nan
            if weather == "foggy":
                want[f"foggy/left-image-full-size/{name}.png"] = gt
    return want


def cityscapes_crop(h, w):
    """ManyDepth's Cityscapes crop: rows H/4 .. 3H/4, columns 3W/32 .. 29W/32 (rows
    256..767 and columns 192..1855 of 1024 x 2048)."""
    inside = np.zeros((h, w), bool)
    inside[int(0.25 * h):int(0.75 * h), int(0.09375 * w):int(0.90625 * w)] = True
    return inside


def eigen_crop(h, w):
    """KITTI's Eigen crop (rows 0.3324324 H .. 0.91351351 H, columns 0.0359477 W ..
    0.96405229 W) as a mask."""
    inside = np.zeros((h, w), bool)
    inside[int(0.3324324 * h):int(0.91351351 * h), int(0.0359477 * w):int(0.96405229 * w)] = True
    return inside


# preset: (tree maker, valid depth range of its evaluation, crop, extra build flags)
PRESETS = {"diode-c": (diode_tree, 0.6, 350.0, None, ()),
           "sintel-c": (sintel_tree, 1e-3, 70.0, None, ()),
           "eth3d-c": (eth3d_tree, 1e-5, 1000.0, None, ()),
           "scannet-c": (scannet_tree, 1e-3, 10.0, None, ()),
           "vkitti2-c": (vkitti2_tree, 1e-5, 80.0, eigen_crop, ("--depth", "{tmp}/depth")),
           "cityscapes-c": (cityscapes_tree, 1e-3, 80.0, cityscapes_crop, ()),
           "drivingstereo-c": (drivingstereo_tree, 1e-3, 80.0, None, ("--split", "foggy"))}


@pytest.mark.parametrize("preset", PRESETS)
def test_whole_loop(preset, tmp_path, cli):
    make, low, high, crop, flags = PRESETS[preset]
    root, out, pred = tmp_path / "root", tmp_path / "out", tmp_path / "pred"
    want = make(root)
    res = cli("build", preset, "--root", root, "--out", out, "--corruptions", "fog,dark",
              "--levels", "1,2", "--jobs", 1, *(f.format(tmp=tmp_path) for f in flags))
    assert res.exit_code == 0, res.output
    built = sorted(p.relative_to(out / "clean").as_posix() for p in (out / "clean").rglob("*.png"))
    assert built == sorted(want)  # exactly the preset's images (not Sintel's clean pass)
    for key, gt in want.items():
        got = np.load(out / "gt" / (key[:-4] + ".npy"))
        np.testing.assert_array_equal(np.isnan(got), np.isnan(gt))
        np.testing.assert_allclose(got[~np.isnan(got)], gt[~np.isnan(gt)], rtol=2e-6)
    assert cli("verify", out).exit_code == 0
    (tmp_path / "m.py").write_text(MODEL)
    res = cli("predict", out, "-m", f"python:{tmp_path / 'm.py'}:constant", "--kind", "depth",
              "--metric", "-o", pred)
    assert res.exit_code == 0, res.output
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    assert f"depths {low:g}..{high:g}" in res.output
    assert f"crop {crop.__name__[:-5] if crop else 'none'}" in res.output
    # By hand: every valid pixel (inside the preset's range, not masked), no crop, the
    # constant prediction; AbsRel and delta1 per image, then their mean.
    abs_rel, a1 = [], []
    for key in sorted(want):
        g = want[key]
        inside = crop(*g.shape) if crop else np.ones(g.shape, bool)
        g = g[(g > low) & (g < high) & inside].astype(np.float64)
        abs_rel.append(np.mean(np.abs(g - PREDICTED) / g))
        a1.append(np.mean(np.maximum(g / PREDICTED, PREDICTED / g) < 1.25))
    with open(tmp_path / "r.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["corruption"], r["level"]) for r in rows] == [
        ("clean", "0"), ("dark", "1"), ("dark", "2"), ("fog", "1"), ("fog", "2")]
    for r in rows:
        assert float(r["abs_rel"]) == pytest.approx(np.mean(abs_rel), rel=1e-5)
        assert float(r["a1"]) == pytest.approx(np.mean(a1), rel=1e-6)
    # the results name their dataset (and split): score needs no --benchmark
    assert {(r["dataset"], r["split"]) for r in rows} == {(preset, "foggy" if "--split" in flags else "")}
    res = cli("score", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    assert f"baseline: none ({preset} has no published one" in res.output
    one_line_error(cli("score", tmp_path / "r.csv", "--benchmark", "kitti-c"),
                    f"--benchmark kitti-c: {tmp_path / 'r.csv'} says its results are on {preset}")
    res = cli("score", tmp_path / "r.csv", "--benchmark", preset)
    assert res.exit_code == 0, res.output
    assert "mRR 100.00" in res.output and "mCE n/a" in res.output


@pytest.mark.parametrize("preset", PRESETS)
def test_a_tree_of_another_dataset_is_refused_before_any_work(preset, tmp_path, cli):
    root, out = tmp_path / "root", tmp_path / "out"
    for name in ("a/x.png", "b/c/y.png", "z.png"):  # images, but not the preset's layout
        save(root / name, random_image(H, W, seed=0))
    (tmp_path / "depth").mkdir()  # vkitti2-c's --depth
    flags = [f.format(tmp=tmp_path) for f in PRESETS[preset][4]]
    res = cli("build", preset, "--root", root, "--out", out, "--corruptions", "fog", "--levels", "1", *flags)
    one_line_error(res, f"{root}: no file matches")
    assert not out.exists()


def test_a_scale_on_float_depth_is_refused_before_any_work(tmp_path, cli):
    # Sintel's .dpt holds metres: --depth-scale 100 made its ground truth 100 times too near
    root, out = tmp_path / "root", tmp_path / "out"
    sintel_tree(root)
    res = cli("build", "sintel-c", "--root", root, "--out", out, "--corruptions", "fog", "--levels", "1",
              "--depth-scale", "100")
    one_line_error(res, "float depth values are metres")
    assert not out.exists()


def test_the_datasets_without_a_published_baseline_are_the_builds_with_depth():
    from robodepth_cli.sources.datasets import DATASETS, unpublished

    assert set(unpublished()) == {n for n, d in DATASETS.items() if d.discovers_sources}


def test_a_real_condition_alone(tmp_path, cli):
    """--corruptions none: the clean images of a real-condition set (DrivingStereo rainy)
    with their ground truth, evaluated on their own."""
    root, out = tmp_path / "root", tmp_path / "out"
    drivingstereo_tree(root)
    res = cli("build", "drivingstereo-c", "--root", root, "--out", out, "--split", "rainy",
              "--corruptions", "none")
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in out.iterdir()) == ["build.json", "clean", "gt", "manifest.csv"]
    assert [p.parent.name for p in (out / "gt").rglob("*.npy")] == ["left-image-full-size"]
    assert cli("verify", out).exit_code == 0
    (tmp_path / "m.py").write_text(MODEL)
    assert cli("predict", out, "-m", f"python:{tmp_path / 'm.py'}:constant", "--kind", "depth",
               "--metric", "-o", tmp_path / "P").exit_code == 0
    res = cli("evaluate", out, "--pred", tmp_path / "P", "--out", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "r.csv").read_text().splitlines()[1].startswith("clean,0,")
    res = cli("build", "drivingstereo-c", "--root", root, "--out", tmp_path / "x", "--split", "snowy")
    assert res.exit_code == 2 and "valid: sunny, cloudy, foggy, rainy, all" in res.output
