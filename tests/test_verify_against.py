"""`robodepth verify`: the build's recorded versions against the lock, and
`verify OUT --against OTHER`: two builds (or a build and a manifest) compared output by output."""

from __future__ import annotations

import json

import pytest

from _trees import kitti_tree


def _lock() -> dict[str, str]:
    from robodepth_cli.lock import LOCK_FILE

    pins = {}
    for line in LOCK_FILE.read_text().splitlines():
        if "==" in line and not line.startswith("#"):
            name, version = line.split("==")
            pins[name] = version
    return pins


@pytest.fixture(scope="module")
def small_build(tmp_path_factory):
    """A KITTI-C build of two frames, two corruptions, two levels."""
    from click.testing import CliRunner

    from robodepth_cli.cli import main

    tmp = tmp_path_factory.mktemp("against")
    root = tmp / "kitti_raw"
    split = kitti_tree(root, [(3, "l", ".png"), (4, "l", ".png")])
    out = tmp / "out"
    res = CliRunner().invoke(main, ["build", "kitti-c", "--root", str(root), "--split", str(split),
                                    "--out", str(out), "--size", "64x96", "--corruptions",
                                    "contrast,gaussian_noise", "--levels", "1,2", "--jobs", "1",
                                    "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


def test_verify_names_each_library_built_at_another_version_than_the_lock(tmp_path, cli, small_build):
    import shutil

    same = cli("verify", small_build)
    assert same.exit_code == 0 and "versions" not in same.output, same.output
    out = tmp_path / "older"
    shutil.copytree(small_build, out)
    record = json.loads((out / "build.json").read_text())
    lock = _lock()
    assert record["versions"]["opencv-python-headless"] == lock["opencv-python-headless"]
    record["versions"]["opencv-python-headless"] = "4.12.0.88"
    record["versions"]["numpy"] = "1.26.4"
    record["versions"]["tqdm"] = "0.1"  # decides no pixel: not named
    (out / "build.json").write_text(json.dumps(record))
    res = cli("verify", out)
    assert res.exit_code == 0, res.output  # the files still match their manifest
    (line,) = [ln for ln in res.output.splitlines() if "lock" in ln]
    assert line == (f"{out}: built with other versions than the lock (numpy 1.26.4 (lock "
                    f"{lock['numpy']}); opencv-python-headless 4.12.0.88 (lock "
                    f"{lock['opencv-python-headless']})): the build may not be the reference bytes")


def test_a_torch_build_label_is_the_same_release():
    from robodepth_cli.lock import differences

    lock = {"torch": "2.13.0", "av": "18.1.0", "Pillow": "13.0.0"}
    assert differences({"torch": "2.13.0+cpu", "pillow": "13.0.0"}, lock) == []
    assert differences({"torch": "2.12.1+cu128"}, lock) == ["torch 2.12.1+cu128 (lock 2.13.0)"]
    # A library a build did not record (or had not installed) says nothing about its bytes;
    # an install that lacks it is named when asked.
    assert differences({"av": "not installed"}, lock) == []
    assert differences({"av": "not installed", "torch": "2.13.0", "Pillow": "13.0.0"}, lock,
                       missing=True) == ["av not installed (lock 18.1.0)"]
