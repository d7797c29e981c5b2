"""`build --corruptions fog_3d,...`: NYU's depth from its own ground truth, KITTI's from the
velodyne made dense at the output size; the depth source in build.json and the manifest;
resume and verify as for every corruption; refusals for datasets without depth."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from PIL import Image
from scipy.ndimage import distance_transform_edt

from robodepth_cli.groundtruth import kitti as kitti_raw

from tests.helpers.manifest import manifest_by_output
from tests.helpers.paths import FIXTURES
from tests.helpers.trees import fixture_kitti_with_scans
from tests.helpers.depth_files import depth_stamp

KEY_NYU = "bedroom/rgb_00001.png"
KITTI_DRIVE = "2011_09_26/2011_09_26_drive_0002_sync"


def fog_by_hand(clean, depth, visibility):
    t = np.exp(math.log(0.02) / visibility * depth)[:, :, None]
    return np.floor(np.clip(clean * t + 204.0 * (1 - t), 0, 255) + 0.5).astype(np.uint8)


def nearest_fill(d):
    missing = ~np.isfinite(d)
    idx = distance_transform_edt(missing, return_distances=False, return_indices=True)
    return d[idx[0], idx[1]]


def test_nyu_build_uses_its_own_ground_truth(tmp_path, cli):
    out = tmp_path / "nyu"
    args = ("build", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", FIXTURES / "nyu_split.txt",
            "--out", out, "--corruptions", "fog_3d,brightness", "--levels", "4", "--limit", "1", "--jobs", "1")
    res = cli(*args)
    assert res.exit_code == 0, res.output
    clean = np.asarray(Image.open(out / "clean" / KEY_NYU), dtype=np.float64)
    mm = np.asarray(Image.open(FIXTURES / "nyu" / "bedroom" / "sync_depth_00001.png"), dtype=np.float64)
    assert (mm > 0).all()  # this frame has no hole: the formula applies pixel by pixel
    got = np.asarray(Image.open(out / "fog_3d" / "4" / KEY_NYU))
    np.testing.assert_array_equal(got, fog_by_hand(clean, mm / 1000.0, 40.0))
    record = json.loads((out / "build.json").read_text())
    assert record["depth"]["kind"] == "nyu-ground-truth"
    r = manifest_by_output(out)
    assert r[f"fog_3d/4/{KEY_NYU}"]["params"] == \
        f"depth=nyu-ground-truth/v1;map={depth_stamp(FIXTURES / 'nyu/bedroom/sync_depth_00001.png')}"
    assert r[f"brightness/4/{KEY_NYU}"]["params"] == ""  # the 18 are made as before
    assert cli("verify", out).exit_code == 0
    again = cli(*args)
    assert again.exit_code == 0 and "0 written" in again.output, again.output


@pytest.mark.slow
def test_kitti_build_densifies_the_velodyne_at_the_output_size(tmp_path, cli):
    root, out = fixture_kitti_with_scans(tmp_path), tmp_path / "k"
    res = cli("build", "kitti-c", "--root", root, "--split", FIXTURES / "kitti_split.txt", "--out", out,
              "--corruptions", "fog_3d", "--compose", "zoom_3d:2+gaussian_noise:1", "--levels", "3",
              "--size", "48x160", "--jobs", "1")
    assert res.exit_code == 0, res.output
    key = f"kitti_data/{KITTI_DRIVE}/image_02/data/0000000069.png"
    sparse = kitti_raw.depth_map(kitti_raw.Calibration.load(root / "2011_09_26"),
                                 kitti_raw.load_velodyne(root / KITTI_DRIVE / "velodyne_points/data/0000000069.bin"))
    # the documented method, by hand: each output pixel the nearest return falling in it,
    # then each empty pixel the depth of the nearest pixel with one
    h0, w0 = sparse.shape
    grid = np.full((48, 160), np.inf)
    for v, u in zip(*np.nonzero(sparse)):
        r, c = v * 48 // h0, u * 160 // w0
        grid[r, c] = min(grid[r, c], sparse[v, u])
    dense = nearest_fill(np.where(np.isinf(grid), np.nan, grid))
    clean = np.asarray(Image.open(out / "clean" / key), dtype=np.float64)
    got = np.asarray(Image.open(out / "fog_3d" / "3" / key))
    np.testing.assert_array_equal(got, fog_by_hand(clean, np.clip(dense, 0.05, 1000), 75.0))
    record = json.loads((out / "build.json").read_text())
    assert record["depth"]["kind"] == "kitti-lidar-densified"
    for path, r in manifest_by_output(out).items():
        if r["variant"] not in ("clean", "gt"):
            frame = path.split("/")[-1][:-len(".png")]
            files = [root / KITTI_DRIVE / f"velodyne_points/data/{frame}.bin",
                     root / "2011_09_26/calib_cam_to_cam.txt", root / "2011_09_26/calib_velo_to_cam.txt"]
            assert r["params"] == f"depth=kitti-lidar-densified/v1;map={depth_stamp(*files)}"
    assert cli("verify", out).exit_code == 0


def test_a_changed_scan_remakes_its_depth_aware_outputs(tmp_path, cli):
    """A velodyne scan overwritten (its points nearer): the rerun remakes that frame's
    depth-aware output, as a fresh build makes it, and no other."""
    root = fixture_kitti_with_scans(tmp_path)

    def build(out):
        res = cli("build", "kitti-c", "--root", root, "--split", FIXTURES / "kitti_split.txt", "--out",
                  out, "--corruptions", "fog_3d,brightness", "--levels", "3", "--size", "32x96",
                  "--jobs", "1", "--no-gt")
        assert res.exit_code == 0, res.output
        return res.output

    key = f"kitti_data/{KITTI_DRIVE}/image_02/data/0000000069.png"
    other = f"kitti_data/{KITTI_DRIVE}/image_02/data/0000000054.png"
    out = tmp_path / "k"
    build(out)
    before = {k: (out / "fog_3d/3" / k).read_bytes() for k in (key, other)}
    scan = root / KITTI_DRIVE / "velodyne_points/data/0000000069.bin"
    points = np.fromfile(scan, dtype=np.float32).reshape(-1, 4)
    points[:, :3] *= 0.25
    points.tofile(scan)
    assert "1 written" in build(out)
    assert (out / "fog_3d/3" / key).read_bytes() != before[key]
    assert (out / "fog_3d/3" / other).read_bytes() == before[other]
    build(tmp_path / "fresh")
    assert (tmp_path / "fresh/fog_3d/3" / key).read_bytes() == (out / "fog_3d/3" / key).read_bytes()


def test_a_missing_scan_fails_only_the_depth_aware_outputs(tmp_path, cli):
    root, out = fixture_kitti_with_scans(tmp_path), tmp_path / "k"
    (root / KITTI_DRIVE / "velodyne_points/data/0000000054.bin").unlink()
    res = cli("build", "kitti-c", "--root", root, "--split", FIXTURES / "kitti_split.txt", "--out", out,
              "--corruptions", "fog_3d,brightness", "--levels", "1", "--size", "32x96", "--jobs", "1", "--no-gt")
    assert res.exit_code == 1, res.output
    failed = {o: r for o, r in manifest_by_output(out).items() if r["error"]}
    assert list(failed) == [f"fog_3d/1/kitti_data/{KITTI_DRIVE}/image_02/data/0000000054.png"]
    error = next(iter(failed.values()))["error"]
    assert "0000000054.bin" in error
    # the reason in the user's words: the source, the job, then the depth's problem, no class name
    source = root / KITTI_DRIVE / "image_02/data/0000000054.png"
    scan = root / KITTI_DRIVE / "velodyne_points/data/0000000054.bin"
    assert error == f"{source}: fog_3d level 1: {scan}: no such velodyne file"


def test_datasets_without_depth_refuse_depth_aware_corruptions(tmp_path, cli):
    res = cli("build", "custom", "--root", FIXTURES / "nyu", "--out", tmp_path / "c", "--corruptions", "fog_3d")
    assert res.exit_code == 2 and "fog_3d needs the scene's depth" in res.output
    assert not (tmp_path / "c").exists()


def test_depth_aware_names_are_listed_never_all():
    from robodepth_cli.building.config import resolve
    from robodepth_cli.corruptions import DEPTH_NAMES

    cfg = resolve("nyudepth2-c", flags={"corruptions": "near_focus,fog_3d", "compose": "motion_3d:2+contrast:1"})
    assert cfg.variants == ("near_focus", "fog_3d", "motion_3d:2+contrast:1")
    for preset in ("kitti-c", "nyudepth2-c"):
        assert not set(resolve(preset, flags={"corruptions": "all"}).variants) & set(DEPTH_NAMES)


def test_nyu_build_from_the_labeled_file_uses_its_raw_depths(tmp_path, cli):
    from tests.helpers.gt_trees import SCENES, write_labeled, write_split

    mat = tmp_path / "nyu_depth_v2_labeled.mat"
    _, depth = write_labeled(mat)  # uniform 0..10 m, a block of zeros (missing) at 4:8, :4
    split = write_split(tmp_path / "split.txt", [1])
    out = tmp_path / "out"
    res = cli("build", "nyudepth2-c", "--root", mat, "--split", split, "--out", out,
              "--corruptions", "fog_3d", "--levels", "4", "--jobs", "1", "--no-gt")
    assert res.exit_code == 0, res.output
    key = f"{SCENES[1]}/rgb_00001.png"
    clean = np.asarray(Image.open(out / "clean" / key), dtype=np.float64)
    d = depth[1].astype(np.float64)
    d[d <= 0] = np.nan
    want = fog_by_hand(clean, np.clip(nearest_fill(d), 0.05, 1000), 40.0)
    np.testing.assert_array_equal(np.asarray(Image.open(out / "fog_3d" / "4" / key)), want)


def test_torch_engine_renders_depth_aware_corruptions_with_the_numpy_engine(tmp_path, cli):
    """The depth-aware corruptions have no torch port: a torch-engine build makes them with
    the numpy engine (same bytes, the depth source's fingerprint), the 18 on torch."""
    outs = {}
    for engine in ("numpy", "torch"):
        outs[engine] = out = tmp_path / engine
        res = cli("build", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", FIXTURES / "nyu_split.txt",
                  "--out", out, "--corruptions", "fog_3d,contrast", "--levels", "2", "--limit", "1",
                  "--jobs", "1", "--engine", engine, "--device", "cpu")
        assert res.exit_code == 0, res.output
    for name in ("fog_3d", "contrast"):
        a = np.asarray(Image.open(outs["numpy"] / name / "2" / KEY_NYU))
        b = np.asarray(Image.open(outs["torch"] / name / "2" / KEY_NYU))
        np.testing.assert_array_equal(a, b)
    r = manifest_by_output(outs["torch"])
    assert r[f"fog_3d/2/{KEY_NYU}"]["params"] == \
        f"depth=nyu-ground-truth/v1;map={depth_stamp(FIXTURES / 'nyu/bedroom/sync_depth_00001.png')}"
    assert r[f"contrast/2/{KEY_NYU}"]["params"] == "engine=torch"
    assert cli("verify", outs["torch"]).exit_code == 0
