"""`predict` with a multi-frame model: a python:MODULE:CALLABLE that declares the neighbour
frames it takes gets the frame and its neighbours, in the documented order."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from tests.helpers.trees import kitti_drive, kitti_key

MODULE = '''
import numpy as np

def multi(batch):
    """The red channels of the frame, its previous and its next frame, weighted 1, 2, 4:
    the map tells which image came in which place."""
    assert batch.ndim == 5 and batch.shape[1] == 3
    r = batch[..., 0].astype(np.float32)
    return 1 + r[:, 0] + 2 * r[:, 1] + 4 * r[:, 2]

multi.robodepth_frames = (-1, 1)

def zero(batch):
    return np.ones(batch.shape[:1] + batch.shape[2:4], np.float32)

zero.robodepth_frames = (0,)
'''


@pytest.fixture
def user_module(tmp_path):
    path = tmp_path / "seqmodel.py"
    path.write_text(MODULE)
    return path


def build(tmp_path, build_kitti, *flags):
    root = tmp_path / "raw"
    split = kitti_drive(root, range(6), [0, 2, 5])
    out = tmp_path / "OUT"
    res = build_kitti(root, split, out, "--size", "48x64", "--corruptions", "fog", "--levels", "2",
                      "--jobs", "1", "--no-gt", *flags)
    assert res.exit_code == 0, res.output
    return out


def red(out, variant, frame):
    path = out / variant / kitti_key(frame)
    if frame < 0 or not path.is_file():
        return np.zeros((48, 64), np.float32)  # missing: black
    return np.asarray(Image.open(path))[..., 0].astype(np.float32)


def multi_wanted(out, variant):
    """``multi``'s maps for test frames 0 (no frame -1: black), 2, and 5 (no frame 6: black),
    in split order, from the build's files."""
    return np.stack([1 + red(out, variant, n) + 2 * red(out, variant, n - 1) + 4 * red(out, variant, n + 1)
                     for n in (0, 2, 5)])


def test_a_multi_frame_model_gets_the_frame_then_its_neighbours(tmp_path, cli, build_kitti, user_module):
    out = build(tmp_path, build_kitti, "--frames", "-1,1")
    res = cli("predict", out, "-m", f"python:{user_module}:multi", "--kind", "disp", "-o", tmp_path / "P")
    assert res.exit_code == 0, res.output
    for variant in ("clean", "fog/2"):
        np.testing.assert_array_equal(np.load(tmp_path / "P" / f"{variant}.npy"), multi_wanted(out, variant))
    assert json.loads((tmp_path / "P" / "predictions.json").read_text())["frames"] == [-1, 1]


def test_a_multi_frame_model_needs_a_build_with_its_neighbours(tmp_path, cli, build_kitti, user_module):
    out = build(tmp_path, build_kitti)
    res = cli("predict", out, "-m", f"python:{user_module}:multi", "--kind", "disp", "-o", tmp_path / "P")
    assert res.exit_code == 2
    assert "has no neighbours at -1, 1 (build it with --frames -1,1)" in res.output
    assert not (tmp_path / "P").exists()


def test_bad_frame_declaration_refused(tmp_path, cli, build_kitti, user_module):
    out = build(tmp_path, build_kitti, "--frames", "1")
    res = cli("predict", out, "-m", f"python:{user_module}:zero", "--kind", "disp", "-o", tmp_path / "P")
    assert res.exit_code == 2
    assert "robodepth_frames (0,): expected distinct non-zero integer frame offsets" in res.output


@pytest.mark.parametrize("fmt", ["parquet", "webdataset"])
def test_a_multi_frame_model_predicts_on_an_export_as_on_its_build(tmp_path, cli, build_kitti,
                                                                    user_module, fmt):
    out = build(tmp_path, build_kitti, "--frames", "-1,1")
    export = tmp_path / "export"
    res = cli("export", out, "--format", fmt, "--to", export, "--no-progress")
    assert res.exit_code == 0, res.output
    res = cli("predict", export, "-m", f"python:{user_module}:multi", "--kind", "disp",
              "-o", tmp_path / "P")
    assert res.exit_code == 0, res.output
    for variant in ("clean", "fog/2"):
        np.testing.assert_array_equal(np.load(tmp_path / "P" / f"{variant}.npy"), multi_wanted(out, variant))
