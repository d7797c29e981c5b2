"""`robodepth gt kitti`, `gt nyu` and a build's ground truth refuse what would fail later
(issue 19): an empty or pointless velodyne scan, an output that cannot be written (checked
before any work), an .npz under another name, a `gt nyu` folder inside a build; `gt nyu`
leaves nothing half-written when stopped; `score --plot` into a read-only place fails at
once."""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers.gt_trees import write_labeled, write_split, write_tree
from tests.helpers.messages import one_line_error
from tests.helpers.readonly import read_only_reason


@pytest.fixture
def kitti(tmp_path, fixtures_dir):
    return write_tree(tmp_path, fixtures_dir, frames_per_drive=1)


def scan_of(root, line):
    folder, frame, _ = line.split()
    return root / folder / "velodyne_points" / "data" / f"{frame}.bin"


# --------------------------------------------------------------------------- scans (item 13)

def test_an_empty_scan_is_refused_naming_it(kitti, tmp_path, cli):
    root, split, lines = kitti
    scan = scan_of(root, lines[1])
    scan.write_bytes(b"")
    out = tmp_path / "gt.npz"
    res = cli("gt", "kitti", "--root", root, "--split", split, "--out", out)
    one_line_error(res, f"{split}:2:", str(scan), "0 bytes: an empty scan")
    assert not out.exists()


def test_a_scan_with_no_point_in_front_is_refused(kitti, tmp_path, cli):
    root, split, lines = kitti
    scan = scan_of(root, lines[0])
    behind = np.fromfile(scan, np.float32).reshape(-1, 4)
    behind[:, 0] = -np.abs(behind[:, 0]) - 1  # every point behind the car
    behind.tofile(scan)
    res = cli("gt", "kitti", "--root", root, "--split", split, "--out", tmp_path / "gt.npz")
    one_line_error(res, f"{split}:1:", str(scan), "no point falls in camera 2's image")


def test_a_build_fails_its_ground_truth_on_an_empty_scan(kitti, tmp_path, cli, build_kitti):
    from tests.helpers.trees import random_image, save

    root, split, lines = kitti
    for i, line in enumerate(lines):
        folder, frame, side = line.split()
        save(root / folder / {"l": "image_02", "r": "image_03"}[side] / "data" / f"{frame}.png",
             random_image(40, 120, seed=i))
    scan = scan_of(root, lines[2])
    scan.write_bytes(b"")
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--corruptions", "brightness", "--levels", "1", "--size",
                      "32x96", "--jobs", "1")
    assert res.exit_code == 1, res.output
    assert f"{scan}: 0 bytes: an empty scan" in res.output
    assert not (out / "gt_depths.npz").exists()


# --------------------------------------------------------------------------- outputs (items 3, 18)

def test_gt_kitti_checks_its_output_before_any_work(kitti, tmp_path, read_only_dir, monkeypatch, cli):
    from robodepth_cli.groundtruth import kitti as kitti_raw

    root, split, _ = kitti

    def no_work(*a, **k):
        raise AssertionError("the maps were computed")

    monkeypatch.setattr(kitti_raw, "depth_map", no_work)
    out = read_only_dir / "gt_depths.npz"
    res = cli("gt", "kitti", "--root", root, "--split", split, "--out", out)
    one_line_error(res, f"--out {out}: cannot write ({read_only_reason(read_only_dir)})")
    res = cli("gt", "kitti", "--root", root, "--split", split, "--out", tmp_path / "o.txt")
    one_line_error(res, f"--out {tmp_path / 'o.txt'}: the ground truth is an .npz file", "end it in .npz")
    assert not (tmp_path / "o.txt").exists()


def test_gt_nyu_checks_its_output_before_any_work(tmp_path, read_only_dir, cli):
    mat = tmp_path / "labeled.mat"
    write_labeled(mat)
    split = write_split(tmp_path / "split.txt", [0, 1])
    out = read_only_dir / "NYU_TEST"
    res = cli("gt", "nyu", "--root", mat, "--split", split, "--out", out)
    one_line_error(res, f"--out {out}: cannot write ({read_only_reason(read_only_dir)})")


def test_score_plot_into_a_read_only_place_fails_at_once(tmp_path, read_only_dir, cli):
    results = tmp_path / "r.csv"
    results.write_text("corruption,level,abs_rel,a1\nclean,0,0.1,0.9\nfog,1,0.1,0.9\n")
    res = cli("score", results, "-b", "kitti-c", "--allow-partial", "--plot", read_only_dir / "ce.png")
    one_line_error(res, f"--plot {read_only_dir / 'ce.png'}: cannot write ({read_only_reason(read_only_dir)})")
    res = cli("score", results, "-b", "kitti-c", "--allow-partial", "--plot", f"{read_only_dir}/")
    one_line_error(res, f"--plot {read_only_dir / 'r_ce.png'}: cannot write")


# --------------------------------------------------------------------------- gt nyu's folder (item 6)

def test_gt_nyu_refuses_an_out_inside_a_build(fixtures_dir, tmp_path, cli):
    out = tmp_path / "NYU_C"
    res = cli("build", "nyudepth2-c", "--root", fixtures_dir / "nyu", "--split",
              fixtures_dir / "nyu_split.txt", "--out", out, "--corruptions", "brightness",
              "--levels", "1", "--jobs", "1")
    assert res.exit_code == 0, res.output
    for target in (out / "gt", out / "more", out):
        res = cli("gt", "nyu", "--root", fixtures_dir / "nyu", "--split", fixtures_dir / "nyu_split.txt",
                  "--out", target)
        one_line_error(res, f"--out {target}: inside the build {out}", "rerun robodepth build")
    assert cli("verify", out).exit_code == 0


def test_gt_nyu_stopped_midway_leaves_nothing(tmp_path, monkeypatch, cli):
    from robodepth_cli.groundtruth import nyu as nyu_labeled

    mat = tmp_path / "labeled.mat"
    write_labeled(mat)
    split = write_split(tmp_path / "split.txt", [0, 1, 2])
    encode = nyu_labeled.encode_depth_png
    calls = []

    def stop_at_the_second(depth):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return encode(depth)

    monkeypatch.setattr(nyu_labeled, "encode_depth_png", stop_at_the_second)
    out = tmp_path / "NYU_TEST"
    res = cli("gt", "nyu", "--root", mat, "--split", split, "--out", out)
    assert res.exit_code == 130, res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["labeled.mat", "split.txt"]
    monkeypatch.setattr(nyu_labeled, "encode_depth_png", encode)
    res = cli("gt", "nyu", "--root", mat, "--split", split, "--out", out)
    assert res.exit_code == 0, res.output
    assert len(list(out.rglob("sync_depth_*.png"))) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["NYU_TEST", "labeled.mat", "split.txt"]


def test_gt_nyu_refuses_a_non_empty_out(tmp_path, cli):
    mat = tmp_path / "labeled.mat"
    write_labeled(mat)
    split = write_split(tmp_path / "split.txt", [0])
    out = tmp_path / "NYU_TEST"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    res = cli("gt", "nyu", "--root", mat, "--split", split, "--out", out)
    one_line_error(res, f"--out {out}: exists and is not empty")
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]


# --------------------------------------------------------------------------- progress (item 18)

def test_gt_kitti_reports_the_writing_step(kitti, tmp_path):
    """The maps are done before the file is compressed and written: a step of its own."""
    from robodepth_cli.groundtruth import kitti as kitti_raw

    root, split, lines = kitti
    out = tmp_path / "gt.npz"
    events = []
    kitti_raw.export(root, kitti_raw.read_frames(split), out, progress=lambda n: events.append("map"),
                     stage=lambda text: events.append((text, out.exists())))
    assert events == ["map"] * len(lines) + [(f"compressing and writing {out}", False)]
    assert out.exists()
