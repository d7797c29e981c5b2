"""What keeps a build honest about its output directory: ROOT and OUT apart, one build per
OUT, changed sources redone, verify against the plan, limits on jobs and sizes."""

from __future__ import annotations

import json
import os
import shutil

import pytest
from PIL import Image

from tests.helpers.messages import one_line_error
from tests.helpers.trees import KITTI_DRIVE, kitti_key, kitti_tree, nyu_tree, random_image, save, tree
from robodepth_cli.building import pipeline as builder
from robodepth_cli.building.config import ConfigError, resolve
from robodepth_cli.output.layout import LOCK
from robodepth_cli.output.folder import OutputFolder

SMALL = ["--size", "64x96", "--corruptions", "contrast", "--levels", "1,2", "--jobs", "1"]
FRAMES = [(1, "l", ".png"), (2, "r", ".png")]


@pytest.fixture
def kitti(tmp_path):
    root = tmp_path / "kitti_raw"
    return root, kitti_tree(root, FRAMES)


def sources(root):
    return {p: p.read_bytes() for p in sorted(root.rglob("*.png"))}


# --- defect 1: ROOT and OUT apart ------------------------------------------------------------

def test_root_inside_out_is_refused_and_sources_survive(kitti, tmp_path, build_kitti, monkeypatch):
    """The reported case: rebuilding at another size from the clean images of a build, into
    that build, replaced the source frames."""
    root, split = kitti
    monkeypatch.chdir(tmp_path)
    assert build_kitti(root, split, "KC", *SMALL).exit_code == 0
    clean_root = tmp_path / "KC" / "clean" / "kitti_data"
    before = sources(clean_root)
    res = build_kitti("KC/clean/kitti_data", split, "KC", *SMALL[:-4], "--size", "48x80")
    one_line_error(res, "--out KC contains --root KC/clean/kitti_data",
                   "choose an output directory outside the root")
    assert sources(clean_root) == before
    assert not (tmp_path / "KC" / LOCK).exists()


@pytest.mark.parametrize("where", ["same", "out inside root", "through a symlink"])
def test_out_overlapping_root_is_refused(kitti, tmp_path, build_kitti, where):
    root, split = kitti
    if where == "same":
        out, expected = root, f"--root {root} and --out {root} are the same directory"
    elif where == "out inside root":
        out, expected = root / "C", f"--out {root / 'C'} lies inside --root {root}"
    else:
        (tmp_path / "link").symlink_to(root, target_is_directory=True)
        out = tmp_path / "link" / "C"
        expected = f"--out {out} lies inside --root {root} (through symlinks: "
    before = sources(root)
    one_line_error(build_kitti(root, split, out, *SMALL), expected)
    assert sources(root) == before and not (root / "C").exists()


def test_source_linked_into_out_is_refused(kitti, tmp_path, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    frame = root / KITTI_DRIVE / "image_03" / "data" / f"{2:010d}.png"
    frame.unlink()
    frame.symlink_to(out / "clean" / kitti_key(2, "r"))
    one_line_error(build_kitti(root, split, out, *SMALL),
                   f"{frame}: resolves to", "inside --out", "a build never reads its own outputs")
    assert (out / "clean" / kitti_key(2, "r")).is_file()


# --- defect 2: verify against the plan -------------------------------------------------------

def _interrupt_after(monkeypatch, n_tasks):
    real, calls = builder.run_source_jobs, []

    def run_source_jobs(task, ctx):
        calls.append(task)
        if len(calls) > n_tasks:
            raise KeyboardInterrupt
        return real(task, ctx)

    monkeypatch.setattr(builder, "run_source_jobs", run_source_jobs)


def test_verify_calls_an_interrupted_build_incomplete(kitti, tmp_path, cli, build_kitti, monkeypatch):
    root, split = kitti
    out = tmp_path / "out"
    _interrupt_after(monkeypatch, 1)
    assert build_kitti(root, split, out, *SMALL).exit_code == 130
    monkeypatch.undo()
    res = cli("verify", out)
    assert res.exit_code == 1, res.output
    assert "incomplete: 3 of 6 outputs (build interrupted; rerun the build command to finish)" in res.output
    # A SIGKILL leaves the record saying "running" and no process holding the lock.
    record = json.loads((out / "build.json").read_text())
    (out / "build.json").write_text(json.dumps({**record, "status": "running"}))
    assert "incomplete: 3 of 6 outputs (build interrupted;" in cli("verify", out).output
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    res = cli("verify", out)
    assert res.exit_code == 0 and "6 files match" in res.output


def test_verify_while_a_build_runs_says_so(kitti, tmp_path, cli, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    with OutputFolder(out).lock():
        one_line_error(cli("verify", out), f"{out}: a build (pid {os.getpid()}) is writing here right now")
    assert cli("verify", out).exit_code == 0


def test_verify_lists_why_images_failed(kitti, tmp_path, cli, build_kitti):
    root, split = kitti
    bad = root / KITTI_DRIVE / "image_03" / "data" / f"{2:010d}.png"
    bad.write_bytes(b"not an image")
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL).exit_code == 1
    lines = cli("verify", out).output.splitlines()
    i = lines.index("failed: 3")
    assert lines[i + 1] == f"  {bad}: not an image file Pillow can read"
    assert sorted(lines[i + 2:i + 5]) == sorted(f"    {v}/{kitti_key(2, 'r')}"
                                                for v in ("clean", "contrast/1", "contrast/2"))


def test_damaged_manifest_row_is_named_with_a_way_out(kitti, tmp_path, cli, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    lines = (out / "manifest.csv").read_text().splitlines(keepends=True)
    lines[3] = lines[3][:40] + "\n"  # a row cut short in the middle of the file
    (out / "manifest.csv").write_text("".join(lines))
    res = cli("verify", out)
    one_line_error(res, f"{out / 'manifest.csv'}:4: damaged row (", "to recover, delete that line",
                   "rerun the build command")
    del lines[3]  # do as it says
    (out / "manifest.csv").write_text("".join(lines))
    res = build_kitti(root, split, out, *SMALL)
    assert res.exit_code == 0 and "1 written, 5 skipped" in res.output, res.output
    assert cli("verify", out).exit_code == 0


# --- defect 4: one build per OUT -------------------------------------------------------------

def test_a_custom_build_at_its_own_sizes_into_one_at_a_size_says_so(tmp_path, cli):
    from tests.helpers.trees import random_image, save

    save(tmp_path / "img" / "a.png", random_image(96, 128, seed=0))
    args = ("build", "custom", "--root", tmp_path / "img", "--out", tmp_path / "out", "--corruptions",
            "fog", "--levels", "1")
    res = cli(*args, "--size", "48x64")
    assert res.exit_code == 0, res.output
    res = cli(*args)
    one_line_error(res, "holds another build (--size not given (each image at its own size) (it holds 48x64))")
    assert "()" not in res.output


def test_another_dataset_size_or_seed_into_the_same_out_is_refused(kitti, tmp_path, cli, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    before = tree(out)
    one_line_error(build_kitti(root, split, out, *SMALL, "--seed", "3"),
                   f"{out}: holds another build (--seed 3 (it holds 0))", "choose another --out")
    one_line_error(build_kitti(root, split, out, *SMALL[:-4], "--size", "48x80"),
                   "--size 48x80 (it holds 64x96)")
    nyu_root = tmp_path / "nyu"
    nyu_split = nyu_tree(nyu_root, ["bathroom/rgb_00045.jpg"])
    one_line_error(cli("build", "nyudepth2-c", "--root", nyu_root, "--split", nyu_split, "--out", out,
                       "--corruptions", "contrast", "--levels", "1", "--jobs", "1"),
                   "the dataset nyudepth2-c (it holds kitti-c)")
    assert tree(out) == before and not (out / LOCK).exists()
    assert cli("verify", out).exit_code == 0


def test_limit_and_subsets_extend_the_same_build(kitti, tmp_path, cli, build_kitti, monkeypatch):
    root, split = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL, "--limit", "1").exit_code == 0
    res = build_kitti(root, split, out, *SMALL[:-5], "pixelate", "--levels", "3", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert cli("verify", out).exit_code == 0
    assert len(json.loads((out / "build.json").read_text())["plans"]) == 2
    # The first request still counts: its unfinished part makes the tree incomplete.
    _interrupt_after(monkeypatch, 0)
    assert build_kitti(root, split, out, *SMALL).exit_code == 130
    monkeypatch.undo()
    res = cli("verify", out)
    assert "incomplete: 6 of 8 outputs (build interrupted;" in res.output, res.output
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    assert cli("verify", out).exit_code == 0


# --- defect 5: changed sources ---------------------------------------------------------------

def test_changed_source_redoes_its_outputs(kitti, tmp_path, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    frame = root / KITTI_DRIVE / "image_02" / "data" / f"{1:010d}.png"
    # Other pixels: the build redoes the three outputs of that frame only.
    save(frame, random_image(60, 200, seed=42))
    res = build_kitti(root, split, out, *SMALL)
    assert "3 written, 3 skipped" in res.output, res.output
    # Other pixels in a file of the very same size and modification time (uncompressed
    # PNGs of one shape have one size): only the content hash can tell.
    Image.fromarray(random_image(60, 200, seed=50)).save(frame, compress_level=0)
    assert "3 written, 3 skipped" in build_kitti(root, split, out, *SMALL).output
    st = frame.stat()
    Image.fromarray(random_image(60, 200, seed=51)).save(frame, compress_level=0)
    os.utime(frame, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert frame.stat().st_size == st.st_size
    res = build_kitti(root, split, out, *SMALL)
    assert "3 written, 3 skipped" in res.output, res.output


def test_touched_or_copied_sources_are_not_rebuilt(kitti, tmp_path, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    for p in root.rglob("*.png"):
        os.utime(p, ns=(1, 10**18))  # same bytes, another time
    assert "0 written, 6 skipped" in build_kitti(root, split, out, *SMALL).output
    copy = tmp_path / "copy"
    shutil.copytree(root, copy, copy_function=shutil.copyfile)  # new times again
    assert "0 written, 6 skipped" in build_kitti(copy, split, out, *SMALL).output


# --- defect 9: limits ------------------------------------------------------------------------

def test_jobs_auto_means_one_per_cpu(monkeypatch):
    from robodepth_cli import workers

    # The CPUs this process may use: the one rule of every command's --jobs auto.
    monkeypatch.setattr(workers, "default_jobs", lambda: 3)
    assert resolve("kitti-c", flags={"jobs": "auto"}).jobs == 3
    assert resolve("kitti-c", flags={"jobs": "-1"}).jobs == 3
    with pytest.raises(ConfigError, match=r"--jobs: expected an integer >= 1, got -2 \(or 'auto' or -1"):
        resolve("kitti-c", flags={"jobs": "-2"})


def test_jobs_are_capped_at_the_images_and_warned_above_the_cpus(kitti, tmp_path, build_kitti, monkeypatch):
    root, split = kitti
    out = tmp_path / "out"
    monkeypatch.setattr(builder.os, "cpu_count", lambda: 1)
    res = build_kitti(root, split, out, *SMALL[:-1], "12")
    assert res.exit_code == 0, res.output
    assert json.loads((out / "build.json").read_text())["executor"]["workers"] == 2  # 2 images
    assert ("robodepth: warning: 2 workers (--jobs 12) on 1 CPU: the extra workers only add memory "
            "and contention (--jobs auto: one per CPU)") in res.output


@pytest.mark.parametrize("size", ["100000x100000", "8193x640", "192x9000"])
def test_sizes_above_8192_are_refused(size, cli, tmp_path):
    with pytest.raises(ConfigError, match="both sides must be at most 8192"):
        resolve("kitti-c", flags={"size": size})
    src = tmp_path / "i.png"
    save(src, random_image(40, 40, 1))
    res = cli("corrupt", src, "-c", "contrast", "-l", "1", "--size", size, "--out", tmp_path / "o.png")
    one_line_error(res, "both sides must be at most 8192")


# --- the lock --------------------------------------------------------------------------------

def test_a_refused_or_finished_build_leaves_no_lock(kitti, tmp_path, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    out.mkdir()
    (out / "away").symlink_to(tmp_path, target_is_directory=True)
    one_line_error(build_kitti(root, split, out, *SMALL), "a symlink to")
    assert not (out / LOCK).exists()
    (out / "away").unlink()
    assert build_kitti(root, split, out, *SMALL).exit_code == 0
    assert not (out / LOCK).exists()


def test_lock_taken_again_if_its_file_was_removed_meanwhile(tmp_path, monkeypatch):
    """A build that opened the lock file just before the previous holder removed it must
    not end up holding a lock on the removed file (a third build would lock a new one)."""
    import fcntl

    real, calls = fcntl.flock, []

    def flock(fd, op):
        calls.append(fd)
        if len(calls) == 1:
            os.unlink(tmp_path / LOCK)  # the previous build ends right now
        return real(fd, op)

    monkeypatch.setattr(fcntl, "flock", flock)
    with OutputFolder(tmp_path).lock() as lock:
        assert len(calls) == 2  # locked again, on the file now at the path
        assert os.fstat(lock._fd).st_ino == os.stat(tmp_path / LOCK).st_ino
    monkeypatch.undo()
    assert not (tmp_path / LOCK).exists()


# --- KITTI-S -------------------------------------------------------------------------------

@pytest.mark.slow
def test_kitti_s_rerun_with_nothing_to_do_computes_no_style_statistics(tmp_path, fixtures_dir, cli,
                                                                     monkeypatch):
    from tests.helpers.adain import save_checkpoints
    from robodepth_cli.styles import adain

    vgg, dec, _, _ = save_checkpoints(tmp_path, seed=3)
    args = ["build", "kitti-s", "--root", fixtures_dir / "kitti_raw", "--split",
            fixtures_dir / "kitti_split.txt", "--styles", fixtures_dir / "styles", "--vgg", vgg,
            "--decoder", dec, "--size", "32x96", "--style-size", "32", "--only-styles", "sketch,murals",
            "--limit", "1", "--jobs", "1", "--out", tmp_path / "out"]
    assert cli(*args).exit_code == 0
    real, calls = adain.Stylizer.style_features, []

    def counted(self, style):
        calls.append(style.shape)
        return real(self, style)

    monkeypatch.setattr(adain.Stylizer, "style_features", counted)
    res = cli(*args)
    assert res.exit_code == 0 and "0 written, 3 skipped" in res.output, res.output
    assert calls == []
    # An output deleted since is made again, statistics and all.
    (tmp_path / "out" / "murals").rename(tmp_path / "gone")
    res = cli(*args)
    assert res.exit_code == 0 and "1 written, 2 skipped" in res.output, res.output
    assert len(calls) == 2
