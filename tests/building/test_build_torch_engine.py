"""`build --engine torch --device ...`: the torch engine renders kitti-c, nyudepth2-c and
custom builds with the same layout, manifest, resume and verify; the outputs are compared
with a numpy-engine build of the same sources (the reference)."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
import torch
from PIL import Image

from tests.helpers.manifest import manifest_rows
from tests.helpers.trees import kitti_tree, nyu_tree, random_image, save, tree

# Byte-identical on CPU torch (docs/torch-engine.md); glass_blur runs through the numpy engine.
IDENTICAL = "fog,gaussian_noise,zoom_blur,pixelate,glass_blur"


def pixels(data: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB")).astype(int)


def record(out):
    return json.loads((out / "build.json").read_text())


def params(out) -> set[str]:
    return {r["params"] for r in manifest_rows(out) if not r["output"].startswith("clean/")}


@pytest.fixture(scope="module")
def kitti(tmp_path_factory):
    root = tmp_path_factory.mktemp("k") / "kitti_raw"
    return root, kitti_tree(root, [(5, "l", ".png"), (7, "r", ".png")], size=(48, 96))


def test_kitti_c_torch_build_matches_the_numpy_build(kitti, tmp_path, build_kitti, cli):
    root, split = kitti
    flags = ("--corruptions", IDENTICAL + ",defocus_blur", "--levels", "1,3", "--size", "40x72", "--jobs", "1")
    ref, out = tmp_path / "numpy", tmp_path / "torch"
    assert build_kitti(root, split, ref, *flags).exit_code == 0
    res = build_kitti(root, split, out, *flags, "--engine", "torch", "--device", "cpu")
    assert res.exit_code == 0, res.output
    a, b = tree(ref), tree(out)
    assert set(a) == set(b) and len(a) == 2 * (1 + 6 * 2)
    for path in a:
        if path.startswith("defocus_blur/3/"):  # the FFT level: within one grey level
            diff = np.abs(pixels(a[path]) - pixels(b[path]))
            assert diff.max() <= 1 and (diff == 0).mean() > 0.95, path
        else:
            assert a[path] == b[path], path
    assert record(out)["config"]["extra"] == {"engine": "torch", "device": "cpu", "severity_size": "none"}
    assert record(ref)["config"]["extra"] == {"engine": "numpy", "device": "cpu", "severity_size": "none"}
    assert params(out) == {"engine=torch"} and params(ref) == {""}
    # Resume and verify as for any build.
    again = build_kitti(root, split, out, *flags, "--engine", "torch", "--device", "cpu")
    assert again.exit_code == 0 and "0 written, 26 skipped" in again.output, again.output
    assert cli("verify", out).exit_code == 0
    # The other engine in the same OUT makes the corrupted outputs again, never a mix.
    switched = build_kitti(root, split, out, *flags)
    assert switched.exit_code == 0 and "24 written, 2 skipped" in switched.output, switched.output
    assert tree(out) == a and params(out) == {""}
    assert cli("verify", out).exit_code == 0


@pytest.mark.slow
def test_nyu_and_custom_torch_builds_match_the_numpy_builds(tmp_path, cli):
    nyu = tmp_path / "nyu"
    split = nyu_tree(nyu, ["bathroom/rgb_00045.jpg", "kitchen/rgb_00046.jpg"], size=(48, 64))
    custom = tmp_path / "photos"
    save(custom / "a.png", random_image(40, 56, 1))
    save(custom / "sub" / "b.png", random_image(36, 64, 2))  # each its own size
    for dataset, root, extra in (("nyudepth2-c", nyu, ("--split", split, "--size", "48x64", "--no-gt")),
                                 # the torch engine does not scale: both at none
                                 ("custom", custom, ("--severity-size", "none"))):
        outs = {}
        for engine in ("numpy", "torch"):
            outs[engine] = tmp_path / f"{dataset}-{engine}"
            # The torch build in a pool of two workers: the renderer travels to them.
            res = cli("build", dataset, "--root", root, "--out", outs[engine], "--corruptions",
                      "brightness,motion_blur,shot_noise", "--levels", "2", "--engine", engine,
                      "--jobs", "2" if engine == "torch" else "1", *extra)
            assert res.exit_code == 0, res.output
        assert tree(outs["numpy"]) == tree(outs["torch"]) and len(tree(outs["torch"])) == 8


@pytest.mark.parametrize("flags, message", [
    (("--device", "cuda"), "--device: cuda needs --engine torch (the numpy engine runs on the CPU)"),
    (("--engine", "torch", "--device", "tpu"), "--device: expected one of auto, cpu, cuda, got 'tpu'"),
])
def test_refusals(kitti, tmp_path, build_kitti, flags, message):
    root, split = kitti
    res = build_kitti(root, split, tmp_path / "out", "--corruptions", "fog", "--levels", "1", *flags)
    assert res.exit_code == 2 and f"robodepth: error: {message}" in res.output, res.output
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the refusal on a machine without CUDA")
def test_cuda_refused_without_a_gpu_before_any_work(kitti, tmp_path, build_kitti):
    root, split = kitti
    res = build_kitti(root, split, tmp_path / "out", "--corruptions", "fog", "--levels", "1",
                      "--engine", "torch", "--device", "cuda")
    assert res.exit_code == 2 and "--device: device 'cuda': torch sees no CUDA GPU here" in res.output, res.output
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_cuda_build_is_within_one_level_of_the_numpy_build(kitti, tmp_path, build_kitti):
    root, split = kitti
    flags = ("--corruptions", "fog,gaussian_noise,zoom_blur,snow", "--levels", "3", "--size", "40x72", "--jobs", "1")
    assert build_kitti(root, split, tmp_path / "n", *flags).exit_code == 0
    assert build_kitti(root, split, tmp_path / "t", *flags, "--engine", "torch", "--device", "cuda").exit_code == 0
    a, b = tree(tmp_path / "n"), tree(tmp_path / "t")
    assert record(tmp_path / "t")["config"]["extra"]["device"] == "cuda"
    for path in a:
        assert (np.abs(pixels(a[path]) - pixels(b[path])) <= 1).mean() >= 0.999, path


def test_custom_torch_build_says_the_presets_severity_size_gives_way(tmp_path, cli):
    # It went to none without a word (issue 42); a severity size asked for is refused.
    save(tmp_path / "photos" / "a.png", random_image(40, 56, 1))
    args = ("build", "custom", "--root", tmp_path / "photos", "--corruptions", "brightness",
            "--levels", "1", "--engine", "torch", "--device", "cpu", "--jobs", "1")
    res = cli(*args, "--out", tmp_path / "out")
    assert res.exit_code == 0, res.output
    notes = [ln for ln in res.output.splitlines() if ln.startswith("note:")]
    assert notes == ["note: --engine torch: the levels are not scaled to the preset's severity size "
                     "192x640 (severity size none: each level as tabulated, at any image size; "
                     "--engine numpy scales them)"], res.output
    assert record(tmp_path / "out")["config"]["extra"]["severity_size"] == "none"
    assert "note:" not in cli(*args, "--severity-size", "none", "--out", tmp_path / "o2").output
    refused = cli(*args, "--severity-size", "192x640", "--out", tmp_path / "o3")
    assert refused.exit_code == 2 and "does not scale the levels" in refused.output
