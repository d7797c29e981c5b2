"""`robodepth build` and `robodepth verify` on small synthetic trees: layout, manifest, pixels,
resume and refusals."""

from __future__ import annotations

import hashlib
import io

import numpy as np
import pytest
from PIL import Image

from robodepth_cli import corruptions, files, seeding

from robodepth_cli.building import renderers, jobs

from robodepth_cli.corruptions import NAMES
from robodepth_cli.output.folder import OutputFolder

from tests.helpers.imports import imported_by_command
from tests.helpers.manifest import manifest_rows
from tests.helpers.trees import expected_paths, kitti_key, kitti_tree, tree

CHEAP = ["brightness", "contrast", "pixelate", "gaussian_noise", "color_quant"]
FRAMES = [(5, "l", ".png"), (7, "r", ".jpg")]


@pytest.fixture
def kitti(tmp_path):
    root = tmp_path / "kitti_raw"
    return root, kitti_tree(root, FRAMES)


def test_kitti_layout_manifest_and_pixels(kitti, tmp_path, cli, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--size", "64x96", "--corruptions", "brightness,gaussian_noise",
                      "--levels", "1,3", "--jobs", "1", "--seed", "7")
    assert res.exit_code == 0, res.output
    keys = [kitti_key(5, "l"), kitti_key(7, "r")]
    files = tree(out)
    assert set(files) == expected_paths(keys, ["brightness", "gaussian_noise"], [1, 3])
    assert "clean/kitti_data/2011_09_26/2011_09_26_drive_0001_sync/image_03/data/0000000007.png" in files
    for data in files.values():
        im = Image.open(io.BytesIO(data))
        assert (im.format, im.mode, im.size) == ("PNG", "RGB", (96, 64))

    rows = {r["output"]: r for r in manifest_rows(out)}
    assert set(rows) == set(files)
    for path, r in rows.items():
        assert r["sha256"] == hashlib.sha256(files[path]).hexdigest()
        assert (r["seed"], r["height"], r["width"], r["error"]) == ("7", "64", "96", "")
    r = rows[f"gaussian_noise/3/{keys[1]}"]
    assert (r["variant"], r["level"]) == ("gaussian_noise", "3")
    assert r["source"] == "2011_09_26/2011_09_26_drive_0001_sync/image_03/data/0000000007.jpg"
    assert rows[f"clean/{keys[0]}"]["level"] == ""

    # The clean image is Pillow's Lanczos resize of the RGB source ...
    src = Image.open(root / rows[f"clean/{keys[1]}"]["source"]).convert("RGB")
    clean = np.asarray(src.resize((96, 64), Image.LANCZOS))
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(files[f"clean/{keys[1]}"]))), clean)
    # ... and a job draws from its own generator, keyed by seed, dataset, variant, level, image.
    rng = seeding.job_rng(7, "kitti-c", "gaussian_noise", 3, keys[1])
    want = corruptions.corrupt(clean, "gaussian_noise", 3, rng)
    got = np.asarray(Image.open(io.BytesIO(files[f"gaussian_noise/3/{keys[1]}"])))
    assert np.array_equal(got, want)
    assert cli("verify", out).exit_code == 0


def test_nyu_layout_and_no_resize(fixtures_dir, tmp_path, cli):
    out = tmp_path / "nyu_c"
    res = cli("build", "nyudepth2-c", "--root", fixtures_dir / "nyu", "--split", fixtures_dir / "nyu_split.txt",
              "--out", out, "--corruptions", "brightness", "--levels", "4", "--jobs", "1")
    assert res.exit_code == 0, res.output
    keys = ["bedroom/rgb_00001.png", "bedroom/rgb_00119.png"]
    files = tree(out)
    # The ground truth comes along: the BTS folder's depth files, copied.
    depths = {f"gt/bedroom/sync_depth_{n}.png" for n in ("00001", "00119")}
    assert set(files) == expected_paths(keys, ["brightness"], [4]) | depths
    for path in depths:
        assert files[path] == (fixtures_dir / "nyu" / path[3:]).read_bytes()
    # 480 x 640 sources are used as they are: the clean PNG holds the decoded JPEG exactly.
    src = np.asarray(Image.open(fixtures_dir / "nyu/bedroom/rgb_00119.jpg").convert("RGB"))
    assert src.shape == (480, 640, 3)
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(files["clean/bedroom/rgb_00119.png"]))), src)


def test_all_18_corruptions_5_levels_on_one_image(fixtures_dir, tmp_path, cli):
    out = tmp_path / "all"
    res = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split",
              fixtures_dir / "kitti_split.txt", "--out", out, "--limit", "1", "--size", "64x96", "--jobs", "1")
    assert res.exit_code == 0, res.output
    key = "kitti_data/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"
    assert len(NAMES) == 18
    assert set(tree(out)) == expected_paths([key], NAMES, [1, 2, 3, 4, 5])
    assert cli("verify", out).exit_code == 0


def test_full_dataset_job_counts(splits_dir):
    """The presets and the real splits give the published image counts."""
    from robodepth_cli.building.config import resolve
    from robodepth_cli.sources.datasets import get_dataset, read_split

    for preset, split, n_images, n_corrupted in [("kitti-c", "eigen_test_files.txt", 697, 62730),
                                                 ("nyudepth2-c", "nyudepthv2_test_files_with_gt.txt", 654, 39240)]:
        cfg = resolve(preset)
        ds = get_dataset(cfg.dataset)
        entries = read_split(splits_dir / split, ds.split_format)
        jobs = ds.jobs(cfg.variants, cfg.levels)
        assert len(entries) == n_images
        assert len({e.key for e in entries}) == n_images
        assert len(entries) * (len(jobs) - 1) == n_corrupted


@pytest.mark.slow
def test_jobs_1_and_2_give_identical_trees(kitti, tmp_path, build_kitti):
    root, split = kitti
    flags = ["--size", "64x96", "--corruptions", "gaussian_noise,impulse_noise,shot_noise,pixelate",
             "--levels", "2,5"]
    a, b = tmp_path / "a", tmp_path / "b"
    assert build_kitti(root, split, a, "--jobs", "1", *flags).exit_code == 0
    res = build_kitti(root, split, b, "--jobs", "2", *flags)
    assert res.exit_code == 0, res.output
    ta, tb = tree(a), tree(b)
    assert len(ta) == 2 * (1 + 4 * 2)
    assert ta == tb
    # The finished manifest is compacted and sorted, so it is identical too.
    assert (a / "manifest.csv").read_bytes() == (b / "manifest.csv").read_bytes()


def test_resume_redoes_only_missing_or_changed(kitti, tmp_path, cli, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    flags = ["--size", "64x96", "--corruptions", "contrast,shot_noise", "--levels", "1,2", "--jobs", "1"]
    assert build_kitti(root, split, out, *flags).exit_code == 0
    before = tree(out)
    inodes = {p: (out / p).stat().st_ino for p in before}
    deleted = f"shot_noise/2/{kitti_key(5)}"
    damaged = f"contrast/1/{kitti_key(7, 'r')}"
    (out / deleted).unlink()
    (out / damaged).write_bytes(b"not a png")

    res = build_kitti(root, split, out, *flags)
    assert res.exit_code == 0, res.output
    assert "2 written, 8 skipped" in res.output
    assert tree(out) == before
    # The deleted file is back (tree == before); its new inode may reuse the old number,
    # so only the files that were never deleted are compared by inode.
    redone = {p for p in before if p != deleted and (out / p).stat().st_ino != inodes[p]}
    assert redone == {damaged}
    assert cli("verify", out).exit_code == 0


def test_killed_build_leftovers_are_repaired(kitti, tmp_path, cli, build_kitti):
    """A torn manifest line and a temporary file, as SIGKILL leaves them, do not survive a rerun."""
    root, split = kitti
    out = tmp_path / "out"
    flags = ["--size", "64x96", "--corruptions", "pixelate", "--levels", "1", "--jobs", "1"]
    assert build_kitti(root, split, out, *flags).exit_code == 0
    lost = f"pixelate/1/{kitti_key(7, 'r')}"
    (out / lost).unlink()
    with open(out / "manifest.csv", "a") as fh:
        fh.write(f"{lost},2011_09_26/x.png,pixelate,1,0,64,96,ab12")  # no newline: torn
    temp = (out / lost).parent / ".0000000007.png.k2j3.part"
    temp.write_bytes(b"\x89PNG half")
    assert cli("verify", out).exit_code == 1  # the manifest still reads; the tree is incomplete

    res = build_kitti(root, split, out, *flags)
    assert res.exit_code == 0, res.output
    assert "1 written, 3 skipped" in res.output
    assert not temp.exists()
    assert cli("verify", out).exit_code == 0
    assert len(manifest_rows(out)) == 4


def test_unreadable_source_fails_alone(kitti, tmp_path, cli, build_kitti):
    root, split = kitti
    bad = root / "2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000005.png"
    bad.write_bytes(bad.read_bytes()[:200])  # truncated PNG
    with open(split, "a") as fh:
        fh.write("2011_09_26/2011_09_26_drive_0001_sync 0000000009 l\n")  # not on disk
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--size", "64x96", "--corruptions", "brightness", "--levels", "1,2",
                      "--jobs", "2")
    assert res.exit_code == 1
    # Six outputs failed, of two source images: each count names its unit.
    assert ("3 written, 0 skipped (already done), 6 failed (outputs of 2 images) of 9 outputs "
            "from 3 source images") in res.output
    assert f"wrote 3 outputs to {out}" in res.output
    assert str(bad) in res.output and "0000000009.png: no such file" in res.output
    assert set(tree(out)) == expected_paths([kitti_key(7, "r")], ["brightness"], [1, 2])
    failed = {r["output"]: r for r in manifest_rows(out) if r["error"]}
    assert set(failed) == expected_paths([kitti_key(5), kitti_key(9)], ["brightness"], [1, 2])
    assert all(r["sha256"] == "" for r in failed.values())
    v = cli("verify", out)
    assert v.exit_code == 1 and "failed: 6" in v.output


def test_per_variant_error_does_not_stop_the_others(kitti, tmp_path, monkeypatch, build_kitti):
    root, split = kitti

    def broken(self, clean, key, jobs):
        for job in jobs:
            yield job, (RuntimeError("boom") if job.level == 2 else clean)

    monkeypatch.setattr(renderers.CorruptionRenderer, "render", broken)  # in-process with --jobs 1
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--size", "64x96", "--corruptions", "contrast", "--levels", "1,2",
                      "--jobs", "1")
    assert res.exit_code == 1
    assert "contrast level 2: RuntimeError: boom" in res.output
    assert set(tree(out)) == expected_paths([kitti_key(5), kitti_key(7, "r")], ["contrast"], [1])


# --- whole-build problems: refused before any work, OUT untouched ---------------------------

def test_missing_root(tmp_path, kitti, build_kitti):
    _, split = kitti
    out = tmp_path / "out"
    res = build_kitti(tmp_path / "nowhere", split, out, "--corruptions", "contrast")
    assert res.exit_code == 2
    assert "nowhere: the root directory does not exist" in res.output
    assert "Traceback" not in res.output and not out.exists()


def test_no_listed_image_under_root(tmp_path, kitti, build_kitti):
    _, split = kitti
    (tmp_path / "empty").mkdir()
    res = build_kitti(tmp_path / "empty", split, tmp_path / "out", "--corruptions", "contrast")
    assert res.exit_code == 2 and "none of the 2 images" in res.output and "wrong --root" in res.output
    assert not (tmp_path / "out").exists()


def test_empty_split(tmp_path, kitti, build_kitti):
    root, split = kitti
    split.write_text("\n# nothing\n")
    res = build_kitti(root, split, tmp_path / "out", "--corruptions", "contrast")
    assert res.exit_code == 2 and f"{split}: the split lists no images" in res.output
    assert not (tmp_path / "out").exists()


def test_out_is_a_file(tmp_path, kitti, build_kitti):
    root, split = kitti
    (tmp_path / "out").write_text("x")
    res = build_kitti(root, split, tmp_path / "out", "--corruptions", "contrast")
    assert res.exit_code == 2 and "out: exists and is not a directory" in res.output
    res = build_kitti(root, split, tmp_path / "out" / "sub", "--corruptions", "contrast")
    assert res.exit_code == 2 and "cannot write the output directory" in res.output


def test_unwritable_out(tmp_path, kitti, monkeypatch, build_kitti):
    root, split = kitti

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(files.tempfile, "TemporaryFile", denied)  # files.probe_writable
    res = build_kitti(root, split, tmp_path / "out", "--corruptions", "contrast")
    assert res.exit_code == 2
    assert "out: cannot write the output directory (Permission denied)" in res.output
    assert list((tmp_path / "out").iterdir()) == []


def test_bad_config_refused_before_work(tmp_path, kitti, build_kitti):
    root, split = kitti
    cfg = tmp_path / "mine.yaml"
    cfg.write_text("seed: 3\nworkers: 4\n")
    res = build_kitti(root, split, tmp_path / "out", "--config", cfg)
    assert res.exit_code == 2
    assert f"{cfg}: unknown key 'workers'; valid keys:" in res.output and "jobs" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_second_build_into_same_out_is_refused(tmp_path, kitti, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    out.mkdir()
    with OutputFolder(out).lock():
        res = build_kitti(root, split, out, "--corruptions", "contrast")
    assert res.exit_code == 2 and "another build" in res.output
    assert tree(out) == {}
    assert build_kitti(root, split, out, "--corruptions", "contrast", "--size", "64x96",
                       "--jobs", "1").exit_code == 0


def test_write_error_stops_the_build_and_keeps_finished_work(kitti, tmp_path, monkeypatch, cli,
                                                             build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    flags = ["--size", "64x96", "--corruptions", "contrast", "--levels", "1,2", "--jobs", "1"]
    real, calls = jobs.write_png, []

    def disk_fills_up(path, img, level, **kw):
        calls.append(path)
        if len(calls) > 2:
            raise OSError(28, "No space left on device")
        return real(path, img, level, **kw)

    monkeypatch.setattr(jobs, "write_png", disk_fills_up)
    res = build_kitti(root, split, out, *flags)
    assert res.exit_code == 2
    assert f"{calls[2]}: cannot write (No space left on device); finished images are kept" in res.output
    assert len(calls) == 3  # nothing attempted after the failure
    assert set(tree(out)) == {f"clean/{kitti_key(5)}", f"contrast/1/{kitti_key(5)}"}

    monkeypatch.setattr(jobs, "write_png", real)
    res = build_kitti(root, split, out, *flags)
    assert res.exit_code == 0 and "4 written, 2 skipped" in res.output
    assert cli("verify", out).exit_code == 0


def test_source_gone_missing_keeps_its_finished_outputs(kitti, tmp_path, build_kitti):
    root, split = kitti
    out = tmp_path / "out"
    flags = ["--size", "64x96", "--corruptions", "contrast", "--jobs", "1"]
    assert build_kitti(root, split, out, *flags, "--levels", "1").exit_code == 0
    before = tree(out)
    (root / "2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000005.png").unlink()
    res = build_kitti(root, split, out, *flags, "--levels", "1,2")
    assert res.exit_code == 1
    assert "1 written, 4 skipped (already done), 1 failed" in res.output
    after = tree(out)
    assert {p: after[p] for p in before} == before
    assert set(after) - set(before) == {f"contrast/2/{kitti_key(7, 'r')}"}


def test_split_file_not_found(tmp_path, kitti, build_kitti):
    root, _ = kitti
    res = build_kitti(root, tmp_path / "nope.txt", tmp_path / "out", "--corruptions", "contrast")
    assert res.exit_code == 2
    assert f"{tmp_path / 'nope.txt'}: cannot read the split (No such file or directory)" in res.output


def test_kitti_c_build_never_imports_torch(kitti, tmp_path):

    root, split = kitti
    argv = ["build", "kitti-c", "--root", root, "--split", split, "--out", tmp_path / "out", "--corruptions",
            "contrast", "--levels", "1", "--size", "64x96", "--jobs", "1", "--no-progress"]
    assert imported_by_command(argv, ["torch"]) == []
    assert len(tree(tmp_path / "out")) == 4


def test_record_lists_the_built_entries_in_split_order(tmp_path, build_kitti):
    """build.json names the split entries built (after --limit), in the split's order, so a
    reader of OUT can pair outputs with the split without re-reading it."""
    import json

    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, [(9, "l", ".png"), (3, "r", ".png"), (5, "l", ".png")])
    out = tmp_path / "out"
    res = build_kitti(root, split, out, "--size", "48x96", "--corruptions", "contrast", "--levels", "1",
                      "--jobs", "1", "--limit", "2")
    assert res.exit_code == 0, res.output
    record = json.loads((out / "build.json").read_text())
    assert record["split"]["keys"] == [kitti_key(9, "l"), kitti_key(3, "r")]
    assert record["split"]["images"] == 2
