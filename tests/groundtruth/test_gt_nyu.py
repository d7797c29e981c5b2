"""`robodepth gt nyu` from a small HDF5 file in the layout of the official
``nyu_depth_v2_labeled.mat`` (written with h5py by tests/helpers/gt_trees.py), against BTS's extraction written
there from the rules: border blacked out, OpenCV JPEG at its default quality, depth * 1000 in
float32 truncated to uint16."""

from __future__ import annotations

import cv2
import h5py
import numpy as np
import pytest
from PIL import Image

from tests.helpers.gt_trees import SCENES, bts_files, write_labeled, write_split
from tests.helpers.messages import one_line_error


@pytest.fixture
def run(cli):
    return cli


@pytest.fixture
def labeled(tmp_path):
    path = tmp_path / "nyu_depth_v2_labeled.mat"
    rgb, depth = write_labeled(path)
    return path, rgb, depth


def test_gt_nyu_from_labeled_file_is_bts_layout(labeled, tmp_path, run):
    path, rgb, depth = labeled
    split = write_split(tmp_path / "split.txt", [2, 0, 4])
    out = tmp_path / "out"
    res = run("gt", "nyu", "--root", path, "--split", split, "--out", out)
    assert res.exit_code == 0, res.output
    bts = tmp_path / "bts"
    for i in (2, 0, 4):
        bts_files(rgb[i], depth[i], bts, i, SCENES[i])
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert written == sorted(p.relative_to(bts).as_posix() for p in bts.rglob("*") if p.is_file())
    assert len(written) == 6
    for rel in written:
        if rel.endswith(".png"):
            got = cv2.imread(str(out / rel), cv2.IMREAD_UNCHANGED)
            want = cv2.imread(str(bts / rel), cv2.IMREAD_UNCHANGED)
            assert got.dtype == np.uint16 and got.shape == (480, 640)
            assert np.array_equal(got, want), rel
            assert got[0, 0] == 700 and not got[4:8, :4].any()
        else:
            got, want = (np.asarray(Image.open(d / rel).convert("RGB")) for d in (out, bts))
            assert np.array_equal(got, want), rel
            border = np.concatenate([got[:7].ravel(), got[474:].ravel(), got[:, :7].ravel(), got[:, 632:].ravel()])
            assert border.mean() < 3 and got[7:474, 7:632].mean() > 50  # black but for JPEG ringing
    # The float32 product matters: float64 would truncate 0.7 m to 699 mm.
    assert int(np.float64(np.float32(0.7)) * 1000.0) == 699


def test_clean_image_is_bts_jpeg_decoded(labeled, tmp_path):
    """The clean source of a labeled frame has the pixels of BTS's JPEG of it."""
    from robodepth_cli.groundtruth.nyu import LabeledFile, bts_jpeg, decode_jpeg

    path, rgb, depth = labeled
    bts_files(rgb[3], depth[3], tmp_path / "bts", 3, SCENES[3])
    want = np.asarray(Image.open(tmp_path / "bts" / SCENES[3] / "rgb_00003.jpg").convert("RGB"))
    with LabeledFile(path) as f:
        assert f.n == 5 and f.scene(3) == "living_room"
        assert np.array_equal(f.rgb(3), rgb[3]) and np.array_equal(f.depth(3), depth[3])
        got = decode_jpeg(bts_jpeg(f.rgb(3)))  # what a build from the .mat reads
    assert got.dtype == np.uint8 and got.shape == (480, 640, 3)
    assert np.array_equal(got, want)
    assert not np.array_equal(got, rgb[3])  # the border and the JPEG round trip did something


def test_gt_nyu_from_bts_folder_copies_depth(tmp_path, run):
    rng = np.random.default_rng(3)
    root = tmp_path / "nyu"
    (root / "bedroom").mkdir(parents=True)
    depth = rng.integers(0, 10000, (480, 640), dtype=np.uint16)
    cv2.imwrite(str(root / "bedroom" / "sync_depth_00001.png"), depth)
    split = tmp_path / "split.txt"
    split.write_text("bedroom/rgb_00001.jpg bedroom/sync_depth_00001.png 518.8579\n")
    out = tmp_path / "out"
    res = run("gt", "nyu", "--root", root, "--split", split, "--out", out)
    assert res.exit_code == 0, res.output
    assert [p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()] == ["bedroom/sync_depth_00001.png"]
    assert (out / "bedroom/sync_depth_00001.png").read_bytes() == (root / "bedroom/sync_depth_00001.png").read_bytes()
    # An 8-bit file is not a depth map.
    cv2.imwrite(str(root / "bedroom" / "sync_depth_00001.png"), (depth >> 8).astype(np.uint8))
    one_line_error(run("gt", "nyu", "--root", root, "--split", split, "--out", tmp_path / "out2"),
          f"{split}:1:", "sync_depth_00001.png", "16-bit")
    assert not (tmp_path / "out2").exists()


def test_bad_split_lines(labeled, tmp_path, run):
    path, *_ = labeled
    out = tmp_path / "out"
    split = tmp_path / "split.txt"
    split.write_text("bathroom/rgb_00000.jpg bathroom/sync_depth_00000.png 518.8579\n"
                     "bathroom/rgb_00001.jpg bathroom/sync_depth_00001.png 518.8579\n")  # frame 1 is a kitchen
    one_line_error(run("gt", "nyu", "--root", path, "--split", split, "--out", out), f"{split}:2:", "'kitchen'",
          "'bathroom'", "rgb_00001")
    split.write_text("bedroom/rgb_00004.jpg bedroom/sync_depth_00004.png 518.8579\n"
                     "bedroom/rgb_00005.jpg bedroom/sync_depth_00005.png 518.8579\n")
    one_line_error(run("gt", "nyu", "--root", path, "--split", split, "--out", out), f"{split}:2:", "frame 5", "5 frames")
    split.write_text("bedroom/frame_4.jpg bedroom/sync_depth_00004.png 518.8579\n")
    one_line_error(run("gt", "nyu", "--root", path, "--split", split, "--out", out), f"{split}:1:", "rgb_NNNNN")
    assert not out.exists()


@pytest.mark.parametrize("drop", ["images", "rawDepths", "sceneTypes"])
def test_labeled_file_without_a_dataset(tmp_path, drop, run):
    path = tmp_path / "labeled.mat"
    write_labeled(path, scenes=SCENES[:2], drop=drop)
    split = write_split(tmp_path / "split.txt", [0, 1])
    one_line_error(run("gt", "nyu", "--root", path, "--split", split, "--out", tmp_path / "out"), str(path), repr(drop))


def test_not_hdf5_and_wrong_layout(tmp_path, run):
    split = write_split(tmp_path / "split.txt", [0])
    mat = tmp_path / "labeled.mat"
    mat.write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    one_line_error(run("gt", "nyu", "--root", mat, "--split", split, "--out", tmp_path / "out"), str(mat), "not an HDF5")
    with h5py.File(mat, "w") as f:
        f.create_dataset("images", data=np.zeros((1, 3, 320, 240), np.uint8))
        f.create_dataset("rawDepths", data=np.zeros((1, 640, 480), np.float32))
        f.create_dataset("sceneTypes", (1, 1), dtype=h5py.ref_dtype)
    one_line_error(run("gt", "nyu", "--root", mat, "--split", split, "--out", tmp_path / "out"), str(mat), "'images'",
          "1 x 3 x 640 x 480")
    assert not (tmp_path / "out").exists()


def test_split_with_a_byte_order_mark_writes_the_same_files(labeled, tmp_path, run):
    """A split saved with a UTF-8 byte-order mark (as Windows editors do) names the same
    first frame: the mark is not part of its scene folder."""
    path, _, _ = labeled
    split = write_split(tmp_path / "split.txt", [2, 0, 4])
    marked = tmp_path / "marked.txt"
    marked.write_bytes(b"\xef\xbb\xbf" + split.read_bytes())
    for name, s in (("plain", split), ("marked", marked)):
        res = run("gt", "nyu", "--root", path, "--split", s, "--out", tmp_path / name)
        assert res.exit_code == 0, res.output
    files = {name: {p.relative_to(tmp_path / name).as_posix(): p.read_bytes()
                    for p in (tmp_path / name).rglob("*") if p.is_file()}
             for name in ("plain", "marked")}
    assert len(files["plain"]) == 6
    assert files["marked"] == files["plain"]
