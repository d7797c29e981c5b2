"""open_dataset on a build that did not make every image (it exited 1)."""

from __future__ import annotations

import pytest

from robodepth_cli import open_dataset
from robodepth_cli.api import DatasetError, IncompleteBuild

from tests.helpers.trees import random_image, save


@pytest.fixture(scope="module")
def failed_build(tmp_path_factory, cli):
    """A custom build of four images, the second and fourth unreadable (truncated PNGs)."""
    tmp = tmp_path_factory.mktemp("failed")
    root = tmp / "root"
    for i in range(4):
        path = save(root / f"img{i}.png", random_image(40, 48, seed=i))
        if i in (1, 3):
            path.write_bytes(path.read_bytes()[:100])
    out = tmp / "out"
    r = cli("build", "custom", "--root", root, "--out", out, "--corruptions", "fog",
            "--levels", "2")
    assert r.exit_code == 1, r.output
    return root, out


def test_open_says_how_many_failed_and_which(failed_build):
    root, out = failed_build
    with pytest.warns(IncompleteBuild) as caught:
        ds = open_dataset(out)
    (w,) = caught
    message = str(w.message)
    assert message.startswith(f"{out}: 2 of 4 images failed in the build (img1.png: {root / 'img1.png'}: ")
    assert f"img3.png: {root / 'img3.png'}: " in message and "missing='skip'" in message
    assert list(ds.failed) == ["img1.png", "img3.png"]
    assert "2 failed" in repr(ds)


def test_images_raise_up_front_or_skip_the_missing(failed_build):
    _, out = failed_build
    ds = open_dataset(out, warn=False)
    for variant in ds.variants():
        with pytest.raises(DatasetError, match=r": 2 of 4 images failed in the build \(img1\.png: "):
            variant.images()
        paths = variant.images(missing="skip")
        assert [p.name for p in paths] == ["img0.png", "img2.png"]
        assert all(p.is_file() for p in paths)  # the README loop runs through
        assert list(variant.missing) == ["img1.png", "img3.png"]


def test_complete_build_opens_without_a_word(tmp_path, cli, recwarn):
    root = tmp_path / "root"
    save(root / "a.png", random_image(40, 48, seed=1))
    out = tmp_path / "out"
    assert cli("build", "custom", "--root", root, "--out", out, "--corruptions", "fog",
               "--levels", "2").exit_code == 0
    ds = open_dataset(out)
    assert not recwarn.list and ds.failed == {} and ds.incomplete() == ""
    assert [len(v.images()) for v in ds.variants()] == [1, 1]


def test_kittic_skips_or_names_the_missing(failed_build):
    from robodepth_cli import torch as torch_api

    _, out = failed_build
    with pytest.warns(IncompleteBuild):
        with pytest.raises(torch_api.TorchAPIError, match=r"2 of 4 images failed in the build"):
            torch_api.KittiC(out, "fog", 2)
    with pytest.warns(IncompleteBuild):
        ds = torch_api.KittiC(out, "fog", 2, missing="skip")
    assert len(ds) == 2 and [ds[i]["key"] for i in range(2)] == ["img0.png", "img2.png"]
    assert ds[1]["image"].shape == (3, 40, 48)
    with pytest.raises(IndexError):
        ds[2]
