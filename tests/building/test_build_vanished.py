"""A custom build rerun after source images were deleted from its root: the build, its
manifest and its record follow the root as it is now, and the commands that read the
build agree (issue 42)."""

from __future__ import annotations

import json

from tests.helpers.trees import random_image, save


def _build(cli, root, out, *flags):
    return cli("build", "custom", "--root", root, "--out", out, "--corruptions", "brightness",
               "--levels", "3", "-j", "1", *flags)


def _keys(out):
    record = json.loads((out / "build.json").read_text())
    return record["split"]["keys"], sorted(k for p in record["plans"] for k in p["keys"])


def test_a_deleted_source_leaves_the_build_with_one_line(tmp_path, cli):
    root = tmp_path / "src"
    save(root / "a.png", random_image(32, 48, seed=1))
    save(root / "b.png", random_image(32, 48, seed=2))
    (root / "text.png").write_text("not an image")
    out = tmp_path / "OUT"
    assert _build(cli, root, out).exit_code == 1  # text.png fails

    (root / "text.png").unlink()
    r = _build(cli, root, out)
    assert r.exit_code == 0, r.output
    notes = [line for line in r.output.splitlines() if line.startswith("note: dropped")]
    assert notes == ["note: dropped 1 source image no longer in the root (text.png): 2 outputs, "
                     "their manifest rows and its key in the record"], r.output
    v = cli("verify", out)
    assert v.exit_code == 0, v.output
    assert "text.png" not in (out / "manifest.csv").read_text()
    assert _keys(out) == (["a.png", "b.png"], ["a.png", "b.png"])

    # A good image deleted: its outputs, rows and key go too.
    (root / "b.png").unlink()
    r = _build(cli, root, out)
    assert r.exit_code == 0 and "(b.png): 2 outputs" in r.output, r.output
    assert not (out / "clean/b.png").exists() and not (out / "brightness/3/b.png").exists()
    assert _keys(out) == (["a.png"], ["a.png"])
    assert cli("verify", out).exit_code == 0

    model = tmp_path / "m.py"
    model.write_text("def mean(images):\n    return 0.02 + images.mean(axis=3) / 2550\n")
    p = cli("predict", out, "-m", f"python:{model}:mean", "--kind", "disp", "--out",
            tmp_path / "PRED", "--no-progress")
    assert p.exit_code == 0, p.output
    # Images at their own size: one map per image; only a.png is predicted.
    assert sorted(f.name for f in (tmp_path / "PRED" / "clean").iterdir()) == ["a.npy"]
    e = cli("export", out, "--format", "webdataset", "--to", tmp_path / "WDS", "--no-progress")
    assert e.exit_code == 0, e.output
    assert cli("verify", tmp_path / "WDS").exit_code == 0


def test_an_image_left_out_of_a_request_but_still_there_stays(tmp_path, cli):
    root = tmp_path / "src"
    for i, name in enumerate(("a.png", "b.png")):
        save(root / name, random_image(32, 48, seed=i))
    out = tmp_path / "OUT"
    assert _build(cli, root, out).exit_code == 0
    r = _build(cli, root, out, "--limit", "1")
    assert r.exit_code == 0 and "dropped" not in r.output, r.output
    assert (out / "clean/b.png").is_file() and "b.png" in _keys(out)[0]
    assert cli("verify", out).exit_code == 0
