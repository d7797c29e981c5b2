"""Depth-aware corruptions on builds with a depth folder (`build custom --depth`, the
zero-shot presets) and from a model's predictions (`--scene-depth PRED`), with the depth
source in build.json and the manifest, and the warning of score and report when a model is
judged on corruptions made from its own depth."""

from __future__ import annotations

import json
import math
import struct

import numpy as np
import pytest
from tests.helpers.manifest import manifest_by_output
from tests.helpers.trees import random_image, save
from tests.helpers.depth_files import depth_stamp
from PIL import Image
from scipy.ndimage import distance_transform_edt

H, W = 48, 64
MODEL = '''
import numpy as np

def metric(images):
    return np.full(images.shape[:3], 7.0, np.float32)

def relative(images):
    return np.full(images.shape[:3], 0.25, np.float32)
'''


def fog_by_hand(clean, depth, visibility):
    """Koschmieder's transmission towards a 0.8 * 255 airlight, rounded half up."""
    t = np.exp(math.log(0.02) / visibility * np.clip(depth, 0.05, 1000.0))[..., None]
    return np.floor(np.clip(clean * t + 204.0 * (1 - t), 0, 255) + 0.5).astype(np.uint8)


def folder(tmp_path, depths):
    """Images img/<name>.png (H x W) and, where given, depth/<name>.npy in metres."""
    for i, (name, d) in enumerate(depths.items()):
        save(tmp_path / "img" / f"{name}.png", random_image(H, W, seed=i))
        if d is not None:
            (tmp_path / "depth").mkdir(exist_ok=True)
            np.save(tmp_path / "depth" / f"{name}.npy", d)
    return tmp_path / "img", tmp_path / "depth"


def clean_of(out, key):
    return np.asarray(Image.open(out / "clean" / key), dtype=np.float64)


def test_custom_depth_folder_fog_is_the_transmission_formula(tmp_path, cli):
    img, depth = folder(tmp_path, {"a": np.full((H, W), 12.0, np.float32), "b": None})
    out = tmp_path / "out"
    res = cli("build", "custom", "--root", img, "--depth", depth, "--out", out, "--size", "32x96",
              "--corruptions", "fog_3d,brightness", "--levels", "4", "--jobs", 1)
    assert res.exit_code == 1, res.output  # b has no depth map
    want = fog_by_hand(clean_of(out, "a.png"), np.full((32, 96), 12.0), 40.0)  # level 4: V = 40 m
    np.testing.assert_array_equal(np.asarray(Image.open(out / "fog_3d" / "4" / "a.png")), want)
    r = manifest_by_output(out)
    # only b's depth-aware output (and its ground truth) failed, naming the missing file
    assert sorted(o for o, row in r.items() if row["error"]) == ["fog_3d/4/b.png", "gt/b.npy"]
    assert "b" in r["fog_3d/4/b.png"]["error"] and "no depth file" in r["fog_3d/4/b.png"]["error"]
    assert r["fog_3d/4/a.png"]["params"] == f"depth=depth-folder/v1;map={depth_stamp(depth / 'a.npy')}"
    assert r["brightness/4/a.png"]["params"] == ""
    record = json.loads((out / "build.json").read_text())
    assert record["depth"]["kind"] == "depth-folder" and record["depth"]["directory"] == str(depth)


def test_depth_resized_by_nearest_after_filling_holes(tmp_path, cli):
    d = np.where(np.arange(W)[None, :] < W // 2, 5.0, 50.0) * np.ones((H, 1))
    d[20:30, 10:20] = np.nan  # a hole inside the near half
    d[0:4, 40:60] = 0.0  # no measurement
    img, depth = folder(tmp_path, {"a": d.astype(np.float32)})
    out = tmp_path / "out"
    res = cli("build", "custom", "--root", img, "--depth", depth, "--out", out, "--size", "40x90",
              "--corruptions", "fog_3d", "--levels", "2", "--jobs", 1, "--no-gt")
    assert res.exit_code == 0, res.output
    # by hand: each hole the nearest valid pixel, then each output pixel the pixel under its centre
    missing = ~(d > 0)
    idx = distance_transform_edt(missing, return_distances=False, return_indices=True)
    filled = d[idx[0], idx[1]]
    rows_ = [int((i + 0.5) * H / 40) for i in range(40)]
    cols = [int((j + 0.5) * W / 90) for j in range(90)]
    at_size = filled[np.ix_(rows_, cols)]
    want = fog_by_hand(clean_of(out, "a.png"), at_size, 150.0)  # level 2: V = 150 m
    np.testing.assert_array_equal(np.asarray(Image.open(out / "fog_3d" / "2" / "a.png")), want)


def test_zero_shot_preset_fog_from_its_ground_truth(tmp_path, cli):
    root, out = tmp_path / "sintel", tmp_path / "out"
    name = root / "training" / "final" / "alley_1" / "frame_0001.png"
    save(name, random_image(H, W, seed=1))
    dpt = root / "training" / "depth" / "alley_1" / "frame_0001.dpt"
    dpt.parent.mkdir(parents=True)
    dpt.write_bytes(struct.pack("<fii", 202021.25, W, H) + np.full(H * W, 30.0, "<f4").tobytes())
    res = cli("build", "sintel-c", "--root", root, "--out", out, "--corruptions", "fog_3d",
              "--levels", "1", "--jobs", 1)
    assert res.exit_code == 0, res.output
    key = "training/final/alley_1/frame_0001.png"
    want = fog_by_hand(clean_of(out, key), np.full((H, W), 30.0), 300.0)
    np.testing.assert_array_equal(np.asarray(Image.open(out / "fog_3d" / "1" / key)), want)
    params = manifest_by_output(out)[f"fog_3d/1/{key}"]["params"]  # the preset's pairing rule, then the map's hash
    assert params.startswith("depth=sintel-c-ground-truth/v1(") and params.endswith(f";map={depth_stamp(dpt)}")
    assert cli("verify", out).exit_code == 0


def test_custom_without_depth_refuses_depth_aware_corruptions(tmp_path, cli):
    img, _ = folder(tmp_path, {"a": None})
    for flags in (("--corruptions", "fog_3d"), ("--corruptions", "none", "--compose", "fog:1+zoom_3d:2")):
        res = cli("build", "custom", "--root", img, "--out", tmp_path / "c", *flags)
        assert res.exit_code == 2 and "needs the scene's depth" in res.output, res.output
        assert "--depth DIR" in res.output and "--scene-depth PRED" in res.output
    assert not (tmp_path / "c").exists()


def _predict(cli, tmp_path, out, pred, fn, *flags):
    (tmp_path / "m.py").write_text(MODEL)
    res = cli("predict", out, "-m", f"python:{tmp_path / 'm.py'}:{fn}", "-o", pred, *flags)
    assert res.exit_code == 0, res.output


@pytest.mark.slow
def test_scene_depth_from_metric_predictions_and_the_own_depth_warning(tmp_path, cli):
    img, depth = folder(tmp_path, {"a": np.full((H, W), 12.0, np.float32)})
    first, second = tmp_path / "first", tmp_path / "second"
    assert cli("build", "custom", "--root", img, "--depth", depth, "--out", first, "--corruptions",
               "none", "--jobs", 1).exit_code == 0
    _predict(cli, tmp_path, first, tmp_path / "P", "metric", "--kind", "depth", "--metric")
    assert (tmp_path / "P" / "clean" / "a.npy").is_file()  # each image its own size: one file each
    res = cli("build", "custom", "--root", img, "--depth", depth, "--out", second, "--corruptions",
              "fog_3d,brightness", "--levels", "3", "--jobs", 1, "--scene-depth", tmp_path / "P")
    assert res.exit_code == 0, res.output
    # the model's 7 m, not the depth folder's 12 m
    want = fog_by_hand(clean_of(second, "a.png"), np.full((H, W), 7.0), 75.0)
    np.testing.assert_array_equal(np.asarray(Image.open(second / "fog_3d" / "3" / "a.png")), want)
    depth_entry = json.loads((second / "build.json").read_text())["depth"]
    assert depth_entry["kind"] == "predictions" and depth_entry["rule"] == "metric"
    assert depth_entry["identity"].startswith("python:")
    assert manifest_by_output(second)["fog_3d/3/a.png"]["params"].startswith(f"depth=predictions:{depth_entry['identity']};map=")
    assert cli("verify", second).exit_code == 0
    again = cli("build", "custom", "--root", img, "--depth", depth, "--out", second, "--corruptions",
                "fog_3d,brightness", "--levels", "3", "--jobs", 1, "--scene-depth", tmp_path / "P")
    assert again.exit_code == 0 and "0 written" in again.output, again.output  # resumed: nothing to redo

    # the same model evaluated on it: score and report warn; another model: no warning
    _predict(cli, tmp_path, second, tmp_path / "P2", "metric", "--kind", "depth", "--metric")
    _predict(cli, tmp_path, second, tmp_path / "P3", "relative", "--kind", "depth", "--metric")
    for pred, same in (("P2", True), ("P3", False)):
        csv_path = tmp_path / f"{pred}.csv"
        res = cli("evaluate", second, "--pred", tmp_path / pred, "--out", csv_path)
        assert res.exit_code == 0, res.output
        res = cli("score", csv_path, "--benchmark", "custom", "--allow-partial")
        assert res.exit_code == 0, res.output
        warned = [ln for ln in res.output.splitlines() if "its own depth predictions" in ln]
        assert len(warned) == (1 if same else 0), res.output
    # report: its page notes it (on KITTI-C results, carrying the lines evaluate wrote above)
    from tests.helpers.report import published_csv

    comments = "".join(ln + "\n" for ln in (tmp_path / "P2.csv").read_text().splitlines()[:2])
    assert comments.startswith("# scene depth: predictions of python:")
    kitti = published_csv(tmp_path / "k.csv", "kitti-c", "MonoDepth2 nopt")
    kitti.write_text(comments + kitti.read_text())
    res = cli("report", kitti, "--out", tmp_path / "rep", "--published", "none")
    assert res.exit_code == 0, res.output
    assert "its own depth predictions" in res.output
    assert "its own depth predictions" in (tmp_path / "rep" / "index.html").read_text()


def test_relative_predictions_median_scaled_or_refused(tmp_path, cli):
    img, depth = folder(tmp_path, {"a": np.full((H, W), 12.0, np.float32)})
    first = tmp_path / "first"
    assert cli("build", "custom", "--root", img, "--depth", depth, "--out", first, "--corruptions",
               "none", "--jobs", 1, "--size", f"{H}x{W}").exit_code == 0
    pred = tmp_path / "P"
    _predict(cli, tmp_path, first, pred, "relative", "--kind", "disp", "--relative")
    assert (pred / "clean.npy").is_file()  # one size: the array form (the metric test: per image)
    args = ("build", "custom", "--root", img, "--depth", depth, "--out", tmp_path / "o",
            "--corruptions", "fog_3d", "--levels", "5", "--jobs", 1, "--scene-depth", pred)
    res = cli(*args)  # a relative disparity up to a scale and a shift: no metres
    assert res.exit_code == 2 and "--scene-depth" in res.output and "scale and a shift" in res.output
    assert len(res.output.strip().splitlines()) == 1
    # monodepth2's record: a disparity judged by median scaling in depth space
    record = json.loads((pred / "predictions.json").read_text())
    record["evaluate"] = {"kind": "disp", "align": "median", "align_space": "depth"}
    (pred / "predictions.json").write_text(json.dumps(record))
    res = cli(*args)
    assert res.exit_code == 0, res.output
    # 1 / 0.25 = 4, times median(12) / median(4): the ground truth's 12 m
    want = fog_by_hand(clean_of(tmp_path / "o", "a.png"), np.full((H, W), 12.0), 20.0)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "o" / "fog_3d" / "5" / "a.png")), want)
    # without a depth of its own, relative maps have nothing to be scaled to
    res = cli("build", "custom", "--root", img, "--out", tmp_path / "n", "--corruptions", "fog_3d",
              "--scene-depth", pred)
    assert res.exit_code == 2 and "no depth of its own" in res.output, res.output
    res = cli("build", "custom", "--root", img, "--out", tmp_path / "n", "--corruptions", "fog_3d",
              "--scene-depth", tmp_path / "img")
    assert res.exit_code == 2 and "no predictions.json" in res.output, res.output


def test_depth_turned_with_its_exif_oriented_image(tmp_path, cli):
    """A photo stored sideways (EXIF orientation 6: turn 90 degrees clockwise to view) is
    built upright; its depth map, stored as the photo is, turns with it."""
    (tmp_path / "img").mkdir()
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(random_image(H, W, seed=5)).save(tmp_path / "img" / "a.jpg", exif=exif)
    d = np.full((H, W), 50.0, np.float32)
    d[:, : W // 4] = 3.0  # the stored left quarter is near: after the turn, the top rows
    (tmp_path / "depth").mkdir()
    np.save(tmp_path / "depth" / "a.npy", d)
    out = tmp_path / "out"
    res = cli("build", "custom", "--root", tmp_path / "img", "--depth", tmp_path / "depth", "--out", out,
              "--corruptions", "fog_3d", "--levels", "5", "--jobs", 1, "--no-gt")
    assert res.exit_code == 0, res.output
    clean = clean_of(out, "a.png")
    assert clean.shape[:2] == (W, H)
    want = fog_by_hand(clean, np.rot90(d, -1), 20.0)
    assert np.rot90(d, -1)[0, 0] == 3.0 and np.rot90(d, -1)[-1, 0] == 50.0
    np.testing.assert_array_equal(np.asarray(Image.open(out / "fog_3d" / "5" / "a.png")), want)


def test_score_of_depth_aware_rows_alone(tmp_path, cli):
    """A custom build's results with no benchmark corruption: DEE of clean and the severity
    curve of fog_3d, no traceback."""
    path = tmp_path / "r.csv"
    path.write_text("corruption,level,abs_rel,a1\nclean,0,0.1,0.9\nfog_3d,3,0.2,0.8\n")
    res = cli("score", path, "--benchmark", "custom", "--json")
    assert res.exit_code == 0, res.output
    curve = json.loads(res.output)["beyond_benchmark"]["severity_curves"]["fog_3d"]
    assert list(curve) == ["3"] and curve["3"] == pytest.approx((0.2 + (1 - 0.8)) / 2)  # DEE


def test_a_rebuild_redoes_exactly_the_outputs_whose_depth_changed(tmp_path, cli):
    """Overwriting one depth map, then changing --depth-scale: the same command remakes the
    depth-aware outputs made from the old depth (as a fresh build makes them), nothing else."""
    from tests.helpers.depth_files import png16

    for i, name in enumerate("ab"):
        save(tmp_path / "img" / f"{name}.png", random_image(H, W, seed=i))
        png16(tmp_path / "depth" / f"{name}.png", np.full((H, W), 12000, np.uint16))
    img, depth, out = tmp_path / "img", tmp_path / "depth", tmp_path / "out"

    def build(where, scale):
        res = cli("build", "custom", "--root", img, "--depth", depth, "--depth-scale", scale, "--out",
                  where, "--corruptions", "fog_3d,brightness", "--levels", "3", "--jobs", 1)
        assert res.exit_code == 0, res.output
        return res.output

    def made(where):
        return {p: (where / p).read_bytes() for p in ("fog_3d/3/a.png", "fog_3d/3/b.png", "brightness/3/a.png")}

    build(out, 1000)
    r = manifest_by_output(out)
    assert r["fog_3d/3/a.png"]["params"] == f"depth=depth-folder/v1(scale=1000.0);map={depth_stamp(depth / 'a.png')}"
    before = made(out)
    png16(depth / "a.png", np.full((H, W), 3000, np.uint16))  # a is nearer now: less fog
    assert "2 written" in build(out, 1000)  # fog_3d/3/a.png and gt/a.npy
    after = made(out)
    assert after["fog_3d/3/a.png"] != before["fog_3d/3/a.png"]
    assert after["fog_3d/3/b.png"] == before["fog_3d/3/b.png"]
    build(tmp_path / "fresh", 1000)
    assert made(tmp_path / "fresh") == after
    assert cli("verify", out).exit_code == 0

    assert "4 written" in build(out, 500)  # both maps at another scale: both fogs and both gt
    build(tmp_path / "fresh500", 500)
    assert made(tmp_path / "fresh500") == made(out) != after


def test_scene_depth_outputs_are_keyed_on_the_prediction(tmp_path, cli):
    """--scene-depth: a prediction with other values remakes the depth-aware outputs."""
    img, depth = folder(tmp_path, {"a": np.full((H, W), 12.0, np.float32)})
    first, second = tmp_path / "first", tmp_path / "second"
    assert cli("build", "custom", "--root", img, "--depth", depth, "--out", first, "--corruptions",
               "none", "--jobs", 1).exit_code == 0
    args = ("build", "custom", "--root", img, "--out", second, "--corruptions", "fog_3d", "--levels",
            "3", "--jobs", 1, "--scene-depth", tmp_path / "P")
    _predict(cli, tmp_path, first, tmp_path / "P", "metric", "--kind", "depth", "--metric")
    assert cli(*args).exit_code == 0
    fog = (second / "fog_3d/3/a.png").read_bytes()
    # The same model's prediction, other values (as a rerun of a nondeterministic model gives).
    np.save(tmp_path / "P" / "clean" / "a.npy", np.full((H, W), 3.0, np.float32))
    again = cli(*args)
    assert again.exit_code == 0 and "1 written" in again.output, again.output
    want = fog_by_hand(clean_of(second, "a.png"), np.full((H, W), 3.0), 75.0)
    np.testing.assert_array_equal(np.asarray(Image.open(second / "fog_3d" / "3" / "a.png")), want)
    assert (second / "fog_3d/3/a.png").read_bytes() != fog
