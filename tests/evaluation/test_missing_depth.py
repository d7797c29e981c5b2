"""A build with depth where some image has no usable depth map (missing, unreadable, in
another unit): predict and export take it, evaluate leaves those images out with one line,
the build warns about maps in a wrong unit, and no message quotes a Python API."""

from __future__ import annotations

import numpy as np

from tests.helpers.trees import random_image, save

H, W = 40, 48
MODEL = '''
import numpy as np

def depth(images):
    return (2.0 + images.mean(axis=3) / 25.5).astype(np.float32)
'''


def _tree(root, names):
    """Images img/<n>.png and depth/<n>.npy: a plausible map for "a" and "d", none for "b",
    millimetres-like floats (5000-81000 "m") for "c"."""
    maps = {"a": np.linspace(2, 30, H * W, dtype=np.float32).reshape(H, W),
            "c": np.linspace(5000, 81000, H * W, dtype=np.float32).reshape(H, W),
            "d": np.full((H, W), 9.0, np.float32)}
    (root / "depth").mkdir(parents=True)
    for i, n in enumerate(names):
        save(root / "img" / f"{n}.png", random_image(H, W, seed=i))
        if n in maps:
            np.save(root / "depth" / f"{n}.npy", maps[n])
    return root / "img", root / "depth"


def _build(cli, img, depth, out, code=1):
    res = cli("build", "custom", "--root", img, "--depth", depth, "--out", out, "--corruptions",
              "fog_3d,brightness", "--levels", "2", "--jobs", "1")
    assert res.exit_code == code, res.output
    return res.output


def _predict_evaluate(cli, tmp_path, where, name):
    (tmp_path / "m.py").write_text(MODEL)
    pred = tmp_path / f"P_{name}"
    res = cli("predict", where, "-m", f"python:{tmp_path / 'm.py'}:depth", "--kind", "depth", "-o", pred)
    assert res.exit_code == 0, res.output
    predicted = res.output
    res = cli("evaluate", where, "--pred", pred, "--out", tmp_path / f"{name}.csv")
    assert res.exit_code == 0, res.output
    return predicted, res.output, (tmp_path / f"{name}.csv").read_text()


def test_images_without_usable_depth_are_predicted_exported_and_left_out(tmp_path, cli):
    img, depth = _tree(tmp_path / "all", "abcd")
    out = tmp_path / "out"
    built = _build(cli, img, depth, out)
    warned = [ln for ln in built.splitlines() if "median depth above 1000 m" in ln]
    assert len(warned) == 1 and "c.npy" in warned[0], built
    predicted, evaluated, results = _predict_evaluate(cli, tmp_path, out, "tree")
    assert "1 image(s) without a usable depth map" in predicted and "b.png" in predicted
    left = [ln for ln in evaluated.splitlines() if ln.startswith("robodepth: left out")]
    assert len(left) == 1 and left[0].startswith("robodepth: left out 2 of 4 images without usable "
                                                 "ground truth (b.png: "), evaluated
    assert "c.png: " in left[0]
    # The means are those of the images with ground truth: a build of a and d alone.
    only_img, only_depth = _tree(tmp_path / "ad", "ad")
    _build(cli, only_img, only_depth, tmp_path / "ad_out", code=0)
    assert results == _predict_evaluate(cli, tmp_path, tmp_path / "ad_out", "ad")[2]
    # The export takes the build (without b's ground truth and depth-aware image), verifies,
    # and evaluates the same.
    res = cli("export", out, "--format", "parquet", "--to", tmp_path / "hf", "--no-progress")
    assert res.exit_code == 0, res.output
    assert "1 image(s) without a usable depth map" in res.output
    assert cli("verify", tmp_path / "hf").exit_code == 0
    res = cli("evaluate", tmp_path / "hf", "--pred", tmp_path / "P_tree", "--out", tmp_path / "hf.csv")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "hf.csv").read_text() == results


def test_predict_names_no_python_api_for_a_failed_image(tmp_path, cli):
    root = tmp_path / "root"
    for i in range(2):
        path = save(root / f"img{i}.png", random_image(H, W, seed=i))
    path.write_bytes(path.read_bytes()[:100])  # unreadable: the build fails it
    out = tmp_path / "out"
    assert cli("build", "custom", "--root", root, "--out", out, "--corruptions", "fog", "--levels",
               "2").exit_code == 1
    (tmp_path / "m.py").write_text(MODEL)
    res = cli("predict", out, "-m", f"python:{tmp_path / 'm.py'}:depth", "--kind", "depth", "-o",
              tmp_path / "P")
    assert res.exit_code == 2
    assert "1 of 2 images failed in the build (img1.png" in res.output
    assert "missing=" not in res.output and "images(" not in res.output, res.output
    assert "rerun the build command" in res.output
