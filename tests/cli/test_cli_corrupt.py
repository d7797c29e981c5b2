"""`robodepth list`, `corrupt` and `preview`: what they write, and one-line errors for bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from robodepth_cli.corruptions import NAMES, REGISTRY, corrupt
from robodepth_cli.imageio import load_clean
from robodepth_cli.seeding import job_rng

from tests.helpers.drawkey import pixels_key
from tests.helpers.paths import REFERENCE

INPUT = REFERENCE / "kitti" / "kitti_like_md2__input.png"
CHEAP = ("brightness", "contrast", "color_quant", "pixelate")


def small_png(tmp_path, name="img.png", size=(48, 64)):
    rng = np.random.default_rng(3)
    arr = rng.integers(0, 256, (*size, 3), dtype=np.uint8)
    path = tmp_path / name
    Image.fromarray(arr).save(path)
    return path


def test_list_shows_every_corruption_in_spec_order(cli):
    res = cli("list")
    assert res.exit_code == 0
    lines = res.output.splitlines()[1:]
    assert [ln.split()[1] for ln in lines] == list(REGISTRY)
    assert len(NAMES) == 18 and list(REGISTRY)[:18] == list(NAMES)
    assert list(REGISTRY)[18:] == ["fog_3d", "near_focus", "far_focus", "motion_3d", "zoom_3d",
                                    "rain_3d"]
    assert "weather & lighting" in lines[0] and "0.1" in lines[0]
    assert "needs depth" in lines[18] and "needs depth" not in lines[17]


def test_list_json_has_parameters_per_level(cli):
    data = json.loads(cli("list", "--format", "json").output)
    by_name = {d["name"]: d for d in data}
    assert by_name["jpeg_compression"]["levels"] == [{"quality": q} for q in (25, 18, 15, 10, 7)]
    assert by_name["shot_noise"]["category"] == "data & processing"
    assert by_name["defocus_blur"]["deterministic"] is True
    assert "Poisson" in by_name["shot_noise"]["formula"]  # the function's docstring


def test_docs_table_comes_from_the_registry(cli):
    from tests.helpers.paths import REPO

    table = cli("list", "--format", "markdown").output.strip()
    assert table in (REPO / "docs" / "corruptions.md").read_text(), \
        "docs/corruptions.md's corruption table is stale: paste `robodepth list --format markdown`"


def test_corrupt_one_writes_the_png(tmp_path, cli):
    out = tmp_path / "z.png"
    res = cli("corrupt", INPUT, "-c", "contrast", "-l", "3", "--out", out)
    assert res.exit_code == 0, res.output
    got = np.asarray(Image.open(out))
    expected = np.asarray(Image.open(REFERENCE / "kitti" / "kitti_like_md2__contrast__3.png"))
    assert np.abs(got.astype(int) - expected).max() <= 1


def test_corrupt_all_levels_makes_name_level_tree(tmp_path, cli):
    res = cli("corrupt", small_png(tmp_path), "-c", ",".join(CHEAP), "-l", "all", "--out", tmp_path / "o")
    assert res.exit_code == 0, res.output
    files = sorted(p.relative_to(tmp_path / "o").as_posix() for p in (tmp_path / "o").rglob("*.png"))
    assert files == sorted(f"{n}/{lv}.png" for n in CHEAP for lv in range(1, 6))


def test_corrupt_size_resizes_with_lanczos(tmp_path, cli):
    src = small_png(tmp_path, size=(96, 128))
    out = tmp_path / "b.png"
    assert cli("corrupt", src, "-c", "color_quant", "-l", "5", "--size", "48x64", "--out", out).exit_code == 0
    clean = np.asarray(Image.open(src).resize((64, 48), Image.LANCZOS))
    assert np.array_equal(np.asarray(Image.open(out)), clean & 0x80)


def test_corrupt_matches_library_call_and_seed(tmp_path, cli):
    src = small_png(tmp_path)
    a, b, c = tmp_path / "a.png", tmp_path / "b.png", tmp_path / "c.png"
    cli("corrupt", src, "-c", "gaussian_noise", "-l", "2", "--seed", "5", "--out", a)
    cli("corrupt", src, "-c", "gaussian_noise", "-l", "2", "--seed", "5", "--out", b)
    cli("corrupt", src, "-c", "gaussian_noise", "-l", "2", "--seed", "6", "--out", c)
    assert a.read_bytes() == b.read_bytes() != c.read_bytes()
    clean = load_clean(src, None)
    expected = corrupt(clean, "gaussian_noise", 2, job_rng(5, "image", "gaussian_noise", 2, pixels_key(clean)))
    assert np.array_equal(np.asarray(Image.open(a)), expected)


def test_byte_identical_copies_draw_alike_whatever_their_names(tmp_path, cli):
    import shutil

    src = small_png(tmp_path)
    copy = tmp_path / "elsewhere" / "frame_copy.png"
    copy.parent.mkdir()
    shutil.copy(src, copy)
    for command, args in (("corrupt", ("-c", "fog", "-l", "3")), ("preview", ("-c", "fog,gaussian_noise"))):
        a, b = tmp_path / f"{command}_a.png", tmp_path / f"{command}_b.png"
        assert cli(command, src, *args, "--out", a).exit_code == 0
        assert cli(command, copy, *args, "--out", b).exit_code == 0
        assert a.read_bytes() == b.read_bytes(), command


@pytest.mark.slow
def test_as_remakes_a_build_image_from_its_clean_one(tmp_path, cli, build_kitti):
    """corrupt --as kitti-c:KEY (KEY: the manifest's source, or the image's path under
    OUT/clean/) of the build's clean image, with the build's seed and severity size, gives the
    pixels of the build's fog/3 and gaussian_noise/2 files (the PNG encoding is the build's
    --png choice)."""
    import json

    from tests.helpers.manifest import manifest_rows
    from tests.helpers.trees import kitti_tree

    split = kitti_tree(tmp_path / "raw", [(3, "l", ".png")])
    out = tmp_path / "OUT"
    res = build_kitti(tmp_path / "raw", split, out, "--size", "64x96", "--corruptions",
                      "fog,gaussian_noise", "--levels", "2,3", "--seed", "7", "--jobs", "1", "--no-gt")
    assert res.exit_code == 0, res.output
    size = (json.loads((out / "build.json").read_text())["config"].get("extra") or {}).get("severity_size")
    rows = manifest_rows(out)
    for variant, level, by in (("fog", "3", "key"), ("gaussian_noise", "2", "source")):
        (row,) = [r for r in rows if r["variant"] == variant and r["level"] == level]
        key = row["output"].split("/", 2)[2]
        clean = out / "clean" / key
        args = ["corrupt", clean, "-c", variant, "-l", level, "--seed", "7", "--as",
                f"kitti-c:{key if by == 'key' else row['source']}", "--out", tmp_path / f"{variant}.png"]
        if size:
            args += ["--severity-size", size]
        res = cli(*args)
        assert res.exit_code == 0, res.output
        got, want = (np.asarray(Image.open(p)) for p in (tmp_path / f"{variant}.png", out / row["output"]))
        assert np.array_equal(got, want), variant
    res = cli("corrupt", clean, "-c", "fog", "-l", "3", "--as", "kitti:x.png", "--out", tmp_path / "x.png")
    assert res.exit_code == 2 and "--as kitti:x.png: expected DATASET:KEY" in res.output


@pytest.mark.parametrize("args,message", [
    (["-c", "fogg", "-l", "1"], "unknown corruption 'fogg'; valid: brightness, dark"),
    (["-c", ",", "-l", "1"], "--corruption: expected a non-empty list"),
    (["-c", "fog", "-l", "6"], "--level: level 6 is out of range; valid levels: 1..5"),
    (["-c", "fog", "-l", "0"], "--level: level 0 is out of range; valid levels: 1..5"),
    (["-c", "fog", "-l", "two"], "--level: 'two' is not a number; levels are 1..5"),
    (["-c", "contrast", "-l", "1", "--size", "12x40"], "at least 32"),
])
def test_corrupt_bad_options_exit_with_one_line(tmp_path, args, message, cli):
    res = cli("corrupt", small_png(tmp_path), *args, "--out", tmp_path / "o.png")
    assert res.exit_code != 0
    assert message in res.output
    assert "Traceback" not in res.output and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("content,message", [
    (None, "no such file"),
    (b"not a png at all", "not an image file"),
    (b"\x89PNG\r\n\x1a\n" + b"\0" * 40, "not an image file"),
])
def test_corrupt_unreadable_image(tmp_path, content, message, cli):
    src = tmp_path / "bad.png"
    if content is not None:
        src.write_bytes(content)
    res = cli("corrupt", src, "-c", "contrast", "-l", "1", "--out", tmp_path / "o.png")
    assert res.exit_code != 0
    assert str(src) in res.output and message in res.output
    assert "Traceback" not in res.output


def test_corrupt_truncated_png(tmp_path, cli):
    good = small_png(tmp_path, "good.png")
    bad = tmp_path / "trunc.png"
    bad.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    res = cli("corrupt", bad, "-c", "contrast", "-l", "1", "--out", tmp_path / "o.png")
    assert res.exit_code != 0 and "trunc.png: unreadable image" in res.output and "Traceback" not in res.output


def test_corrupt_out_is_file_for_many_outputs(tmp_path, cli):
    out = tmp_path / "file"
    out.write_text("x")
    res = cli("corrupt", small_png(tmp_path), "-c", "all", "--out", out)
    assert res.exit_code != 0 and "is a file" in res.output


def test_preview_sheet_has_a_row_per_corruption(tmp_path, cli):
    out = tmp_path / "sheet.png"
    res = cli("preview", small_png(tmp_path), "-c", "contrast,color_quant", "--thumb-width", "64", "--out", out)
    assert res.exit_code == 0, res.output
    sheet = Image.open(out)
    # header + clean row + 2 corruption rows of 48-pixel thumbnails, 5 level columns of 64
    assert sheet.height > 3 * 48 and sheet.width > 5 * 64
    arr = np.asarray(sheet)
    assert arr.std() > 10  # images were pasted, not a blank canvas


def test_preview_draws_a_fixed_chain_once(tmp_path, cli):
    from robodepth_cli.corruptions import render
    from robodepth_cli.imageio import load_clean
    from robodepth_cli.preview import _PAD, contact_sheet

    src = small_png(tmp_path)
    clean = load_clean(src, None)
    levels = [1, 1.5, 2, 5]
    sheet = np.asarray(contact_sheet(clean, ["fog:3+gaussian_noise:2.5", "fog+contrast:2"],
                                     levels, thumb_width=64, key=pixels_key(clean)))
    label_w, head_h, th, tw = 8 + 6 * len("fog:3+gaussian_noise:2.5"), 18, 48, 64  # the sheet's layout

    def cell(row, col):  # row 0 is the clean image
        y, x = head_h + row * (th + _PAD), label_w + col * (tw + _PAD) + _PAD
        return sheet[y:y + th, x:x + tw]

    fixed = render(clean, "fog:3+gaussian_noise:2.5", None, seed=0, dataset="image", key=pixels_key(clean))
    assert np.array_equal(cell(1, 0), fixed)  # drawn once, in the first column
    for col in range(1, len(levels)):
        assert (cell(1, col) == 255).all()  # and nowhere else: the same image nine times says nothing
        # the template takes each column's level
        want = render(clean, f"fog:{levels[col]}+contrast:2", None, seed=0, dataset="image",
                      key=pixels_key(clean))
        assert np.array_equal(cell(2, col), want)
    res = cli("preview", src, "-c", "fog:3+gaussian_noise:2.5", "-l", "1,1.5,2,2.5,3,3.5,4,4.5,5",
              "--thumb-width", "64", "--out", tmp_path / "sheet.png")
    assert res.exit_code == 0, res.output


def test_same_bytes_in_another_process(tmp_path):
    """Same image, name, level and seed give identical bytes in any process and order."""
    src = small_png(tmp_path, size=(64, 80))
    clean = load_clean(src, None)
    names = [n for n in NAMES if not REGISTRY[n].deterministic]
    here = {n: corrupt(clean, n, 3, job_rng(9, "image", n, 3, "img.png")).tobytes() for n in reversed(names)}
    code = (
        "import sys, numpy as np, hashlib\n"
        "from robodepth_cli.corruptions import corrupt\n"
        "from robodepth_cli.imageio import load_clean\n"
        "from robodepth_cli.seeding import job_rng\n"
        f"clean = load_clean({str(src)!r}, None)\n"
        f"for n in {names!r}:\n"
        "    print(n, hashlib.sha256(corrupt(clean, n, 3, job_rng(9, 'image', n, 3, 'img.png')).tobytes()).hexdigest())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    import hashlib

    theirs = dict(line.split() for line in out.splitlines())
    assert theirs == {n: hashlib.sha256(b).hexdigest() for n, b in here.items()}


@pytest.mark.parametrize("command", [["corrupt", "-c", "frost", "-l", "2"], ["preview", "-c", "frost"]])
def test_missing_frost_textures_are_a_clear_error(tmp_path, monkeypatch, command, cli):
    from robodepth_cli.corruptions import frost

    def missing(index):
        raise frost.FrostTextureError("imagecorruptions-imaug is not installed; run `make install`")

    # Textures already decoded in this process would hide the missing package.
    frost.texture_bgr.cache_clear()
    frost.scaled_texture.cache_clear()
    monkeypatch.setattr(frost, "texture_path", missing)
    res = cli(command[0], small_png(tmp_path), *command[1:], "--out", tmp_path / "o.png")
    assert res.exit_code == 2
    assert "imagecorruptions-imaug is not installed" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "o.png").exists()


@pytest.mark.slow
def test_the_severity_page_figure_command_remakes_it_from_a_copy_of_the_frame(tmp_path, cli):
    """docs/severity-and-chains.md's preview command, run on a copy of its frame under
    another name, writes docs/images/severity-and-chains.png byte for byte."""
    import re
    import shlex
    import shutil

    from tests.helpers.paths import REPO as ROOT

    page = (ROOT / "docs" / "severity-and-chains.md").read_text()
    (command,) = re.findall(r"```sh\n(robodepth preview frame\.png .*?)\n```", page, re.S)
    args = shlex.split(command.replace("\\\n", " "))[3:]  # after "robodepth preview frame.png"
    out = args.index("--out")
    figure = ROOT / args[out + 1]
    args[out + 1] = str(tmp_path / "figure.png")
    frame = tmp_path / "another_name.png"
    shutil.copy(REFERENCE / "kitti" / "kitti_like_md2__input.png", frame)
    res = cli("preview", frame, *args)
    assert res.exit_code == 0, res.output
    assert (tmp_path / "figure.png").read_bytes() == figure.read_bytes()
