"""Builds facing bad input, hostile files, kills, interrupts, concurrent builds and full disks.

Two kinds of failure (docs/datasets-and-layout.md, "When a build goes wrong"):
- whole-build problems are refused before any work: one line ``robodepth: error: <file or
  flag>: <problem>``, exit 2, OUT not created;
- per-image problems fail that image's outputs only: a row with an error in the manifest, a
  line in the summary, every other output built, exit 1.
A build stopped by SIGKILL, Ctrl-C or a full disk leaves only complete images, and rerunning
the same command finishes it with exactly the bytes of an uninterrupted build.
"""

from __future__ import annotations

import ast
import errno
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from robodepth_cli import imageio

from robodepth_cli.building import gather

from robodepth_cli.output import manifest
from robodepth_cli.output.folder import OutputFolder

from tests.helpers.messages import one_line_error
from tests.helpers.paths import REPO
from tests.helpers.trees import KITTI_DRIVE, kitti_key, kitti_tree, random_image, save, tree

PACKAGE = REPO / "robodepth_cli"
CLI = [sys.executable, "-m", "robodepth_cli.cli"]
SMALL = ["--size", "64x96", "--corruptions", "contrast", "--levels", "1", "--jobs", "1"]


def decodes(data: bytes) -> bool:
    try:
        with Image.open(io.BytesIO(data)) as im:
            im.load()
        return True
    except Exception:
        return False


def outside(tmp_path: Path, out: Path) -> dict[str, bytes]:
    """Every file under ``tmp_path`` but not under ``out``, with its bytes; links not followed."""
    found = {}
    for dirpath, dirs, files in os.walk(tmp_path):
        if Path(dirpath) == out:
            dirs.clear()
            continue
        for name in files:
            p = Path(dirpath, name)
            found[p.relative_to(tmp_path).as_posix()] = b"link" if p.is_symlink() else p.read_bytes()
    return found


@pytest.fixture
def kitti(tmp_path):
    root = tmp_path / "kitti_raw"
    return root, kitti_tree(root, [(1, "l", ".png"), (2, "l", ".png")])


# --- whole-build problems: one line, exit 2, nothing written --------------------------------

def _split_lines(*lines):
    def setup(tmp_path, root, split):
        split.write_text("".join(line + "\n" for line in lines))
        return [], str(split)
    return setup


def _config(text):
    def setup(tmp_path, root, split):
        cfg = tmp_path / "mine.yaml"
        cfg.write_text(text)
        return ["--config", cfg], str(cfg)
    return setup


def _flags(*flags):
    return lambda tmp_path, root, split: (list(flags), flags[0])


def _missing_root(tmp_path, root, split):
    return ["--root", tmp_path / "nowhere"], str(tmp_path / "nowhere")


def _out_is_a_file(tmp_path, root, split):
    (tmp_path / "taken").write_text("x")
    return ["--out", tmp_path / "taken"], str(tmp_path / "taken")


D = KITTI_DRIVE
WHOLE_BUILD = {
    "missing root": (_missing_root, ": the root directory does not exist"),
    "split line with 2 fields": (_split_lines(f"{D} 0000000001 l", f"{D} 0000000002"),
                                 ":2: expected 3 fields 'DATE/DRIVE FRAME SIDE', got 2"),
    "split line with 4 fields": (_split_lines(f"{D} 0000000001 l r"), ":1: expected 3 fields"),
    "duplicate split lines": (_split_lines(f"{D} 0000000001 l", f"{D} 0000000002 l", f"{D} 1 l"),
                              ":3: duplicate of line 1 (kitti_data/"),
    "empty split": (_split_lines("# no images here", ""), ": the split lists no images"),
    "absolute path in split": (_split_lines("/etc/2011_09_26_drive_0001_sync 0000000001 l"),
                               ":1: folder '/etc/2011_09_26_drive_0001_sync' is not a relative path"),
    "'..' in split": (_split_lines("2011_09_26/../../x 0000000001 l"),
                      ":1: folder '2011_09_26/../../x' has an empty, '.' or '..' component"),
    "YAML that does not parse": (_config("seed: [1\n"), ": not valid YAML (line 2, column 1: expected ','"),
    "unknown YAML key": (_config("seed: 1\nworkers: 2\n"), ": unknown key 'workers'; valid keys: "),
    "unknown corruption in YAML": (_config("corruptions: [fog, sleet]\n"),
                                   ": corruptions: unknown corruption 'sleet'; valid: brightness,"),
    "unknown corruption flag": (_flags("--corruptions", "contrast,fogg"),
                                ": unknown corruption 'fogg'; valid: brightness, dark, fog,"),
    "level 0": (_flags("--levels", "0"), ": level 0 is out of range for kitti-c; valid levels: 1..5"),
    "level 6": (_flags("--levels", "1,6"), ": level 6 is out of range for kitti-c; valid levels: 1..5"),
    "--jobs 0": (_flags("--jobs", "0"), ": expected an integer >= 1, got 0"),
    "output path is a file": (_out_is_a_file, ": exists and is not a directory"),
}


@pytest.mark.parametrize("case", WHOLE_BUILD)
def test_whole_build_problem_is_one_line_and_exit_2(case, kitti, tmp_path, cli):
    setup, problem = WHOLE_BUILD[case]
    root, split = kitti
    flags, named = setup(tmp_path, root, split)
    out = tmp_path / "out"
    args = ["--root", root, "--split", split, "--out", out, "--size", "64x96", "--corruptions", "contrast",
            "--levels", "1", "--jobs", "1"]
    # Later flags win: a case's own --root/--out/--levels/... replaces the default.
    res = cli("build", "kitti-c", *args, *flags)
    one_line_error(res, start=named + problem)
    assert not out.exists()


def test_unknown_dataset(kitti, tmp_path, cli):
    root, split = kitti
    res = cli("build", "kitti-x", "--root", root, "--split", split, "--out", tmp_path / "o2")
    one_line_error(res, start="unknown dataset 'kitti-x'; valid: ")
    assert " custom, " in res.output and " kitti-c, kitti-c-hr, " in res.output
    assert not (tmp_path / "o2").exists()


def test_yaml_is_loaded_safely(kitti, tmp_path, build_kitti):
    """A Python tag in a config is refused by name and never executed."""
    root, split = kitti
    marker = tmp_path / "executed"
    cfg = tmp_path / "evil.yaml"
    for text in (f'seed: !!python/object/apply:os.system ["touch {marker}"]\n',
                 "seed: !!python/object/new:os.system [\"true\"]\n"):
        cfg.write_text(text)
        res = build_kitti(root, split, tmp_path / "out", "--config", cfg)
        one_line_error(res, start=f"{cfg}: line 1, column 7: YAML tag '!!python/object/")
        assert "not allowed (configs are read with a safe loader" in res.output
        assert not marker.exists() and not (tmp_path / "out").exists()


def _calls(tree_: ast.AST):
    for node in ast.walk(tree_):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and isinstance(node.func.value, ast.Name):
            yield node.func.value.id, node.func.attr, node


def test_checkpoints_and_configs_never_unpickle():
    """torch.load only with weights_only=True; no pickle, no unsafe YAML loader, anywhere in
    the package."""
    torch_loads = 0
    for path in sorted(PACKAGE.rglob("*.py")):
        for mod, attr, call in _calls(ast.parse(path.read_text(), str(path))):
            where = f"{path.relative_to(PACKAGE)}:{call.lineno}"
            if (mod, attr) == ("torch", "load"):
                torch_loads += 1
                kw = {k.arg: k.value for k in call.keywords}
                assert isinstance(kw.get("weights_only"), ast.Constant) and kw["weights_only"].value is True, where
            assert not (mod in ("pickle", "cPickle", "dill", "marshal") and attr.startswith("load")), where
            assert not (mod == "yaml" and attr in ("load", "load_all", "unsafe_load", "full_load")), where
    assert torch_loads >= 1  # the AdaIN checkpoints are loaded somewhere: the scan saw them


# --- per-image problems: recorded, the rest is built, exit 1 --------------------------------
# Each case spoils frame 2 (right camera) of a two-frame tree and returns (path, problem).

def _frame(data: Path, ext: str = ".png") -> Path:
    return data / f"{2:010d}{ext}"


def _truncated_png(root, data, tmp_path):
    p = _frame(data)
    p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])
    return p, "unreadable image (image file is truncated"


def _truncated_jpg(root, data, tmp_path):
    _frame(data).unlink()
    p = save(_frame(data, ".jpg"), random_image(60, 200, 5))
    p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])
    return p, "unreadable image (image file is truncated"


def _garbage(root, data, tmp_path):
    _frame(data).write_bytes(b"no image here, just text " * 20)
    return _frame(data), "not an image file Pillow can read"


def _bomb(root, data, tmp_path):
    # A GIF header claiming 46,000 x 42,000 pixels: Pillow's decompression-bomb limit refuses it.
    _frame(data).write_bytes(b"GIF89a" + (46000).to_bytes(2, "little") + (42000).to_bytes(2, "little")
                             + b"\x00\x00\x00" + b"," + bytes(9) + b"\x02\x02\x44\x01\x00;")
    return _frame(data), "unreadable image (Image size (1932000000 pixels) exceeds limit"


def _empty(root, data, tmp_path):
    _frame(data).write_bytes(b"")
    return _frame(data), "not an image file Pillow can read"


def _tiny(side):
    def make(root, data, tmp_path):
        save(_frame(data), random_image(side, side, 3))
        return _frame(data), f"{side}x{side} pixels (HxW) is too small (at least 32x32)"
    return make


def _absent(root, data, tmp_path):
    _frame(data).unlink()
    return _frame(data), "no such file (tried .png, .jpg, .jpeg)"


def _directory(root, data, tmp_path):
    _frame(data).unlink()
    _frame(data).mkdir()
    return _frame(data), "is a directory, not an image file"


PER_IMAGE = {
    "truncated PNG": _truncated_png, "truncated JPEG": _truncated_jpg, "garbage bytes": _garbage,
    "absurd size (decompression bomb)": _bomb,
    "empty file": _empty, "1 x 1 image": _tiny(1), "16 x 16 image": _tiny(16),
    "listed but absent": _absent, "a directory": _directory,
}


@pytest.mark.parametrize("case", PER_IMAGE)
def test_per_image_problem_fails_that_image_only(case, tmp_path, cli, build_kitti):
    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, [(1, "l", ".png"), (2, "r", ".png")])
    bad, problem = PER_IMAGE[case](root, root / KITTI_DRIVE / "image_03" / "data", tmp_path)
    good, spoilt = kitti_key(1), kitti_key(2, "r")
    out = tmp_path / "out"
    before = outside(tmp_path, out)
    res = build_kitti(root, split, out, "--size", "64x96", "--corruptions", "contrast,pixelate",
                      "--levels", "2", "--jobs", "1")

    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output
    # Outputs and source images are counted apart (3 outputs of 1 image failed).
    assert ("3 written, 0 skipped (already done), 3 failed (outputs of 1 image) of 6 outputs "
            "from 2 source images") in res.output
    assert res.output.rstrip().endswith(f"wrote 3 outputs to {out}"), res.output
    message = f"{bad}: {problem}"
    assert any(line.startswith(f"  {message}") for line in res.output.splitlines()), res.output
    files = tree(out)
    assert set(files) == {f"clean/{good}", f"contrast/2/{good}", f"pixelate/2/{good}"}
    assert all(decodes(b) for b in files.values())
    failed = {p: r for p, r in OutputFolder(out).rows().items() if r.error}
    assert set(failed) == {f"clean/{spoilt}", f"contrast/2/{spoilt}", f"pixelate/2/{spoilt}"}
    assert all(r.error.startswith(message) and r.sha256 == "" for r in failed.values())
    v = cli("verify", out)
    assert v.exit_code == 1 and "failed: 3" in v.output
    assert outside(tmp_path, out) == before


def _rgb16(a: np.ndarray) -> np.ndarray:
    return a[..., ::-1] if a.ndim == 3 and a.shape[2] == 3 else a[..., [2, 1, 0, 3]]


def test_gray_alpha_palette_and_16_bit_sources_build_as_rgb(tmp_path, build_kitti):
    """Every PNG pixel format is converted to 8-bit RGB: grey repeated, alpha dropped, a palette
    looked up, 16 bits cut to their top 8 (65535 -> 255, 256 -> 1, 255 -> 0)."""
    h, w = 64, 96
    rng = np.random.default_rng(5)
    data = tmp_path / "kitti_raw" / KITTI_DRIVE / "image_02" / "data"
    data.mkdir(parents=True)
    u8 = lambda *shape: rng.integers(0, 256, (h, w, *shape), dtype=np.uint8)  # noqa: E731
    u16 = lambda *shape: rng.integers(0, 65536, (h, w, *shape), dtype=np.uint16)  # noqa: E731
    expected = {}

    gray = u8()
    Image.fromarray(gray, "L").save(data / "0000000001.png")
    expected[1] = np.repeat(gray[..., None], 3, axis=2)
    la = u8(2)
    Image.fromarray(la, "LA").save(data / "0000000002.png")
    expected[2] = np.repeat(la[..., :1], 3, axis=2)
    rgba = u8(4)
    Image.fromarray(rgba, "RGBA").save(data / "0000000003.png")
    expected[3] = rgba[..., :3]
    palette = rng.integers(0, 256, (256, 3), dtype=np.uint8)
    index = u8()
    im = Image.fromarray(index, "P")
    im.putpalette(palette.tobytes())
    im.save(data / "0000000004.png", transparency=0)
    expected[4] = palette[index]

    g16 = u16()
    g16[0, :6] = [0, 255, 256, 0x7FFF, 0x8000, 0xFFFF]
    assert cv2.imwrite(str(data / "0000000005.png"), g16)
    expected[5] = np.repeat((g16 >> 8).astype(np.uint8)[..., None], 3, axis=2)
    assert list(expected[5][0, :6, 0]) == [0, 0, 1, 127, 128, 255]
    rgb16 = u16(3)
    assert cv2.imwrite(str(data / "0000000006.png"), _rgb16(rgb16))  # OpenCV writes BGR
    expected[6] = (rgb16 >> 8).astype(np.uint8)
    rgba16 = u16(4)
    assert cv2.imwrite(str(data / "0000000007.png"), _rgb16(rgba16))
    expected[7] = (rgba16[..., :3] >> 8).astype(np.uint8)
    for n in expected:  # the files really are in the formats this test is about
        assert Image.open(data / f"{n:010d}.png").mode == ["L", "LA", "RGBA", "P", "I;16", "RGB", "RGBA"][n - 1]
    assert cv2.imread(str(data / "0000000006.png"), cv2.IMREAD_UNCHANGED).dtype == np.uint16

    split = tmp_path / "split.txt"
    split.write_text("".join(f"{KITTI_DRIVE} {n} l\n" for n in expected))
    out = tmp_path / "out"
    # Sources are already 64 x 96: no resize, so the clean image is the conversion itself.
    res = build_kitti(tmp_path / "kitti_raw", split, out, "--size", f"{h}x{w}", "--corruptions",
                      "contrast,gaussian_noise", "--levels", "3", "--jobs", "1")
    assert res.exit_code == 0, res.output
    for n, want in expected.items():
        for variant in ("clean", "contrast/3", "gaussian_noise/3"):
            with Image.open(out / variant / kitti_key(n)) as im:
                assert (im.mode, im.size) == ("RGB", (w, h)), (n, variant)
                if variant == "clean":
                    assert np.array_equal(np.asarray(im), want), n


# --- writes stay inside OUT -----------------------------------------------------------------

def test_split_entries_that_would_leave_out_are_refused(tmp_path, cli):
    """NYU entries whose output would land outside OUT (``..``, absolute) are refused before
    anything is written, even when the file they name exists."""
    root = tmp_path / "nyu"
    save(root / "bedroom/rgb_00001.jpg", random_image(48, 64, 1))
    save(tmp_path / "escape/rgb_00002.jpg", random_image(48, 64, 2))
    out = tmp_path / "out"
    split = tmp_path / "split.txt"
    for entry, problem in [("../escape/rgb_00002.jpg", "has an empty, '.' or '..' component"),
                           ("bedroom/../../escape/rgb_00002.jpg", "has an empty, '.' or '..' component"),
                           (f"{tmp_path}/escape/rgb_00002.jpg", "is not a relative path")]:
        split.write_text(f"bedroom/rgb_00001.jpg bedroom/d_1.png 518.8\n{entry} escape/d_2.png 518.8\n")
        before = outside(tmp_path, out)
        res = cli("build", "nyudepth2-c", "--root", root, "--split", split, "--out", out, "--size", "48x64",
                  "--corruptions", "contrast", "--levels", "1", "--jobs", "1")
        one_line_error(res, start=f"{split}:2: RGB path {entry!r} {problem}")
        assert outside(tmp_path, out) == before
        assert not out.exists()


def test_symlink_in_out_leading_outside_is_refused(kitti, tmp_path, build_kitti):
    """A link planted in OUT cannot redirect the build's writes (or deletions) elsewhere."""
    root, split = kitti
    out = tmp_path / "out"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out.mkdir()
    (out / "contrast").symlink_to(elsewhere, target_is_directory=True)
    before = outside(tmp_path, out)
    res = build_kitti(root, split, out, *SMALL)
    one_line_error(res, start=f"{out / 'contrast'}: a symlink to {elsewhere}, outside {out}; refused")
    assert outside(tmp_path, out) == before and list(elsewhere.iterdir()) == []
    assert not (out / "clean").exists()
    # A link that stays inside OUT is harmless and allowed.
    (out / "contrast").unlink()
    (out / "mine").mkdir()
    (out / "contrast").symlink_to(out / "mine", target_is_directory=True)
    res = build_kitti(root, split, out, *SMALL)
    assert res.exit_code == 0, res.output
    assert (out / "mine/1" / kitti_key(1)).is_file()


# --- unwritable and full output file systems ------------------------------------------------

def _mount_tmpfs(where: Path, options: str) -> bool:
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True)
    return res.returncode == 0


@pytest.fixture
def mount_point(tmp_path):
    """An empty directory to mount a tmpfs on; unmounted afterwards."""
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    yield mnt
    subprocess.run(["umount", str(mnt)], capture_output=True)


def test_read_only_output_file_system(kitti, tmp_path, mount_point, build_kitti):
    """The real thing, where this machine allows a mount (root); without it the same path
    is covered by test_build.py::test_unwritable_out with a patched write."""
    if not _mount_tmpfs(mount_point, "ro,size=64k"):
        pytest.skip("cannot mount a read-only tmpfs here; see test_build.py::test_unwritable_out")
    root, split = kitti
    res = build_kitti(root, split, mount_point / "out", *SMALL)
    one_line_error(res, start=f"{mount_point / 'out'}: cannot write the output directory (Read-only file system)")


@pytest.mark.slow
def test_full_disk_midway_keeps_only_complete_images_and_resumes(big, reference, tmp_path,
                                                                 mount_point, cli, build_kitti):
    """A build onto a real, too-small file system (tmpfs), with the default pool of workers."""
    if not _mount_tmpfs(mount_point, "size=96k"):
        pytest.skip("cannot mount a tmpfs here; test_write_failing_midway_leaves_no_partial_file "
                    "covers the same with a patched write")
    root, split = big
    out = mount_point / "out"
    res = build_kitti(root, split, out, *BIG, "--jobs", "2")
    assert res.exit_code == 2, res.output
    assert "cannot write (No space left on device); finished images are kept, rerun to resume" in res.output
    assert "Traceback" not in res.output and "Warning" not in res.output
    names = [p.name for p in out.rglob("*")]
    assert not [n for n in names if n.endswith(".part")]
    files = tree(out)
    assert 0 < len(files) < len(reference[0])
    assert all(decodes(b) for b in files.values())
    rows = OutputFolder(out).rows()  # readable, and never claims an image that is not there
    assert all(files.get(p) == reference[0][p] for p, r in rows.items() if not r.error)

    subprocess.run(["mount", "-o", "remount,size=16m", str(mount_point)], check=True)
    res = build_kitti(root, split, out, *BIG, "--jobs", "2")
    assert res.exit_code == 0, res.output
    assert cli("verify", out).exit_code == 0
    assert tree(out) == reference[0]


def test_write_failing_midway_leaves_no_partial_file(kitti, tmp_path, monkeypatch, build_kitti):
    """ENOSPC half-way through a file's bytes (the OS-level write, patched): the temporary file
    goes, no final name is ever truncated, the message says what happened; a rerun finishes."""
    root, split = kitti
    out = tmp_path / "out"
    flags = ["--size", "64x96", "--corruptions", "contrast,pixelate", "--levels", "1,2", "--jobs", "1"]
    real_fdopen = os.fdopen
    victim = out / "contrast/2" / kitti_key(1)

    class FillsUp:
        def __init__(self, fh):
            self.fh = fh

        def write(self, data):
            self.fh.write(data[: len(data) // 2])
            self.fh.flush()
            raise OSError(errno.ENOSPC, "No space left on device")

        def __getattr__(self, name):
            return getattr(self.fh, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

    def fdopen(fd, *a, **k):
        fh = real_fdopen(fd, *a, **k)
        temp = Path(os.readlink(f"/proc/self/fd/{fd}"))  # write_atomic's .<name>.XXXX.part
        return FillsUp(fh) if temp.parent == victim.parent and temp.name.startswith(f".{victim.name}.") else fh

    monkeypatch.setattr(imageio.os, "fdopen", fdopen)
    res = build_kitti(root, split, out, *flags)
    assert res.exit_code == 2, res.output
    failed = f"{victim}: cannot write (No space left on device)"
    assert f"robodepth: error: {failed}; finished images are kept, rerun to resume" in res.output
    assert not [p for p in out.rglob("*") if p.name.endswith(".part")]
    files = tree(out)
    assert set(files) == {f"clean/{kitti_key(1)}", f"contrast/1/{kitti_key(1)}"}
    assert all(decodes(b) for b in files.values())

    monkeypatch.setattr(imageio.os, "fdopen", real_fdopen)
    res = build_kitti(root, split, out, *flags)
    assert res.exit_code == 0 and "8 written, 2 skipped" in res.output, res.output
    fresh = tmp_path / "fresh"
    assert build_kitti(root, split, fresh, *flags).exit_code == 0
    assert tree(out) == tree(fresh)


@pytest.mark.parametrize("stage", ["start", "append", "compact", "end"])
def test_bookkeeping_write_failure_is_a_clear_stop(stage, kitti, tmp_path, monkeypatch, cli,
                                                   build_kitti):
    """The manifest or build record cannot be written (disk full): one clear message, exit 2,
    and the rerun completes; the images never disagree with the manifest."""
    root, split = kitti
    out = tmp_path / "out"

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    if stage == "append":
        monkeypatch.setattr(manifest.ManifestWriter, "append", full)
        named = out / "manifest.csv"
    elif stage == "compact":
        monkeypatch.setattr(OutputFolder, "compact", full)
        named = out / "manifest.csv"
    else:  # the build record, when the build starts or when it ends
        real, calls = OutputFolder.write_record, []

        def fails(folder, record):
            calls.append(record)
            return full() if len(calls) == (1 if stage == "start" else 2) else real(folder, record)

        monkeypatch.setattr(OutputFolder, "write_record", fails)
        named = out / "build.json"
    res = build_kitti(root, split, out, *SMALL)
    assert res.exit_code == 2, res.output
    assert f"robodepth: error: {named}: cannot write (No space left on device)" in res.output
    if stage == "start":  # refused before any image
        one_line_error(res, start=f"{named}: cannot write (No space left on device)")
        assert tree(out) == {}
    assert "Traceback" not in res.output
    rows = OutputFolder(out).rows()
    assert all((out / p).is_file() for p, r in rows.items() if not r.error)
    monkeypatch.undo()
    res = build_kitti(root, split, out, *SMALL)
    assert res.exit_code == 0, res.output
    assert cli("verify", out).exit_code == 0


# --- killed, interrupted and concurrent builds (real processes) -----------------------------

BIG = ["--size", "64x96", "--corruptions", "contrast,gaussian_noise,pixelate", "--levels", "all"]
BIG_FRAMES = 16
BIG_TOTAL = BIG_FRAMES * (1 + 3 * 5)


@pytest.fixture(scope="module")
def big(tmp_path_factory):
    root = tmp_path_factory.mktemp("big") / "kitti_raw"
    return root, kitti_tree(root, [(i, "l", ".png") for i in range(BIG_FRAMES)])


@pytest.fixture(scope="module")
def reference(big, tmp_path_factory, build_kitti):
    """An uninterrupted build (one worker): its tree and its manifest."""
    root, split = big
    out = tmp_path_factory.mktemp("reference") / "out"
    res = build_kitti(root, split, out, *BIG, "--jobs", "1")
    assert res.exit_code == 0, res.output
    files = tree(out)
    assert len(files) == BIG_TOTAL
    return files, (out / "manifest.csv").read_bytes()


@pytest.fixture
def processes():
    """Builds started in their own process group; whatever is left is killed at the end."""
    started: list[subprocess.Popen] = []

    def start(*args):
        # SIGINT as a terminal has it, even when the suite runs from a background shell
        # (which leaves it ignored in children, and the Ctrl-C would then be lost).
        p = subprocess.Popen([*CLI, *map(str, args)], start_new_session=True, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        started.append(p)
        return p

    yield start
    for p in started:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def build_args(big, out, jobs="2"):
    root, split = big
    return ["build", "kitti-c", "--root", root, "--split", split, "--out", out, *BIG, "--jobs", jobs,
            "--no-progress"]


def wait_until_partly_done(proc, out: Path, timeout: float = 120.0) -> None:
    """Return once the build has recorded at least one image and is still running."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if (out / "manifest.csv").read_bytes().count(b"\n") >= 2:
                assert proc.poll() is None, "the build finished before it could be stopped"
                return
        except FileNotFoundError:
            pass
        if proc.poll() is not None:
            raise AssertionError(f"the build ended early ({proc.returncode}): {proc.communicate()[1]}")
        time.sleep(0.005)
    raise AssertionError("the build wrote nothing in time")


def signalled_midway(processes, big, out: Path, sig: int):
    """A build of ``big`` into ``out``, sent ``sig`` (to its process group: the main process
    and its workers) once it has recorded an image; its process."""
    proc = processes(*build_args(big, out))
    wait_until_partly_done(proc, out)
    os.killpg(proc.pid, sig)
    return proc


def completed_rows(out: Path) -> int:
    """Outputs recorded so far: in the manifest, or in the journal of a killed build."""
    return sum(1 for r in OutputFolder(out).recorded().values() if not r.error)


@pytest.mark.slow
def test_sigkill_midway_then_rerun_equals_an_uninterrupted_build(big, reference, tmp_path,
                                                                 processes, cli):
    out = tmp_path / "out"
    proc = signalled_midway(processes, big, out, signal.SIGKILL)
    proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    done = completed_rows(out)
    assert 0 < done < BIG_TOTAL
    # Atomic writes: whatever carries a final name is a complete image (temporaries may remain).
    assert all(decodes(b) for p, b in tree(out).items() if not p.endswith(".part"))

    res = subprocess.run([*CLI, *map(str, build_args(big, out))], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert f"{BIG_TOTAL - done} written, {done} skipped (already done), 0 failed" in res.stderr
    assert not [p for p in out.rglob("*") if p.name.endswith(".part")]
    files = tree(out)
    assert all(decodes(b) for b in files.values())
    assert cli("verify", out).exit_code == 0
    assert files == reference[0]
    assert (out / "manifest.csv").read_bytes() == reference[1]


@pytest.mark.slow
@pytest.mark.parametrize("sig", [
    signal.SIGINT,   # what Ctrl-C in a terminal does: the whole group
    signal.SIGTERM,  # what a batch scheduler sends at the end of a job's time
], ids=["ctrl-c", "sigterm"])
def test_ctrl_c_stops_cleanly_and_the_rerun_completes(big, reference, tmp_path, processes, sig, cli,
                                                      build_kitti):
    out = tmp_path / "out"
    proc = signalled_midway(processes, big, out, sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "Warning" not in err, err
    assert err.strip().splitlines()[-1] == "robodepth: interrupted; rerun the same command to resume"
    assert "stopped after" in err
    assert json.loads((out / "build.json").read_text())["status"] == "interrupted"
    assert not [p for p in out.rglob("*") if p.name.endswith(".part")]
    assert all(decodes(b) for b in tree(out).values())
    done = completed_rows(out)
    assert 0 < done < BIG_TOTAL

    res = build_kitti(*big, out, *BIG, "--jobs", "2")
    assert res.exit_code == 0, res.output
    assert f"{done} skipped (already done)" in res.output
    assert cli("verify", out).exit_code == 0
    assert tree(out) == reference[0]


@pytest.mark.slow
def test_second_build_into_the_same_out_is_refused_while_one_runs(big, reference, tmp_path,
                                                                  processes, cli):
    out = tmp_path / "out"
    # Held mid-build, its lock taken, for as long as needed.
    first = signalled_midway(processes, big, out, signal.SIGSTOP)
    try:
        second = processes(*build_args(big, out, jobs="1"))
        _, err = second.communicate(timeout=300)
    finally:
        os.killpg(first.pid, signal.SIGCONT)
    assert second.returncode == 2
    assert err.strip() == (f"robodepth: error: {out}: another build (pid {first.pid}) is writing here; "
                           f"wait for it to finish or choose another --out")
    _, err = first.communicate(timeout=600)
    assert first.returncode == 0, err
    assert cli("verify", out).exit_code == 0
    assert tree(out) == reference[0]


def test_interrupt_before_the_build_starts_is_clean(kitti, tmp_path, monkeypatch, build_kitti):
    """Ctrl-C while the split is read or the plan is made: the same message and exit code."""
    root, split = kitti

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(gather, "read_split", interrupted)
    res = build_kitti(root, split, tmp_path / "out", *SMALL)
    assert res.exit_code == 130
    assert res.output.strip() == "robodepth: interrupted; rerun the same command to resume"


def test_unknown_style(kitti, tmp_path, cli):
    """KITTI-S names its variants styles: a wrong one is refused like a wrong corruption."""
    root, split = kitti
    out = tmp_path / "out"
    res = cli("build", "kitti-s", "--root", root, "--split", split, "--out", out, "--only-styles", "sketch,skecth")
    one_line_error(res, start="--only-styles: unknown style 'skecth'; valid: cartoon, digital_art,")
    cfg = tmp_path / "mine.yaml"
    cfg.write_text("only_styles: [relief, murals, graffiti]\n")
    res = cli("build", "kitti-s", "--root", root, "--split", split, "--out", out, "--config", cfg)
    one_line_error(res, start=f"{cfg}: only_styles: unknown style 'graffiti'; valid: cartoon,")
    assert not out.exists()
