"""`build kitti-c --frames`: neighbour frames from the raw drive, their layout, manifest,
resume and verify, and their corruption consistent with the test frame."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from robodepth_cli import corruptions, seeding
from robodepth_cli.corruptions.frames import DRAWS, NO_DRAWS, PER_FRAME, SHARED

from tests.helpers.imports import imported_by_command
from tests.helpers.manifest import manifest_by_output
from tests.helpers.trees import expected_paths, kitti_drive, kitti_key, random_image, tree

SIZE = ("--size", "48x64")
FLAGS = (*SIZE, "--corruptions", "fog,gaussian_noise,motion_blur", "--levels", "3", "--jobs", "1",
         "--no-gt")


@pytest.fixture
def drive(tmp_path):
    """Frames 0..5 of one drive; test frames 0, 2 and 5 (0 has no previous frame, 5 no next)."""
    root = tmp_path / "raw"
    return root, kitti_drive(root, range(6), [0, 2, 5])


def read(out, path):
    return np.asarray(Image.open(out / path))


def test_neighbours_written_listed_and_verified(drive, tmp_path, cli, build_kitti):
    root, split = drive
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *FLAGS, "--frames", "-1,1")
    assert res.exit_code == 0, res.output
    variants = ["fog", "gaussian_noise", "motion_blur"]
    # Test frames 0, 2, 5 and their neighbours 1, 3, 4 (1 neighbours both 0 and 2): no frame
    # -1 or 6 exists, so none is written for them.
    assert set(tree(out)) == expected_paths([kitti_key(n) for n in range(6)], variants, [3])
    rows = manifest_by_output(out)
    assert rows[f"fog/3/{kitti_key(2)}"]["params"] == ""
    # A frame next to two test frames is rendered for the first in split order.
    assert rows[f"fog/3/{kitti_key(1)}"]["params"] == f"neighbour_of={kitti_key(0)}"
    assert rows[f"clean/{kitti_key(3)}"]["params"] == f"neighbour_of={kitti_key(2)}"
    assert rows[f"gaussian_noise/3/{kitti_key(4)}"]["params"] == f"neighbour_of={kitti_key(5)}"
    plan = json.loads((out / "build.json").read_text())["plans"][-1]
    assert plan["keys"] == [kitti_key(0), kitti_key(2), kitti_key(5)]
    assert plan["frames"] == [-1, 1]
    assert plan["neighbours"] == {kitti_key(0): [None, kitti_key(1)],
                                  kitti_key(2): [kitti_key(1), kitti_key(3)],
                                  kitti_key(5): [kitti_key(4), None]}
    assert cli("verify", out).exit_code == 0

    # Resume: nothing to redo; a lost neighbour is reported by verify and made again.
    again = build_kitti(root, split, out, *FLAGS, "--frames", "-1,1")
    assert "0 written, 24 skipped" in again.output
    lost = out / f"motion_blur/3/{kitti_key(3)}"
    before = lost.read_bytes()
    lost.unlink()
    v = cli("verify", out)
    assert v.exit_code == 1 and f"motion_blur/3/{kitti_key(3)}" in v.output
    assert "1 written" in build_kitti(root, split, out, *FLAGS, "--frames", "-1,1").output
    assert lost.read_bytes() == before


def test_without_frames_the_test_frames_are_unchanged(drive, tmp_path, build_kitti):
    root, split = drive
    plain, framed = tmp_path / "plain", tmp_path / "framed"
    assert build_kitti(root, split, plain, *FLAGS).exit_code == 0
    assert build_kitti(root, split, framed, *FLAGS, "--frames", "-2,1").exit_code == 0
    a, b = tree(plain), tree(framed)
    assert set(a) < set(b) and all(b[p] == data for p, data in a.items())
    ra, rb = manifest_by_output(plain), manifest_by_output(framed)
    assert all({k: v for k, v in rb[p].items() if k != "source_mtime"}
               == {k: v for k, v in r.items() if k != "source_mtime"} for p, r in ra.items())
    record = json.loads((plain / "build.json").read_text())
    assert "frames" not in record["config"] and "neighbours" not in record["plans"][0]
    assert "frames" not in record["split"]


def test_neighbours_share_the_scene_draws_and_not_the_noise(drive, tmp_path, build_kitti):
    """In the build: each neighbour output is its clean image corrupted with the scene draws
    of its test frame and noise of its own."""
    root, split = drive
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *FLAGS, "--frames", "-1,1").exit_code == 0
    clean = read(out, f"clean/{kitti_key(3)}")
    for name in ("fog", "gaussian_noise", "motion_blur"):
        shared_key = kitti_key(2) if DRAWS[name][0] == SHARED else kitti_key(3)
        expected = corruptions.corrupt(clean, name, 3, seeding.job_rng(0, "kitti-c", name, 3, shared_key))
        assert np.array_equal(read(out, f"{name}/3/{kitti_key(3)}"), expected), name


@pytest.mark.parametrize("name", list(DRAWS))
def test_every_corruption_across_frames(name):
    """The same image as test frame and as its neighbour: a scene/camera corruption gives the
    same pixels, a noise the same amount of noise but independent of the test frame's."""
    x = random_image(48, 64, seed=3)
    test, neighbour = kitti_key(4), kitti_key(5)
    # The depth-aware corruptions take the scene's depth: a slanted plane, 5 to 50 m.
    depth = np.linspace(5.0, 50.0, 48)[:, None].repeat(64, axis=1) if corruptions.needs_depth(name) else None

    def render(key, anchor=None):
        return corruptions.render(x, name, 3, seed=1, dataset="kitti-c", key=key, anchor=anchor,
                                  depth=depth)

    a, b = render(test), render(neighbour, anchor=test)
    if DRAWS[name][0] in (SHARED, NO_DRAWS):
        assert np.array_equal(a, b)
        return
    assert DRAWS[name][0] == PER_FRAME
    if depth is not None:  # rain_3d: the drops differ, the scene's dimming by depth does not
        assert not np.array_equal(a, b)
        return
    ra, rb = a.astype(float) - x, b.astype(float) - x
    assert 0.7 < rb.std() / ra.std() < 1.4  # the same level of noise
    assert abs(np.corrcoef(ra.ravel(), rb.ravel())[0, 1]) < 0.1  # drawn anew


@pytest.mark.parametrize("value, problem", [
    ("0", "non-zero"), ("-1,x", "not an integer"), ("1.5", "not an integer"), ("11", "non-zero"),
])
def test_bad_frames_refused(drive, tmp_path, build_kitti, value, problem):
    root, split = drive
    res = build_kitti(root, split, tmp_path / "out", *FLAGS, "--frames", value)
    assert res.exit_code == 2 and "--frames" in res.output and problem in res.output
    assert not (tmp_path / "out").exists()


def test_frames_only_for_kitti(tmp_path, cli):
    res = cli("build", "nyudepth2-c", "--root", tmp_path, "--out", tmp_path / "o", "--frames", "-1,1")
    assert res.exit_code == 2 and "--frames does not apply to nyudepth2-c" in res.output


OVER_TIME = ("--corruptions", "frame_lost,frame_freeze,h264_crf,bit_error", "--levels", "1,5")


@pytest.mark.parametrize("jobs", [1, 2])  # 1: the sequences a process keeps are reused
def test_corruptions_over_time_in_a_build(drive, tmp_path, cli, build_kitti, jobs):
    """Each frame of a sequence is cut from the same corrupted sequence: the written frames
    equal the sequence corruption of the written clean frames."""
    from robodepth_cli.corruptions.temporal import corrupt_sequence

    root, split = drive
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *SIZE, *OVER_TIME, "--frames", "-1,1", "--jobs", jobs, "--no-gt")
    assert res.exit_code == 0, res.output
    assert cli("verify", out).exit_code == 0
    # frame_lost at level 5 (p = 1): both neighbours of test frame 2 black, the test frame clean.
    assert not read(out, f"frame_lost/5/{kitti_key(3)}").any()
    assert np.array_equal(read(out, f"frame_lost/5/{kitti_key(2)}"), read(out, f"clean/{kitti_key(2)}"))
    # Frame 3 is written for test frame 2's sequence (1, 2, 3); frame 4 for 5's (4, 5, -).
    # The codec ones to the bit in worker processes too: no stream depends on what ran
    # before in the process.
    for name, level in (("h264_crf", 5), ("bit_error", 5), ("frame_freeze", 1)):
        seq = [read(out, f"clean/{kitti_key(n)}") for n in (1, 2, 3)]
        rng = seeding.job_rng(0, "kitti-c", name, level, kitti_key(2))
        expected = corrupt_sequence(name, seq, 1, level, rng)
        assert np.array_equal(read(out, f"{name}/{level}/{kitti_key(2)}"), expected[1]), name
        assert np.array_equal(read(out, f"{name}/{level}/{kitti_key(3)}"), expected[2]), name
        seq = [read(out, f"clean/{kitti_key(n)}") for n in (4, 5)] + [None]
        rng = seeding.job_rng(0, "kitti-c", name, level, kitti_key(5))
        assert np.array_equal(read(out, f"{name}/{level}/{kitti_key(4)}"),
                              corrupt_sequence(name, seq, 1, level, rng)[0]), name


def test_corruptions_over_time_need_frames_and_are_not_in_all(drive, tmp_path, build_kitti):
    root, split = drive
    res = build_kitti(root, split, tmp_path / "o", *SIZE, "--corruptions", "fog,h265_crf")
    assert res.exit_code == 2
    assert "--corruptions: h265_crf is a corruption over time: it needs the neighbour frames" in res.output
    res = build_kitti(root, split, tmp_path / "o", *SIZE, "--corruptions", "all", "--levels", "1",
                      "--frames", "1", "--limit", "1", "--jobs", "1", "--no-gt")
    assert res.exit_code == 0, res.output
    assert not any(p.split("/")[0] in ("frame_lost", "h264_crf") for p in tree(tmp_path / "o"))


@pytest.mark.parametrize("flags", [(), ("--frames", "-1,1")])
def test_builds_without_corruptions_over_time_never_import_pyav(drive, tmp_path, flags):

    root, split = drive
    argv = ["build", "kitti-c", "--root", str(root), "--split", str(split), "--out", str(tmp_path / "o"),
            *SIZE, "--corruptions", "fog,gaussian_noise", "--levels", "1", "--jobs", "1", "--no-progress",
            "--no-gt", *flags]
    assert imported_by_command(argv, ["av"]) == []


def test_a_missing_test_frame_has_no_neighbours(drive, tmp_path, cli, build_kitti):
    root, split = drive
    (root / "2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000005.png").unlink()
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *FLAGS, "--frames", "-1,1")
    assert res.exit_code == 1  # frame 5's outputs failed; the rest is built
    assert not any(kitti_key(4) in p for p in tree(out))
    plan = json.loads((out / "build.json").read_text())["plans"][-1]
    assert plan["neighbours"][kitti_key(5)] == [None, None]
    v = cli("verify", out)
    assert "failed: 4" in v.output and "missing:" not in v.output and "incomplete" not in v.output


def test_codec_corruptions_need_pyav(drive, tmp_path, build_kitti, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "av" else real(name, *a))
    root, split = drive
    res = build_kitti(root, split, tmp_path / "o", *SIZE, "--corruptions", "frame_lost,bit_error",
                      "--frames", "-1")
    assert res.exit_code == 2
    assert "--corruptions: bit_error needs PyAV: pip install 'robodepth-cli[video]'" in res.output
    assert not (tmp_path / "o").exists()


def test_a_changed_neighbour_redoes_its_sequence(drive, tmp_path, build_kitti):
    """A corruption over time of the test frame depends on its neighbours: when one of them
    changes, the rerun makes the sequence again, and nothing else."""
    root, split = drive
    out = tmp_path / "out"
    flags = (*SIZE, "--corruptions", "fog,h264_crf", "--levels", "1", "--frames", "-1,1", "--jobs", "1",
             "--no-gt")
    assert build_kitti(root, split, out, *flags).exit_code == 0
    before = tree(out)
    frame3 = root / "2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000003.png"
    Image.fromarray(255 - np.asarray(Image.open(frame3))).save(frame3)
    res = build_kitti(root, split, out, *flags)
    assert res.exit_code == 0, res.output
    after = tree(out)
    changed = {p for p in after if after[p] != before[p]}
    # Frame 3's own outputs, and the h264 frames of its sequence (test frame 2, frames 1 and 3).
    assert changed == {f"clean/{kitti_key(3)}", f"fog/1/{kitti_key(3)}",
                       *(f"h264_crf/1/{kitti_key(n)}" for n in (2, 3))}
    rows = manifest_by_output(out)
    assert rows[f"h264_crf/1/{kitti_key(2)}"]["params"].startswith("sequence=")
    assert rows[f"h264_crf/1/{kitti_key(1)}"]["params"].startswith(f"neighbour_of={kitti_key(0)};sequence=")


@pytest.mark.parametrize("value, expected", [([1, -1], [-1, 1]), (-2, [-2]), ("+1, -1,1", [-1, 1])])
def test_frames_in_a_config_file(drive, tmp_path, build_kitti, value, expected):
    import yaml

    root, split = drive
    config = tmp_path / "mine.yaml"
    config.write_text(yaml.safe_dump({"frames": value, "corruptions": ["brightness"], "levels": [1]}))
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *SIZE, "--config", config, "--limit", "1", "--jobs", "1", "--no-gt")
    assert res.exit_code == 0, res.output
    assert json.loads((out / "build.json").read_text())["config"]["frames"] == expected
