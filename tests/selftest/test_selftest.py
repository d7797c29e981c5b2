"""`robodepth selftest`: the shipped fixtures built with every kind of variant and compared
with the shipped reference; what it says when an output or a version differs."""

from __future__ import annotations

import json
import lzma
import shutil

import numpy as np
import pytest

from robodepth_cli import versionlock
from robodepth_cli.selftest import check as selftest

READ_REFERENCE = selftest.read_reference  # the real one, for the tampered copies


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The selftest's builds, made once by the real builder."""
    work = tmp_path_factory.mktemp("selftest")
    selftest.build_all(work)
    return work


@pytest.fixture
def prebuilt(built, monkeypatch):
    """The selftest command with its builds taken from :func:`built`."""
    monkeypatch.setattr(selftest, "build_all", lambda work: shutil.copytree(built, work, dirs_exist_ok=True))


def tampered_reference(tmp_path, monkeypatch, key, delta):
    """A copy of the reference in which output ``key`` has other pixels (``delta`` added to
    one value) and so another hash."""
    meta = json.loads((selftest.DATA / selftest.REFERENCE).read_text())
    pixels = bytearray(lzma.decompress((selftest.DATA / selftest.PIXELS).read_bytes()))
    entry = meta["outputs"][key]
    i = entry["offset"] + 100
    pixels[i] = pixels[i] + delta if pixels[i] < 128 else pixels[i] - delta
    entry["sha256"] = "0" * 64
    folder = tmp_path / "reference"
    folder.mkdir(parents=True)
    (folder / selftest.REFERENCE).write_text(json.dumps(meta))
    (folder / selftest.PIXELS).write_bytes(lzma.compress(bytes(pixels), preset=0))
    monkeypatch.setattr(selftest, "read_reference", lambda: READ_REFERENCE(folder))


def test_the_builds_cover_every_kind_of_variant():
    from robodepth_cli.benchmark_facts import ALL_CORRUPTIONS as CORRUPTIONS, TEMPORAL

    ref = selftest.read_reference()
    variants = {e["variant"] for e in ref.outputs.values()}
    names = {e["corruption"] for e in ref.outputs.values()}
    assert set(CORRUPTIONS) | set(TEMPORAL) <= names  # the 18, the depth-aware, the ones over time
    for name in CORRUPTIONS:
        assert {f"custom:{name}/{lv}" for lv in (1, 2, 3, 4, 5, 2.5)} <= variants, name
    for name in TEMPORAL:
        assert {f"sequence:{name}/{lv}" for lv in (1, 2, 3, 4, 5, 2.5)} <= variants, name
    assert "custom:fog-3+gaussian_noise-2.5" in variants and "kitti-s:sketch" in variants
    # the sequence: every variant has the test frame and its two neighbours
    assert sum(1 for k in ref.outputs if k.startswith("sequence/h264_crf/3/")) == 3
    assert len(selftest.DATA.joinpath(selftest.PIXELS).read_bytes()) < 700_000


def test_passes_on_the_locked_install(cli, prebuilt):
    res = cli("selftest")
    assert res.exit_code == 0, res.output
    (line,) = res.output.splitlines()
    assert line.startswith(f"selftest: all {len(selftest.read_reference().outputs)} outputs match "
                           f"the reference (KITTI-S within 1 grey level), versions as locked, in ")


def test_a_differing_output_is_named_with_its_largest_difference(tmp_path, cli, prebuilt, monkeypatch):
    tampered_reference(tmp_path, monkeypatch, "custom/fog/3/street.png", 3)
    res = cli("selftest")
    assert res.exit_code == 1
    assert res.output.splitlines() == [
        "custom:fog/3: 1 of 1 outputs differ from the reference, largest difference 3 grey levels",
        f"selftest: 1 of {len(selftest.read_reference().outputs)} outputs differ from the reference"]


def test_kitti_s_passes_within_one_grey_level_only(tmp_path, cli, prebuilt, monkeypatch):
    key = next(k for k in selftest.read_reference().outputs if k.startswith("kitti-s/sketch/"))
    tampered_reference(tmp_path / "one", monkeypatch, key, 1)
    assert cli("selftest").exit_code == 0
    tampered_reference(tmp_path / "two", monkeypatch, key, 2)
    res = cli("selftest")
    assert res.exit_code == 1
    assert res.output.splitlines()[0] == ("kitti-s:sketch: 1 of 1 outputs differ from the reference, "
                                          "largest difference 2 grey levels")


def test_a_version_other_than_the_lock_is_named(tmp_path, cli, prebuilt, monkeypatch):
    pins = versionlock.locked()
    text = versionlock.LOCK_FILE.read_text().replace(f"numpy=={pins['numpy']}", "numpy==1.26.4")
    (tmp_path / "constraints.txt").write_text(text)
    monkeypatch.setattr(versionlock, "LOCK_FILE", tmp_path / "constraints.txt")
    res = cli("selftest")  # every output matches: a warning, exit 0
    assert res.exit_code == 0, res.output
    warning, line = res.output.splitlines()
    assert warning == (f"warning: installed versions other than the lock: numpy {pins['numpy']} "
                       f"(lock 1.26.4); they make the reference bytes here")
    assert line.startswith(f"selftest: all {len(selftest.read_reference().outputs)} outputs match "
                           f"the reference (KITTI-S within 1 grey level), versions not as locked, in ")
    # an output differing as well: exit 1, the versions named beside it
    tampered_reference(tmp_path, monkeypatch, "custom/fog/3/street.png", 3)
    res = cli("selftest")
    assert res.exit_code == 1
    assert res.output.splitlines() == [
        "custom:fog/3: 1 of 1 outputs differ from the reference, largest difference 3 grey levels",
        f"installed versions other than the lock: numpy {pins['numpy']} (lock 1.26.4)",
        f"selftest: 1 of {len(selftest.read_reference().outputs)} outputs differ from the reference; "
        f"this is not the locked install"]
    # the maintainer's command refuses to record from such an install
    from robodepth_cli.selftest.__main__ import main

    assert main(["--record"]) == 2


def test_without_pyav_only_the_codec_outputs_are_skipped(cli, prebuilt, monkeypatch):
    monkeypatch.setattr(selftest, "absent", lambda: ("av",))
    flags = selftest.build_flags(dict(selftest.BUILDS[1][2]), {})
    assert flags["corruptions"] == "frame_lost,frame_freeze"
    res = cli("selftest")
    assert res.exit_code == 0, res.output
    ref = selftest.read_reference().outputs
    codec = sum(1 for e in ref.values() if e["corruption"] in selftest.CODEC)
    assert codec == 3 * 6 * 3
    assert res.output.splitlines()[0] == "skipped h264_crf, h265_crf, bit_error: PyAV (av) is not installed"
    assert f"all {len(ref) - codec} outputs match" in res.output.splitlines()[1]


def test_without_torch_only_kitti_s_is_skipped(cli, prebuilt, monkeypatch):
    monkeypatch.setattr(selftest, "absent", lambda: ("torch",))
    res = cli("selftest")
    assert res.exit_code == 0, res.output
    ref = selftest.read_reference().outputs
    styles = sum(1 for k in ref if k.startswith("kitti-s/"))
    assert styles == 2  # clean and sketch
    assert res.output.splitlines()[0] == "skipped KITTI-S: torch is not installed"
    assert f"all {len(ref) - styles} outputs match" in res.output.splitlines()[1]


def test_without_torch_no_kitti_s_build_is_tried(tmp_path, monkeypatch):
    from types import SimpleNamespace

    from robodepth_cli.building import pipeline

    built = []
    monkeypatch.setattr(selftest, "absent", lambda: ("torch",))
    monkeypatch.setattr(pipeline, "build", lambda cfg, root, out, **kw: (
        built.append((cfg.dataset, out.name)), SimpleNamespace(fatal="", interrupted=False))[1])
    selftest.build_all(tmp_path)
    assert built == [("custom", "custom"), ("kitti-c", "sequence"), ("kitti-c", "neighbours")]
    assert not list(tmp_path.glob("*.pth"))


def test_a_reference_of_other_builds_is_refused(tmp_path, cli, monkeypatch):
    meta = json.loads((selftest.DATA / selftest.REFERENCE).read_text())
    meta["plan"] = "0" * 16
    (tmp_path / selftest.REFERENCE).write_text(json.dumps(meta))
    shutil.copy(selftest.DATA / selftest.PIXELS, tmp_path)
    monkeypatch.setattr(selftest, "read_reference", lambda: READ_REFERENCE(tmp_path))
    res = cli("selftest")
    assert res.exit_code == 2
    assert "rerun 'make selftest-record' on the locked install" in res.output


def test_random_adain_weights_are_the_seeded_ones(tmp_path):
    import torch

    vgg, _ = selftest.write_random_adain(tmp_path)
    state = torch.load(vgg, weights_only=True)
    rng = np.random.default_rng(selftest.ADAIN_SEED)
    first = rng.standard_normal((3, 3, 1, 1), dtype=np.float32) * np.float32(1.4 / np.sqrt(3))
    np.testing.assert_array_equal(state["0.weight"].numpy(), first)
