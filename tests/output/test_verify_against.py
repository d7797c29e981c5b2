"""`robodepth verify`: the build's recorded versions against the lock, and
`verify OUT --against OTHER`: two builds (or a build and a manifest) compared output by output."""

from __future__ import annotations

import json

import pytest

from tests.helpers.trees import kitti_key, kitti_tree


def _lock() -> dict[str, str]:
    from robodepth_cli.versionlock import LOCK_FILE

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
    from robodepth_cli.versionlock import differences

    lock = {"torch": "2.13.0", "av": "18.1.0", "Pillow": "13.0.0"}
    assert differences({"torch": "2.13.0+cpu", "pillow": "13.0.0"}, lock) == []
    assert differences({"torch": "2.12.1+cu128"}, lock) == ["torch 2.12.1+cu128 (lock 2.13.0)"]
    # A library a build did not record (or had not installed) says nothing about its bytes;
    # an install that lacks it is named when asked.
    assert differences({"av": "not installed"}, lock) == []
    assert differences({"av": "not installed", "torch": "2.13.0", "Pillow": "13.0.0"}, lock,
                       missing=True) == ["av not installed (lock 18.1.0)"]


def _twin(build, to):
    """A copy of ``build`` where contrast/1 of frame 3 has other pixels (+2 on one pixel, its
    manifest row updated) and gaussian_noise/2 of frame 4 was never built."""
    import hashlib
    import shutil

    import numpy as np
    from PIL import Image

    shutil.copytree(build, to)
    changed, dropped = f"contrast/1/{kitti_key(3)}", f"gaussian_noise/2/{kitti_key(4)}"
    old = hashlib.sha256((to / changed).read_bytes()).hexdigest()
    img = np.asarray(Image.open(to / changed)).copy()
    img[5, 7, 1] = img[5, 7, 1] + 2 if img[5, 7, 1] < 250 else img[5, 7, 1] - 2
    Image.fromarray(img).save(to / changed)
    new = hashlib.sha256((to / changed).read_bytes()).hexdigest()
    (to / dropped).unlink()
    lines = (to / "manifest.csv").read_text().splitlines(keepends=True)
    lines = [ln.replace(old, new) for ln in lines if not ln.startswith(dropped + ",")]
    (to / "manifest.csv").write_text("".join(lines))
    return to


def test_against_a_twin_build_counts_per_variant(tmp_path, cli, small_build):
    import shutil

    twin = _twin(small_build, tmp_path / "twin")
    res = cli("verify", small_build, "--against", twin)
    assert res.exit_code == 1, res.output
    lines = res.output.splitlines()
    assert "clean: 2 identical, 0 differ, 0 missing here, 0 missing there" in lines
    assert ("contrast/1: 1 identical, 1 differ, 0 missing here, 0 missing there, "
            "largest pixel difference 2") in lines
    assert "contrast/2: 2 identical, 0 differ, 0 missing here, 0 missing there" in lines
    assert "gaussian_noise/2: 1 identical, 0 differ, 0 missing here, 1 missing there" in lines
    assert f"{small_build}: 2 of 10 outputs differ from {twin} or are missing on one side" in lines
    # the other way round: OUT lacks what OTHER has
    back = cli("verify", twin, "--against", small_build)
    assert back.exit_code == 1
    assert "gaussian_noise/2: 1 identical, 0 differ, 1 missing here, 0 missing there" in back.output
    # an identical copy, given as a folder or as its manifest
    same = tmp_path / "same"
    shutil.copytree(small_build, same)
    for other in (same, same / "manifest.csv"):
        ok = cli("verify", small_build, "--against", other)
        assert ok.exit_code == 0, ok.output
        assert ok.output.splitlines()[-1] == f"{small_build}: all 10 outputs identical to {other}"


def test_against_a_manifest_alone_counts_without_pixels(tmp_path, cli, small_build):
    twin = _twin(small_build, tmp_path / "twin")
    alone = tmp_path / "elsewhere" / "manifest.csv"
    alone.parent.mkdir()
    alone.write_bytes((twin / "manifest.csv").read_bytes())
    res = cli("verify", small_build, "--against", alone)
    assert res.exit_code == 1
    assert ("contrast/1: 1 identical, 1 differ, 0 missing here, 0 missing there, 1 differing with "
            "no pixel difference taken (a file missing, unreadable or of another size)") in res.output


def test_against_refuses_what_is_not_a_build(tmp_path, cli, small_build):
    for other, why in ((tmp_path / "nowhere", "does not exist"),
                       (tmp_path, "no manifest.csv; give a robodepth build, an export or a manifest.csv")):
        res = cli("verify", small_build, "--against", other)
        assert res.exit_code == 2
        assert res.output.strip() == f"robodepth: error: --against: {other}: {why}"


def _nudge(png, by=3):
    """Change one pixel of ``png`` by ``by`` grey levels, leaving its manifest row alone."""
    import numpy as np
    from PIL import Image

    img = np.asarray(Image.open(png)).copy()
    img[2, 3, 0] = img[2, 3, 0] + by if img[2, 3, 0] < 250 else img[2, 3, 0] - by
    Image.fromarray(img).save(png)


def test_files_on_disk_are_compared_not_what_the_manifests_claim(tmp_path, cli, small_build):
    import shutil

    other = tmp_path / "other"
    shutil.copytree(small_build, other)
    changed, deleted = f"contrast/1/{kitti_key(3)}", f"gaussian_noise/2/{kitti_key(4)}"
    _nudge(other / changed)
    (other / deleted).unlink()
    res = cli("verify", small_build, "--against", other)
    assert res.exit_code == 1, res.output
    lines = res.output.splitlines()
    assert ("contrast/1: 1 identical, 1 differ, 0 missing here, 0 missing there, "
            "largest pixel difference 3") in lines
    assert "gaussian_noise/2: 1 identical, 0 differ, 0 missing here, 1 missing there" in lines
    assert lines[-1] == f"{small_build}: 2 of 10 outputs differ from {other} or are missing on one side"
    # the other way round: OUT's own check and the comparison agree
    back = cli("verify", other, "--against", small_build)
    assert back.exit_code == 1
    lines = back.output.splitlines()
    assert f"  {changed}" in lines and f"  {deleted}" in lines  # verify's changed and missing
    assert ("contrast/1: 1 identical, 1 differ, 0 missing here, 0 missing there, "
            "largest pixel difference 3") in lines
    assert "gaussian_noise/2: 1 identical, 0 differ, 1 missing here, 0 missing there" in lines
    assert not any("all 10 outputs identical" in ln for ln in lines)
    assert lines[-1] == f"{other}: 2 of 10 outputs differ from {small_build} or are missing on one side"


@pytest.mark.parametrize("fmt", ["parquet", "webdataset"])
def test_against_an_export_of_the_build(tmp_path, cli, small_build, fmt):
    import shutil

    export = tmp_path / "export"
    res = cli("export", small_build, "--format", fmt, "--to", export, "--no-progress")
    assert res.exit_code == 0, res.output
    ok = cli("verify", small_build, "--against", export)
    assert ok.exit_code == 0, ok.output
    assert ok.output.splitlines()[-1] == f"{small_build}: all 10 outputs identical to {export}"
    mine = tmp_path / "mine"
    shutil.copytree(small_build, mine)
    _nudge(mine / f"contrast/2/{kitti_key(4)}", by=5)
    res = cli("verify", mine, "--against", export)
    assert res.exit_code == 1
    assert ("contrast/2: 1 identical, 1 differ, 0 missing here, 0 missing there, "
            "largest pixel difference 5") in res.output.splitlines()
