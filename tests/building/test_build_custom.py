"""`robodepth build custom`: any folder of images, each at its own size or a given one."""

from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest
from PIL import Image

from robodepth_cli import corruptions, seeding
from robodepth_cli.sources.custom import compile_pattern

from tests.helpers.manifest import manifest_by_output
from tests.helpers.trees import random_image, save, tree

VARIANTS = "fog,gaussian_noise,pixelate"


@pytest.fixture
def build(cli):
    """``build(root, out, *flags)``: ``robodepth build custom`` with three corruptions at
    levels 1 and 3."""
    def run(root, out, *flags):
        return cli("build", "custom", "--root", root, "--out", out, "--corruptions", VARIANTS,
                   "--levels", "1,3", *flags)

    return run


def load(path):
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).copy()


@pytest.fixture
def folder(tmp_path):
    """Three images of three sizes, nested, with upper-case and jpg extensions, plus a
    file that is not an image."""
    root = tmp_path / "city"
    save(root / "berlin" / "f_000.png", random_image(40, 64, seed=1))
    save(root / "berlin" / "f_001.PNG", random_image(48, 36, seed=2))
    save(root / "bonn" / "deep" / "g.jpg", random_image(33, 90, seed=3))
    (root / "notes.txt").write_text("not an image")
    return root


KEYS = {"berlin/f_000.png": (40, 64), "berlin/f_001.png": (48, 36), "bonn/deep/g.png": (33, 90)}
SOURCES = {"berlin/f_000.png": "berlin/f_000.png", "berlin/f_001.png": "berlin/f_001.PNG",
           "bonn/deep/g.png": "bonn/deep/g.jpg"}


def test_layout_own_sizes_and_pixels(folder, tmp_path, build):
    out = tmp_path / "out"
    r = build(folder, out, "--seed", "3")
    assert r.exit_code == 0, r.output
    m = manifest_by_output(out)
    expected = {f"clean/{k}" for k in KEYS} | {f"{v}/{lv}/{k}" for k in KEYS
                                               for v in VARIANTS.split(",") for lv in (1, 3)}
    assert set(tree(out)) == expected == set(m)
    for key, (h, w) in KEYS.items():
        source = load(folder / SOURCES[key])
        clean = load(out / "clean" / key)
        np.testing.assert_array_equal(clean, source)  # no --size: not resized
        for v in VARIANTS.split(","):
            for lv in (1, 3):
                row = m[f"{v}/{lv}/{key}"]
                assert (row["source"], int(row["height"]), int(row["width"])) == (SOURCES[key], h, w)
                # seeded from (seed, "custom", variant, level, key), as SPEC section 4 says
                rng = seeding.job_rng(3, "custom", v, lv, key)
                # at build custom's severity size, 192 x 640
                np.testing.assert_array_equal(load(out / v / str(lv) / key),
                                              corruptions.corrupt(clean, v, lv, rng, severity_size=(192, 640)))
    record = json.loads((out / "build.json").read_text())
    assert record["dataset"] == "custom" and record["config"]["size"] is None
    assert record["split"]["keys"] == sorted(KEYS)


def test_size_resizes_with_lanczos(folder, tmp_path, build):
    out = tmp_path / "out"
    r = build(folder, out, "--size", "32x48")
    assert r.exit_code == 0, r.output
    for key in KEYS:
        with Image.open(folder / SOURCES[key]) as im:
            ref = np.asarray(im.convert("RGB").resize((48, 32), Image.LANCZOS))
        np.testing.assert_array_equal(load(out / "clean" / key), ref)
    assert {(r["height"], r["width"]) for r in manifest_by_output(out).values()} == {("32", "48")}


def test_jobs_1_and_2_identical_and_resume(folder, tmp_path, build):
    a, b = tmp_path / "a", tmp_path / "b"
    assert build(folder, a, "--jobs", "1").exit_code == 0
    assert build(folder, b, "--jobs", "2").exit_code == 0
    assert tree(a) == tree(b)
    before = {p: os.stat(a / p).st_mtime_ns for p in tree(a)}
    (a / "fog" / "3" / "bonn" / "deep" / "g.png").unlink()
    r = build(folder, a, "--jobs", "2")
    assert r.exit_code == 0 and "1 written" in r.output
    assert tree(a) == tree(b)
    assert all(os.stat(a / p).st_mtime_ns == t for p, t in before.items()
               if p != "fog/3/bonn/deep/g.png")
    # a fixed size after own sizes redoes everything
    r = build(folder, a, "--size", "40x40")
    assert r.exit_code == 0 and f"{len(before)} written" in r.output


def test_list_restricts_and_orders(folder, tmp_path, build):
    lst = tmp_path / "list.txt"
    lst.write_text("# two of them\nbonn/deep/g.jpg\n\nberlin/f_000.png\n")
    out = tmp_path / "out"
    r = build(folder, out, "--list", lst)
    assert r.exit_code == 0, r.output
    assert {p.split("/", 1)[1] for p in tree(out) if p.startswith("clean/")} == {"bonn/deep/g.png", "berlin/f_000.png"}
    assert json.loads((out / "build.json").read_text())["split"]["keys"] == ["bonn/deep/g.png", "berlin/f_000.png"]


def test_config_file_and_limit(folder, tmp_path, cli):
    cfg = tmp_path / "mine.yaml"
    cfg.write_text("pattern: 'berlin/*.png'\ncorruptions: [contrast]\nlevels: [2]\n")
    out = tmp_path / "out"
    r = cli("build", "custom", "--root", folder, "--out", out, "--config", cfg, "--limit", "1")
    assert r.exit_code == 0, r.output
    # case-insensitive: f_001.PNG matches too, and sorts after f_000.png; the limit keeps one
    assert set(tree(out)) == {"clean/berlin/f_000.png", "contrast/2/berlin/f_000.png"}


def test_collision_refused_before_any_work(folder, tmp_path, build):
    save(folder / "berlin" / "f_000.jpg", random_image(40, 40, seed=9))
    out = tmp_path / "out"
    r = build(folder, out)
    assert r.exit_code == 2
    assert "berlin/f_000.jpg and berlin/f_000.png would both be written as berlin/f_000.png" in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize("flags,message", [
    (["--pattern", "**/*.{png,jpg}"], "braces are not supported"),
    (["--pattern", "a**/*.png"], "'**' must be a whole path component"),
    (["--pattern", "**/[ab.png"], "unclosed '['"),
    (["--pattern", "../*.png"], "'..' component"),
    (["--pattern", "**/*.gif"], "no file matches **/*.gif"),
    (["--split", "eigen_test"], "custom has no split"),
])
def test_bad_input_is_one_line(folder, tmp_path, flags, message, build):
    out = tmp_path / "out"
    r = build(folder, out, *flags)
    assert r.exit_code == 2, r.output
    assert message in r.output and r.output.startswith("robodepth: error:")
    assert len(r.output.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize("line", ["../outside.png", "/etc/passwd", "berlin/../../x.png"])
def test_list_line_escaping_the_root(folder, tmp_path, line, build):
    lst = tmp_path / "list.txt"
    lst.write_text(f"berlin/f_000.png\n{line}\n")
    r = build(folder, tmp_path / "out", "--list", lst)
    assert r.exit_code == 2 and f"{lst}:2:" in r.output, r.output


def test_pattern_and_list_together_refused(folder, tmp_path, build):
    lst = tmp_path / "list.txt"
    lst.write_text("berlin/f_000.png\n")
    r = build(folder, tmp_path / "out", "--list", lst, "--pattern", "**/*.png")
    assert r.exit_code == 2 and "give one of them" in r.output


def test_small_image_fails_alone_symlink_out_is_followed(folder, tmp_path, build):
    save(folder / "tiny.png", random_image(20, 50, seed=4))
    outside = save(tmp_path / "elsewhere.png", random_image(40, 40, seed=5))
    os.symlink(outside, folder / "link.png")
    out = tmp_path / "out"
    r = build(folder, out)
    assert r.exit_code == 1, r.output
    m = manifest_by_output(out)
    assert "too small" in m["clean/tiny.png"]["error"]
    # symlinks under the root are followed wherever they lead, as for the presets
    assert not m["clean/link.png"]["error"]
    assert all(not m[f"clean/{k}"]["error"] for k in KEYS)


def test_out_inside_root_is_refused(folder, build):
    r = build(folder, folder / "corrupted")
    assert r.exit_code == 2 and "inside --root" in r.output, r.output


def test_pattern_semantics():
    rx = compile_pattern("**/*_leftImg8bit.png")
    assert rx.fullmatch("a_leftImg8bit.png") and rx.fullmatch("val/berlin/a_leftimg8bit.PNG")
    assert not rx.fullmatch("val/a_leftImg8bit.png.bak")
    rx = compile_pattern("val/*/f_?.jpg")
    assert rx.fullmatch("val/x/f_1.jpg") and not rx.fullmatch("val/x/y/f_1.jpg")
    assert not rx.fullmatch("val/x/f_12.jpg")
    rx = compile_pattern("[!a]*.png")
    assert rx.fullmatch("b.png") and not rx.fullmatch("a.png") and not rx.fullmatch("d/b.png")


def test_pattern_help_and_preset_name_every_default_extension(cli):
    from robodepth_cli.sources.custom import IMAGE_EXTS

    from tests.helpers.paths import REPO

    help_text = " ".join(cli("build", "--help").output.split())
    default = help_text[help_text.index("--pattern"):].split("at any depth")[0]
    preset = (REPO / "configs" / "custom.yaml").read_text().split("\n")[0]
    for ext in IMAGE_EXTS:
        assert re.search(rf"\b{ext}\b", default), (ext, default)
        assert re.search(rf"\b{ext}\b", preset), (ext, preset)


def _tagged_png(path, stored, orientation):
    exif = Image.Exif()
    exif[0x0112] = orientation
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(stored).save(path, exif=exif)


def test_exif_orientation_is_applied_and_recorded(tmp_path, build, cli):
    # Stored 64 wide x 48 high. Orientation 6 means "rotate 90 degrees clockwise to
    # display", 3 "rotate 180", 2 "mirror left-right" (the EXIF standard's table).
    stored = random_image(48, 64, seed=7)
    root = tmp_path / "phone"
    _tagged_png(root / "cw.png", stored, 6)
    _tagged_png(root / "flip.png", stored, 3)
    _tagged_png(root / "mirror.png", stored, 2)
    save(root / "plain.png", stored)
    out = tmp_path / "out"
    r = build(root, out)
    assert r.exit_code == 0, r.output
    upright = {"cw.png": np.rot90(stored, k=-1), "flip.png": stored[::-1, ::-1],
               "mirror.png": stored[:, ::-1], "plain.png": stored}
    m = manifest_by_output(out)
    for name, want in upright.items():
        np.testing.assert_array_equal(load(out / "clean" / name), want)
        got = load(out / "fog" / "3" / name)
        assert got.shape == want.shape
        row = m[f"fog/3/{name}"]
        assert (int(row["height"]), int(row["width"])) == want.shape[:2]
    # Said, and recorded: which sources were turned.
    assert "3 source images turned upright by their EXIF orientation" in r.output
    record = json.loads((out / "build.json").read_text())
    assert record["exif_orientation"] == {"applied": True,
                                          "turned": ["cw.png", "flip.png", "mirror.png"]}
    # A rerun finds everything done (the turned sizes are the recorded ones).
    r = build(root, out)
    assert r.exit_code == 0 and re.search(r"\b0 written", r.output), r.output
    assert cli("verify", out).exit_code == 0


def _stop_at_write(monkeypatch, n, exc=KeyboardInterrupt):
    """Make the build's ``n``-th PNG write raise ``exc`` (the earlier ones are written): a
    stop in the middle of one source image's outputs."""
    from robodepth_cli.building import jobs

    real, calls = jobs.write_png, []

    def write_png(*args, **kwargs):
        calls.append(args[0])
        if len(calls) == n:
            raise exc
        return real(*args, **kwargs)

    monkeypatch.setattr(jobs, "write_png", write_png)


def test_interrupt_mid_image_keeps_and_records_what_was_written(folder, tmp_path, build, cli,
                                                                monkeypatch):
    out = tmp_path / "out"
    per_image = 1 + 3 * 2
    _stop_at_write(monkeypatch, 5)  # four outputs of the first image are on disk
    r = build(folder, out, "--jobs", "1")
    monkeypatch.undo()
    assert r.exit_code == 130, r.output
    assert r.output.startswith("custom: 4 written, 0 skipped"), r.output
    assert "stopped after 4 of 21 outputs" in r.output
    m = manifest_by_output(out)
    assert set(m) == set(tree(out)) and len(m) == 4
    v = cli("verify", out)
    assert "extra" not in v.output and f"incomplete: 4 of {3 * per_image} outputs" in v.output
    r = build(folder, out, "--jobs", "1")
    assert r.exit_code == 0 and f"{3 * per_image - 4} written, 4 skipped" in r.output, r.output
    assert cli("verify", out).exit_code == 0


def test_killed_mid_image_the_rerun_reuses_what_was_written(folder, tmp_path, build, cli,
                                                            monkeypatch):
    from robodepth_cli.building import pipeline

    out = tmp_path / "out"
    per_image = 1 + 3 * 2

    class Killed(BaseException):
        """Stands for SIGKILL: nothing after it runs, not even the build's own clean-up."""

    _stop_at_write(monkeypatch, per_image + 3, Killed)  # one whole image, then two outputs
    with pytest.raises(Killed):
        pipeline.build(__import__("robodepth_cli.building.config", fromlist=["resolve"]).resolve(
            "custom", None, {"corruptions": VARIANTS, "levels": "1,3", "jobs": "1"}), folder, out)
    monkeypatch.undo()
    from robodepth_cli.output.layout import JOURNAL

    assert len(tree(out)) == per_image + 2 and (out / JOURNAL).is_dir()
    # The record of the two outputs of the image in flight survived the kill: verify counts
    # them (no "extra"), and the rerun keeps them instead of making them again.
    v = cli("verify", out)
    assert "extra" not in v.output and f"incomplete: {per_image + 2} of" in v.output, v.output
    r = build(folder, out, "--jobs", "1")
    done = per_image + 2
    assert r.exit_code == 0 and f"{3 * per_image - done} written, {done} skipped" in r.output, r.output
    assert cli("verify", out).exit_code == 0 and not (out / JOURNAL).exists()


def test_presets_read_their_sources_as_stored(tmp_path, cli):
    # The benchmarks' own frames carry no orientation tag and are built as stored; a tag in
    # a preset's source changes nothing (the published datasets were made that way).
    from tests.helpers.trees import nyu_tree

    root = tmp_path / "nyu"
    split = nyu_tree(root, ["bedroom/rgb_00001.jpg"])
    stored = random_image(48, 64, seed=4)
    path = root / "bedroom" / "rgb_00001.jpg"
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(stored).save(path, exif=exif, quality=95)
    out = tmp_path / "out"
    r = cli("build", "nyudepth2-c", "--root", root, "--split", split, "--out", out,
            "--corruptions", "contrast", "--levels", "1", "--no-gt", "--size", "48x64")
    assert r.exit_code == 0, r.output
    with Image.open(path) as im:
        as_stored = np.asarray(im.convert("RGB"))
    np.testing.assert_array_equal(load(out / "clean" / "bedroom" / "rgb_00001.png"), as_stored)
    assert "EXIF" not in r.output
    assert "exif_orientation" not in json.loads((out / "build.json").read_text())
