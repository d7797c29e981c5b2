"""`robodepth build --png fast|compact`: the same pixels either way, the encoder in the
record, and resume/verify across the two."""

from __future__ import annotations

import io
import json

import numpy as np
from PIL import Image

from robodepth_cli.imageio import encode_png

from tests.helpers.manifest import manifest_by_output
from tests.helpers.trees import kitti_tree, tree

FLAGS = ["--size", "64x96", "--corruptions", "gaussian_noise,contrast", "--levels", "1,5", "--jobs", "1"]


def _pixels(data: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im).copy()


def _record(out) -> dict:
    return json.loads((out / "build.json").read_text())


def _shas(out) -> dict:
    return {o: r["sha256"] for o, r in manifest_by_output(out).items()}


def _kitti(tmp_path):
    root = tmp_path / "kitti_raw"
    return root, kitti_tree(root, [(5, "l", ".png"), (7, "r", ".jpg")])


def test_fast_default_and_compact_build_the_same_pixels(tmp_path, cli, build_kitti):
    root, split = _kitti(tmp_path)
    fast, compact = tmp_path / "fast", tmp_path / "compact"
    assert build_kitti(root, split, fast, *FLAGS).exit_code == 0
    res = build_kitti(root, split, compact, *FLAGS, "--png", "compact")
    assert res.exit_code == 0, res.output
    a, b = tree(fast), tree(compact)
    pngs = sorted(p for p in a if p.endswith(".png"))
    assert set(a) == set(b) and len(pngs) == 10
    for path in pngs:
        np.testing.assert_array_equal(_pixels(a[path]), _pixels(b[path]), err_msg=path)
        assert a[path] != b[path], path  # two encoders, really
        # each file is what its encoder makes of those pixels
        assert a[path] == encode_png(_pixels(a[path]), method="fast")
        assert b[path] == encode_png(_pixels(b[path]), method="compact")
    assert (_record(fast)["png"], _record(compact)["png"]) == ("fast", "compact")
    assert _record(fast)["png_encoder"].startswith("fpng")
    assert _record(compact)["png_encoder"].startswith("opencv-libpng")
    assert "fpng" in _record(fast)["versions"]
    assert cli("verify", fast).exit_code == 0 and cli("verify", compact).exit_code == 0
    # deterministic bytes: a second fast build gives the same manifest
    again = tmp_path / "again"
    assert build_kitti(root, split, again, *FLAGS).exit_code == 0
    assert _shas(again) == _shas(fast)


def test_resume_keeps_the_builds_own_encoder(tmp_path, cli, build_kitti):
    root, split = _kitti(tmp_path)
    out = tmp_path / "out"
    first = ["--size", "64x96", "--corruptions", "contrast", "--levels", "1", "--jobs", "1"]
    assert build_kitti(root, split, out, *first, "--png", "compact").exit_code == 0
    before = tree(out)
    # Resumed and extended without --png: the old files stay, the new ones are compact too.
    res = build_kitti(root, split, out, "--size", "64x96", "--corruptions", "contrast,gaussian_noise",
                      "--levels", "1", "--jobs", "1")
    assert res.exit_code == 0 and "2 written, 4 skipped" in res.output, res.output
    after = tree(out)
    assert all(after[p] == data for p, data in before.items())
    for path, data in after.items():
        if path.endswith(".png"):
            assert data == encode_png(_pixels(data), method="compact"), path
    assert _record(out)["png"] == "compact"
    # Asking for the other encoder is refused before any work, naming both.
    res = build_kitti(root, split, out, *first, "--png", "fast")
    assert res.exit_code == 2
    assert "built with --png compact; --png fast would mix two PNG encoders" in res.output
    assert tree(out) == after
    assert cli("verify", out).exit_code == 0


def test_fast_without_fpng_is_one_line_error(tmp_path, build_kitti, monkeypatch):
    import sys

    root, split = _kitti(tmp_path)
    monkeypatch.setitem(sys.modules, "fpng", None)  # import fpng -> ImportError
    out = tmp_path / "out"
    res = build_kitti(root, split, out, *FLAGS)
    assert res.exit_code == 2
    assert res.output.startswith("robodepth: error: --png fast needs the fpng package")
    assert "pip install fpng" in res.output and "--png compact" in res.output
    assert not out.exists()


def test_png_key_in_a_config_file(tmp_path, build_kitti):
    root, split = _kitti(tmp_path)
    cfg = tmp_path / "c.yaml"
    cfg.write_text("png: compact\n")
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--config", cfg, "--size", "64x96", "--corruptions", "contrast",
                      "--levels", "1", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert _record(out)["png"] == "compact"
    cfg.write_text("png: small\n")
    res = build_kitti(root, split, tmp_path / "bad", "--config", cfg)
    assert res.exit_code == 2
    assert f"{cfg}: png: expected one of fast, compact, got 'small'" in res.output
