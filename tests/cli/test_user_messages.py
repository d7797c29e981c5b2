"""Messages a new user meets: each names the file or flag and says what to do, in one line."""

from __future__ import annotations

import os
import shutil
import socket

import numpy as np
import pytest
import torch

from tests.helpers.messages import one_line_error
from tests.helpers.trees import KITTI_DRIVE, kitti_key, kitti_tree, nyu_tree
from robodepth_cli.sources import splits
from robodepth_cli.building.config import ConfigError, resolve
from robodepth_cli.corruptions import NAMES
from robodepth_cli.sources.datasets import read_split
from robodepth_cli.sources.splits import SplitError

SMALL = ["--size", "64x96", "--corruptions", "contrast", "--levels", "1", "--jobs", "1"]
NYU_NAMES = [n for n in NAMES if n not in ("fog", "frost", "snow")]



def dee_csv(path, names, n_levels, dee=0.2, clean=0.1):
    rows = ["corruption,level,dee", f"clean,0,{clean}"]
    rows += [f"{n},{lv},{dee}" for n in names for lv in range(1, n_levels + 1)]
    path.write_text("\n".join(rows) + "\n")
    return path


# --- score ----------------------------------------------------------------------------------

def test_zero_baseline_dee_is_a_one_line_error(cli, tmp_path):
    results = dee_csv(tmp_path / "model.csv", NAMES, 5)
    base = tmp_path / "base.csv"
    dee_csv(base, NAMES, 5)
    base.write_text(base.read_text().replace("snow,1,0.2", "snow,1,0").replace("snow,2,0.2", "snow,2,0")
                    .replace("snow,3,0.2", "snow,3,0").replace("snow,4,0.2", "snow,4,0")
                    .replace("snow,5,0.2", "snow,5,0"))
    res = cli("score", results, "-b", "kitti-c", "--baseline", base)
    one_line_error(res, f"{base}: the baseline DEE of snow is 0; CE divides by it")


def test_nyu_results_scored_as_kitti_c_say_which_benchmark_they_fit(cli, tmp_path):
    nyu = dee_csv(tmp_path / "nyu.csv", NYU_NAMES, 4)
    res = cli("score", nyu, "-b", "kitti-c")
    one_line_error(res, f"{nyu}: the rows look like nyudepth2-c results (15 corruptions x 4 levels): "
                        "use --benchmark nyudepth2-c (as kitti-c results, 30 of 90 variants are missing)")
    assert "--allow-partial" not in res.output
    kitti = dee_csv(tmp_path / "kitti.csv", NAMES, 5)
    res = cli("score", kitti, "-b", "nyudepth2-c")
    one_line_error(res, "the rows look like kitti-c results (18 corruptions x 5 levels): "
                        "use --benchmark kitti-c")
    # Rows that fit neither get no such guess.
    part = dee_csv(tmp_path / "part.csv", NYU_NAMES[:3], 4)
    res = cli("score", part, "-b", "kitti-c")
    one_line_error(res, "missing", "--allow-partial")
    assert "look like" not in res.output


# --- splits ---------------------------------------------------------------------------------

def test_split_file_with_a_byte_order_mark_is_read(cli, tmp_path):
    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, [(1, "l", ".png"), (2, "l", ".png")])
    split.write_bytes(b"\xef\xbb\xbf" + split.read_bytes())
    assert [e.key for e in read_split(split, "eigen")] == [kitti_key(1), kitti_key(2)]
    res = cli("build", "kitti-c", "--root", root, "--split", split, "--out", tmp_path / "out", *SMALL)
    assert res.exit_code == 0, res.output


def test_kitti_split_given_to_the_nyu_build_says_so(cli, tmp_path):
    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, [(1, "l", ".png")])
    res = cli("build", "nyudepth2-c", "--root", root, "--split", split, "--out", tmp_path / "out")
    one_line_error(res, f"{split}:1: this looks like a KITTI (Eigen) split",
                   "this dataset needs an NYU Depth V2 split (lines 'RGB DEPTH FOCAL')")
    nyu_split = nyu_tree(tmp_path / "nyu", ["bathroom/rgb_00045.jpg"])
    with pytest.raises(SplitError, match=r":1: this looks like an NYU Depth V2 split .*needs a KITTI"):
        read_split(nyu_split, "eigen")


def test_unknown_split_name_lists_the_standard_ones(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = cli("build", "kitti-c", "--root", tmp_path, "--split", "eigen", "--out", tmp_path / "out")
    one_line_error(res, "--split: no standard split named 'eigen'",
                   "standard splits of kitti-c: eigen_test, kitti_sequences; or give a split file")
    res = cli("build", "nyudepth2-c", "--root", tmp_path, "--split", "nyu", "--out", tmp_path / "out")
    one_line_error(res, "standard splits of nyudepth2-c: nyu_test")


def test_cached_split_with_a_wrong_checksum_says_so_before_fetching(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("ROBODEPTH_CACHE_DIR", str(tmp_path / "cache"))
    rec = splits.record("eigen_test")
    cached = tmp_path / "cache" / "splits" / rec.file
    cached.parent.mkdir(parents=True)
    cached.write_text("2011_09_26/2011_09_26_drive_0001_sync 0000000001 l\n")  # an edited copy
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        url = f"http://127.0.0.1:{s.getsockname()[1]}/x.txt"  # nothing listens there once closed
    with pytest.raises(SplitError) as err:
        splits.standard_split("eigen_test", url=url, timeout=5)
    warning = capsys.readouterr().err
    assert warning.startswith(f"robodepth: warning: the cached copy {cached} has sha256 ")
    assert "downloading the eigen_test split again" in warning
    assert f"(the cached copy {cached} has sha256" in str(err.value)
    assert cached.exists()  # not thrown away: the user may want to look at it


# --- flags of another dataset ---------------------------------------------------------------

@pytest.mark.parametrize("preset, flags, expected", [
    ("kitti-s", {"corruptions": "fog"},
     "--corruptions does not apply to kitti-s (it is a setting of kitti-c, nyudepth2-c, custom, diode-c, sintel-c, eth3d-c, scannet-c, vkitti2-c, cityscapes-c, drivingstereo-c); "
     "kitti-s picks its styles with --only-styles"),
    ("kitti-c", {"alpha": "0.5"}, "--alpha does not apply to kitti-c (it is a setting of kitti-s)"),
    ("kitti-c", {"only_styles": "sketch"},
     "--only-styles does not apply to kitti-c (it is a setting of kitti-s); "
     "kitti-c picks its corruptions with --corruptions"),
    ("kitti-s", {"levels": "1"}, "--levels does not apply to kitti-s (it is a setting of kitti-c, "
                                 "nyudepth2-c, custom, diode-c, sintel-c, eth3d-c, scannet-c, vkitti2-c, cityscapes-c, drivingstereo-c); kitti-s has no levels (one output per style)"),
])
def test_a_flag_of_another_dataset_does_not_apply(preset, flags, expected):
    with pytest.raises(ConfigError) as err:
        resolve(preset, flags=flags)
    assert str(err.value) == expected


def test_kitti_s_does_not_list_levels_as_a_key(tmp_path):
    f = tmp_path / "mine.yaml"
    f.write_text("levls: 1\n")
    with pytest.raises(ConfigError) as err:
        resolve("kitti-s", f)
    valid = str(err.value).split("valid keys: ")[1].split(", ")
    assert "levels" not in valid and "only_styles" in valid and "alpha" in valid
    f.write_text("levels: [1]\n")
    with pytest.raises(ConfigError, match=r"mine\.yaml: key 'levels' does not apply to kitti-s"):
        resolve("kitti-s", f)


# --- files ----------------------------------------------------------------------------------

def test_paths_in_messages_are_as_typed(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "real").mkdir()
    (tmp_path / "root").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real", target_is_directory=True)
    res = cli("build", "kitti-c", "--root", "root", "--split", "link/none.txt", "--out", "out")
    one_line_error(res, "robodepth: error: link/none.txt: cannot read the split")
    res = cli("build", "kitti-s", "--root", "root", "--styles", "link/styles", "--out", "out")
    one_line_error(res, "--styles: link/styles: the style directory does not exist")
    f = tmp_path / "link" / "mine.yaml"
    f.write_text("split: few.txt\n")
    res = cli("build", "kitti-c", "--root", "root", "--config", "link/mine.yaml", "--out", "out")
    one_line_error(res, "robodepth: error: link/few.txt: cannot read the split")
    f.write_text("2011_09_26/2011_09_26_drive_0001_sync 1 l\n")
    res = cli("build", "kitti-c", "--root", "link/../root", "--split", f, "--out", "out")
    one_line_error(res, "robodepth: error: link/../root: none of the 1 images")


@pytest.mark.parametrize("content", [b"", b"hello, not a checkpoint\n" * 40, b"PK\x03\x04" + bytes(200)],
                         ids=["empty", "text", "broken zip"])
def test_garbage_checkpoint_is_one_clear_sentence(tmp_path, content):
    from robodepth_cli.styles import adain

    bad = tmp_path / "vgg_normalised.pth"
    bad.write_bytes(content)
    with pytest.raises(adain.CheckpointError) as err:
        adain.load_model(bad, "vgg")
    message = str(err.value)
    assert message.startswith(f"{bad}: not a PyTorch state_dict (")
    assert message.endswith("expected a checkpoint of the AdaIN release such as vgg_normalised.pth "
                            "or decoder.pth")
    assert "\n" not in message and "weights_only" not in message and "\x1b" not in message


def test_checkpoint_with_other_objects_never_suggests_unsafe_loading(tmp_path):
    from robodepth_cli.styles import adain

    bad = tmp_path / "decoder.pth"
    torch.save({"0.weight": np.zeros(3)}, bad)  # a numpy array: refused by weights_only
    with pytest.raises(adain.CheckpointError) as err:
        adain.load_model(bad, "decoder")
    message = str(err.value)
    assert "holds Python objects besides tensors, which are never loaded" in message
    assert "weights_only" not in message and "trust" not in message and "\n" not in message


# --- sources --------------------------------------------------------------------------------

def test_root_made_of_symlinked_date_folders_builds(cli, tmp_path):
    disk = tmp_path / "disk2"
    root = tmp_path / "kitti_raw"
    split = kitti_tree(disk, [(1, "l", ".png"), (2, "r", ".png")])
    root.mkdir()
    date = KITTI_DRIVE.split("/")[0]
    (root / date).symlink_to(disk / date, target_is_directory=True)
    out = tmp_path / "out"
    res = cli("build", "kitti-c", "--root", root, "--split", split, "--out", out, *SMALL)
    assert res.exit_code == 0, res.output
    assert (out / "contrast" / "1" / kitti_key(2, "r")).is_file()
    reference = tmp_path / "reference"
    assert cli("build", "kitti-c", "--root", disk, "--split", split, "--out", reference, *SMALL).exit_code == 0
    for key in (kitti_key(1), kitti_key(2, "r")):
        assert (out / "contrast/1" / key).read_bytes() == (reference / "contrast/1" / key).read_bytes()
    shutil.rmtree(reference)


def test_an_output_under_proc_is_not_said_not_to_exist(tmp_path, cli):
    from tests.helpers.paths import FIXTURES

    if not os.path.isdir("/proc/self"):
        pytest.skip("this system has no /proc")
    img = FIXTURES / "kitti_raw" / "2011_09_26" / "2011_09_26_drive_0002_sync" / "image_02" / "data" / "0000000069.png"
    for out in ("/proc/x/f.png", "/proc/f.png"):
        res = cli("corrupt", img, "-c", "fog", "-l", "1", "--out", out)
        one_line_error(res, f"{out}: cannot write (/proc exists but takes no new files or folders: ")


def test_counts_are_worded_in_the_singular_and_plural():
    from robodepth_cli.errors import counted

    assert counted(1, "variant") == "1 variant" and counted(2, "variant") == "2 variants"
    assert counted(0, "time") == "0 times" and counted(1, "results file") == "1 results file"


@pytest.mark.parametrize("command", [["corrupt", "-c", "fog", "-l", "1"], ["preview", "-c", "fog"]])
def test_single_image_refusals_are_worded_as_the_other_commands(cli, tmp_path, command):
    """--size names its flag as build does; an --out under a regular file says 'is not a
    directory' as run, score and evaluate do, before any work."""
    from tests.helpers.paths import REFERENCE

    frame = REFERENCE / "kitti" / "kitti_like_md2__input.png"
    res = cli(*command[:1], frame, *command[1:], "--size", "0x0", "--out", tmp_path / "o.png")
    assert one_line_error(res) == "robodepth: error: --size: size '0x0': both sides must be at least 32"
    (tmp_path / "file").write_text("")
    target = tmp_path / "file" / "x.png"
    res = cli(*command[:1], frame, *command[1:], "--out", target)
    assert one_line_error(res) == (f"robodepth: error: --out {target}: cannot write "
                                   f"({tmp_path / 'file'} is not a directory)")
    build = cli("build", "custom", "--root", tmp_path, "--out", tmp_path / "b", "--size", "0x0")
    assert one_line_error(build).startswith("robodepth: error: --size: size '0x0': ")


def test_a_file_in_the_way_of_an_output_folder_is_named_alike_wherever_it_is_met(tmp_path):
    """cannot_write of EEXIST or ENOTDIR (a file where a folder of the path should be)
    names that file as check_writable does."""
    import errno

    from robodepth_cli.errors import cannot_write
    from robodepth_cli.files import check_writable
    from robodepth_cli.errors import RobodepthError

    (tmp_path / "file").write_text("")
    target = tmp_path / "file" / "sub" / "x.png"
    with pytest.raises(RobodepthError) as early:
        check_writable(target)
    for code in (errno.EEXIST, errno.ENOTDIR):
        late = cannot_write(target, OSError(code, os.strerror(code)))
        assert late == str(early.value) == f"{target}: cannot write ({tmp_path / 'file'} is not a directory)"
