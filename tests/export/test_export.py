"""`robodepth export`: a build as Hugging Face parquet or WebDataset shards, read back by the
libraries users read them with (datasets, webdataset, tarfile) and by robodepth itself, and
checked by `robodepth verify`."""

from __future__ import annotations

import io
import json
import shutil
import tarfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.helpers.imports import imported_by_command
from tests.helpers.manifest import manifest_by_output
from tests.helpers.paths import FIXTURES

MODEL = '''
import numpy as np

def brightness(images):
    return (0.02 + images.mean(axis=3) / 2550).astype(np.float32)
'''


@pytest.fixture(scope="module")
def build(tmp_path_factory, cli, kitti_scans_root) -> Path:
    """A KITTI-C build of the two fixture frames with their ground truth (gt_depths.npz)."""
    tmp = tmp_path_factory.mktemp("export")
    root = kitti_scans_root
    out = tmp / "KITTI_C"
    res = cli("build", "kitti-c", "--root", root, "--split", FIXTURES / "kitti_split.txt", "--out",
              out, "--corruptions", "fog,gaussian_noise", "--levels", "1,3", "--size", "48x160",
              "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert (out / "gt_depths.npz").is_file()
    return out


def _kitti_maps(build: Path) -> list[np.ndarray]:
    """The build's own gt_depths.npz as monodepth2 reads it (a test may unpickle its own file)."""
    return list(np.load(build / "gt_depths.npz", allow_pickle=True)["data"])


def _npy_sha(depth) -> str:
    """sha256 of the map saved as a .npy (format 1.0, little-endian float32), numpy's own way."""
    import hashlib

    buf = io.BytesIO()
    np.save(buf, np.asarray(depth, dtype="<f4"), allow_pickle=False)
    return hashlib.sha256(buf.getvalue()).hexdigest()


def _tree_bytes(out: Path) -> dict[str, bytes]:
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def exports(build, tmp_path_factory, cli) -> dict[str, Path]:
    """Both formats; 20 kB shards, so each split of two ~12 kB images has two shards."""
    before = _tree_bytes(build)
    tmp = tmp_path_factory.mktemp("exports")
    made = {}
    for fmt in ("parquet", "webdataset"):
        res = cli("export", build, "--format", fmt, "--to", tmp / fmt, "--shard-size", "20kB",
                  "--no-progress")
        assert res.exit_code == 0, res.output
        made[fmt] = tmp / fmt
    assert _tree_bytes(build) == before  # the build is read, never written
    return made


def _pixels(data: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB"))


def _variants(build: Path) -> dict[tuple[str, str], list[str]]:
    """(configuration, split) -> the build's files in split order, from the build's own
    record and its layout (clean/KEY, CORRUPTION/LEVEL/KEY)."""
    keys = json.loads((build / "build.json").read_text())["split"]["keys"]
    out = {("clean", "test"): [f"clean/{k}" for k in keys]}
    for c in ("fog", "gaussian_noise"):
        for lv in (1, 3):
            out[(c, f"level_{lv}")] = [f"{c}/{lv}/{k}" for k in keys]
    return out


def test_parquet_loads_with_datasets_pixel_for_pixel(build, exports, tmp_path, monkeypatch):
    monkeypatch.setenv("HF_DATASETS_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    import datasets

    monkeypatch.setattr(datasets.config, "HF_DATASETS_OFFLINE", True, raising=False)
    monkeypatch.setattr(datasets.config, "HF_HUB_OFFLINE", True, raising=False)
    export = exports["parquet"]
    assert (export / "data/fog/level_3-00000-of-00002.parquet").is_file()
    assert (export / "data/fog/level_3-00001-of-00002.parquet").is_file()
    card = (export / "README.md").read_text()
    assert card.startswith("---\n") and "config_name: \"fog\"" in card and "kong2023robodepth" in card
    assert "| 3 | fog | weather & lighting | t, d | 1.5, 2 |" in card and "| 1 | brightness" not in card
    assert "- `fog`: levels 1, 3; seed 0; numpy engine" in card and "Size 48x160 (HxW)" in card
    assert "cc-by-nc-sa-3.0" in card
    assert "`robodepth build kitti-c` of 2 images from KITTI raw data (Geiger" in card
    manifest = manifest_by_output(build)
    keys = json.loads((build / "build.json").read_text())["split"]["keys"]
    for (config, split), files in _variants(build).items():
        ds = datasets.load_dataset(str(export), config, split=split, cache_dir=str(tmp_path / "hf"))
        assert ds.features["image"].__class__.__name__ == "Image"
        assert ds["key"] == keys  # split order
        for row, file in zip(ds, files):
            assert np.array_equal(np.asarray(row["image"]), _pixels((build / file).read_bytes()))
            assert row["sha256"] == manifest[file]["sha256"]
            assert row["variant"] == config
            assert row["level"] == (None if split == "test" else float(split[len("level_"):]))
        raw = ds.cast_column("image", datasets.Image(decode=False))
        assert [r["image"]["bytes"] for r in raw] == [(build / f).read_bytes() for f in files]
        assert [r["image"]["path"] for r in raw] == files
    # The ground truth: one row per image, keyed like the images, its map a 2-D float array
    # that datasets decodes without pickle, NaN where the build's file has 0 (no return).
    gt = datasets.load_dataset(str(export), "ground_truth", split="test", cache_dir=str(tmp_path / "hf"))
    assert gt.features["depth"] == datasets.Sequence(datasets.Sequence(datasets.Value("float32")))
    assert gt["key"] == keys and gt["path"] == ["gt_depths.npz"] * 2
    for row, want in zip(gt.with_format("numpy"), _kitti_maps(build)):
        assert row["depth"].dtype == np.float32 and row["depth"].shape == want.shape == (375, 1242)
        np.testing.assert_array_equal(row["depth"], np.where(want > 0, want, np.nan))
        assert row["sha256"] == _npy_sha(row["depth"])


def test_tar_shards_load_with_webdataset_and_tarfile(build, exports):
    import webdataset as wds

    export = exports["webdataset"]
    manifest = manifest_by_output(build)
    for (config, split), files in _variants(build).items():
        shards = sorted(str(p) for p in (export / "data" / config).glob(f"{split}-*.tar"))
        assert len(shards) == 2
        samples = list(wds.WebDataset(shards, shardshuffle=False, empty_check=False).decode("rgb8"))
        assert [s["json"]["path"] for s in samples] == files
        for s, file in zip(samples, files):
            assert s["__key__"] + ".png" == s["json"]["key"] == file.split("/", 1 if config == "clean" else 2)[-1]
            assert np.array_equal(s["png"], _pixels((build / file).read_bytes()))
            assert s["json"]["sha256"] == manifest[file]["sha256"]
        members = {}
        for shard in shards:
            with tarfile.open(shard) as tar:
                members.update({m.name: tar.extractfile(m).read() for m in tar if m.name.endswith(".png")})
        assert [members[f.split("/", 1 if config == "clean" else 2)[-1]] for f in files] == \
               [(build / f).read_bytes() for f in files]
    keys = json.loads((build / "build.json").read_text())["split"]["keys"]
    shards = sorted(str(p) for p in (export / "data/ground_truth").glob("test-*.tar"))
    samples = list(wds.WebDataset(shards, shardshuffle=False, empty_check=False).decode())
    assert [s["json"]["key"] for s in samples] == keys
    for s, key, want in zip(samples, keys, _kitti_maps(build)):
        assert s["__key__"] + ".png" == key and s["json"]["path"] == "gt_depths.npz"
        np.testing.assert_array_equal(s["depth.npy"], np.where(want > 0, want, np.nan))
        assert s["json"]["sha256"] == _npy_sha(s["depth.npy"])
    with tarfile.open(shards[0]) as tar:  # a plain .npy: numpy loads it without pickle
        member = tar.extractfile(keys[0][:-len(".png")] + ".depth.npy").read()
        assert np.load(io.BytesIO(member), allow_pickle=False).shape == (375, 1242)


@pytest.mark.parametrize("fmt", ["parquet", "webdataset"])
def test_verify_names_a_changed_missing_or_extra_row(build, exports, tmp_path, cli, fmt):
    export = tmp_path / fmt
    shutil.copytree(exports[fmt], export)
    res = cli("verify", export)
    assert res.exit_code == 0 and "12 files match the manifest" in res.output, res.output
    assert (export / "robodepth" / "manifest.csv").read_bytes() == (build / "manifest.csv").read_bytes()
    ext = "parquet" if fmt == "parquet" else "tar"
    # One byte of one image, inside its shard: the image is named, and so is the shard.
    shard = export / f"data/fog/level_3-00000-of-00002.{ext}"
    data = bytearray(shard.read_bytes())
    key = json.loads((build / "build.json").read_text())["split"]["keys"][0]
    png = (build / "fog" / "3" / key).read_bytes()
    at = bytes(data).index(png) + len(png) // 2
    data[at] ^= 0xFF
    shard.write_bytes(bytes(data))
    (export / f"data/clean/test-00001-of-00002.{ext}").unlink()
    shutil.copy(export / f"data/fog/level_1-00000-of-00002.{ext}", export / f"data/fog/level_1-x.{ext}")
    res = cli("verify", export)
    assert res.exit_code == 1, res.output
    lines = res.output.splitlines()
    assert f"  fog/3/{key}" in lines  # changed
    assert any(line.startswith(f"  data/fog/level_3-00000-of-00002.{ext} (shard") for line in lines)
    second = json.loads((build / "build.json").read_text())["split"]["keys"][1]
    assert "missing: 1" in lines and f"  clean/{second}" in lines
    assert f"  data/fog/level_1-x.{ext}" in lines  # a file the export record does not name


def test_open_dataset_and_kittic_read_an_export_as_the_build(build, exports):
    from robodepth_cli import open_dataset
    from robodepth_cli.api import DatasetError
    from robodepth_cli.torch import KittiC

    tree = open_dataset(build)
    for export in exports.values():
        ds = open_dataset(export)
        assert ds.name == tree.name and ds.keys == tree.keys
        assert [(v.name, v.level) for v in ds.variants()] == [(v.name, v.level) for v in tree.variants()]
        for v, t in zip(ds.variants(), tree.variants()):
            for i in range(len(v)):
                assert np.array_equal(v.read(i), t.read(i))
                with v.open(i) as a, t.open(i) as b:
                    assert a.read() == b.read()
        with pytest.raises(DatasetError, match="images are in shards; use variant.read"):
            ds.variants()[0].images()
        got = np.load(ds.ground_truth(), allow_pickle=True)["data"]  # written back from the rows
        assert all(np.array_equal(a, b) for a, b in zip(got, _kitti_maps(build))) and len(got) == 2
        a, b = KittiC(export, "fog", 3), KittiC(build, "fog", 3)
        assert len(a) == len(b) == 2
        for i in range(2):
            x, y = a[i], b[i]
            assert x["key"] == y["key"]
            assert np.array_equal(x["image"].numpy(), y["image"].numpy())
            assert np.array_equal(x["depth"].numpy(), y["depth"].numpy())
        fly = KittiC(export, "fog", 3, on_the_fly=True)
        assert np.array_equal(fly[1]["image"].numpy(), b[1]["image"].numpy())


def test_predict_and_evaluate_an_export_as_the_build(build, exports, tmp_path, cli):
    module = tmp_path / "m.py"
    module.write_text(MODEL)
    results = {}
    for name, where in [("tree", build), *exports.items()]:
        pred = tmp_path / f"P_{name}"
        res = cli("predict", where, "-m", f"python:{module}:brightness", "--kind", "disp", "-o", pred)
        assert res.exit_code == 0, res.output
        res = cli("evaluate", where, "--pred", pred, "--out", tmp_path / f"{name}.csv")
        assert res.exit_code == 0, res.output
        results[name] = ({p.relative_to(pred).as_posix(): p.read_bytes() for p in pred.rglob("*.npy")},
                         (tmp_path / f"{name}.csv").read_text())
    assert len(results["tree"][0]) == 5
    assert results["parquet"] == results["tree"] == results["webdataset"]


def test_resume_rewrites_only_the_missing_shard(build, exports, tmp_path, cli):
    export = tmp_path / "again"
    shutil.copytree(exports["parquet"], export)
    before = _tree_bytes(export)
    (export / "data/gaussian_noise/level_1-00001-of-00002.parquet").unlink()
    # What a killed export leaves: a shard under its temporary name, and a record that does
    # not say finished.
    (export / "data/gaussian_noise/.level_1-00001-of-00002.parquet.abc.part").write_bytes(b"PAR1")
    record = json.loads((export / "robodepth/export.json").read_text())
    (export / "robodepth/export.json").write_text(json.dumps({**record, "status": "running"}))
    with pytest.raises(Exception, match="did not finish"):
        from robodepth_cli import open_dataset

        open_dataset(export)
    res = cli("export", build, "--format", "parquet", "--to", export, "--shard-size", "20kB",
              "--no-progress")
    assert res.exit_code == 0, res.output
    assert "12 rows in 12 parquet shards (1 written now)" in res.output
    assert _tree_bytes(export) == before  # the same shard, byte for byte


def test_an_interrupted_export_keeps_whole_shards_and_resumes(build, exports, tmp_path, cli,
                                                              monkeypatch):
    from robodepth_cli.export import driver

    real = driver.WRITERS["webdataset"]
    calls = []

    def stopping(fh, *args):
        calls.append(1)
        if len(calls) == 4:
            fh.write(b"half a shard")
            raise KeyboardInterrupt  # Ctrl-C in the middle of the fourth shard
        return real(fh, *args)

    monkeypatch.setitem(driver.WRITERS, "webdataset", stopping)
    export = tmp_path / "wds"
    args = ("export", build, "--format", "webdataset", "--to", export, "--shard-size", "20kB",
            "--no-progress")
    res = cli(*args)
    assert res.exit_code == 130
    assert "robodepth: interrupted; finished shards are kept in" in res.output
    files = sorted(p.name for p in (export / "data").rglob("*") if p.is_file())
    assert len(files) == 3 and not any(f.endswith(".part") for f in files)
    assert len((export / "robodepth/.shards.jsonl").read_text().splitlines()) == 3
    monkeypatch.setitem(driver.WRITERS, "webdataset", real)
    res = cli(*args)
    assert res.exit_code == 0 and "(9 written now)" in res.output, res.output
    assert not (export / "robodepth/.shards.jsonl").exists()
    assert _tree_bytes(export) == _tree_bytes(exports["webdataset"])


def test_refusals(build, exports, tmp_path, cli):
    def refused(*args) -> str:
        res = cli("export", *args, "--no-progress")
        assert res.exit_code == 2, res.output
        return res.output.strip()

    other = exports["parquet"]
    assert "holds an export of another build or with other options" in refused(
        build, "--format", "parquet", "--to", other)  # default shard size, not 20kB
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("mine")
    assert "not empty and not an export" in refused(build, "--format", "webdataset", "--to", tmp_path / "full")
    assert "must be outside the build" in refused(build, "--format", "parquet", "--to", build / "hf")
    assert "--shard-size '0.1x'" in refused(build, "--format", "parquet", "--to", tmp_path / "a",
                                            "--shard-size", "0.1x")
    assert "not a directory" in refused(tmp_path / "nothing", "--format", "parquet", "--to", tmp_path / "b")
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert "cannot write" in refused(build, "--format", "parquet", "--to", blocker / "sub")
    # A build whose file changed since its manifest is not exported, and nothing is left.
    changed = tmp_path / "changed"
    shutil.copytree(build, changed)
    victim = next((changed / "clean").rglob("*.png"))
    victim.write_bytes(victim.read_bytes() + b"x")
    msg = refused(changed, "--format", "webdataset", "--to", tmp_path / "c")
    assert f"{victim}: changed since the build" in msg
    assert not list((tmp_path / "c" / "data").rglob("*.tar"))


def test_a_build_with_failed_images_is_refused(tmp_path, cli):
    from tests.helpers.trees import random_image, save

    root = tmp_path / "root"
    for i in range(2):
        path = save(root / f"img{i}.png", random_image(40, 48, seed=i))
    path.write_bytes(path.read_bytes()[:100])  # unreadable: the build fails it
    out = tmp_path / "out"
    assert cli("build", "custom", "--root", root, "--out", out, "--corruptions", "fog",
               "--levels", "2").exit_code == 1
    res = cli("export", out, "--format", "parquet", "--to", tmp_path / "x", "--no-progress")
    assert res.exit_code == 2
    assert res.output.startswith(f"robodepth: error: {out}: 1 of 2 images failed in the build (img1.png:")
    assert "export a finished build" in res.output
    assert not (tmp_path / "x").exists()


def test_a_plain_build_imports_no_export_library(tmp_path):

    split = FIXTURES / "kitti_split.txt"
    argv = ["build", "kitti-c", "--root", FIXTURES / "kitti_raw", "--split", split, "--out", tmp_path / "out",
            "--corruptions", "contrast", "--levels", "1", "--size", "48x64", "--jobs", "1", "--no-progress"]
    assert imported_by_command(argv, ["pyarrow", "webdataset", "datasets"]) == []


def _evaluated_three_ways(cli, tmp_path, out) -> list[str]:
    """The results CSV of the same depth predictions evaluated on the build ``out`` and on
    its parquet and webdataset exports (each export verified first)."""
    module = tmp_path / "m.py"
    module.write_text(MODEL)
    results = []
    for fmt in ("tree", "parquet", "webdataset"):
        where = out if fmt == "tree" else tmp_path / fmt
        if fmt != "tree":
            res = cli("export", out, "--format", fmt, "--to", where, "--no-progress")
            assert res.exit_code == 0, res.output
            assert cli("verify", where).exit_code == 0
        res = cli("predict", where, "-m", f"python:{module}:brightness", "--kind", "depth", "-o",
                  tmp_path / f"P_{fmt}")
        assert res.exit_code == 0, res.output
        res = cli("evaluate", where, "--pred", tmp_path / f"P_{fmt}", "--out", tmp_path / f"{fmt}.csv")
        assert res.exit_code == 0, res.output
        results.append((tmp_path / f"{fmt}.csv").read_text())
    return results


def test_nyu_ground_truth_rows_and_evaluation(tmp_path, cli):
    """NYU's ground truth is a PNG per image: one ground_truth row each, keyed by its image,
    and evaluate reads them back out of the shards."""
    out = tmp_path / "NYU_C"
    res = cli("build", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", FIXTURES / "nyu_split.txt",
              "--out", out, "--corruptions", "dark", "--levels", "2", "--size", "48x64", "--jobs", "1")
    assert res.exit_code == 0, res.output
    gts = sorted((out / "gt").rglob("*.png"))
    assert len(gts) == 2
    results = _evaluated_three_ways(cli, tmp_path, out)
    assert results[0] == results[1] == results[2]
    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "parquet" / "data/ground_truth/test-00000-of-00001.parquet")
    keys = json.loads((out / "build.json").read_text())["split"]["keys"]
    assert table.column("key").to_pylist() == keys
    assert table.column("path").to_pylist() == [p.relative_to(out).as_posix() for p in gts]
    for depth, png in zip(table.column("depth").to_pylist(), gts):
        mm = np.asarray(Image.open(png), dtype=np.float64)  # 16-bit millimetres, 0: none
        want = np.where(mm > 0, mm / 1000, np.nan).astype(np.float32)
        np.testing.assert_array_equal(np.asarray(depth, dtype=np.float32), want)


def test_report_draws_a_frame_of_an_export_as_of_the_build(build, exports, tmp_path, cli):
    """`report --dataset` takes an export: the one-frame figure's images are the build's."""
    pytest.importorskip("matplotlib")
    from robodepth_cli.report import write as W
    from robodepth_cli.report.qualitative import qualitative
    from tests.helpers.report import evaluate_csv, tables  # a whole KITTI-C results file (the paper's figures)

    module = tmp_path / "m.py"
    module.write_text(MODEL)
    pred = tmp_path / "P"
    assert cli("predict", build, "-m", f"python:{module}:brightness", "--kind", "disp", "-o", pred).exit_code == 0
    report = W.assemble(tables([evaluate_csv(tmp_path / "r.csv", "kitti-c", "MonoViT")]), ["m"], None, "none", build)

    def pixels(where):
        (_, _, _, fig), _ = qualitative(report, where, [pred], 1)
        return [np.asarray(im.get_array()) for ax in fig.axes for im in ax.get_images()]

    tree = pixels(build)
    assert len(tree) >= 4
    for export in exports.values():
        got = pixels(export)
        assert len(got) == len(tree) and all(np.array_equal(a, b) for a, b in zip(tree, got))


def test_a_frames_build_exports_every_neighbour_frame(tmp_path, cli, frames_build, monkeypatch):
    """A build with --frames: every file of it is exported (the neighbour frames in a split
    ``<split>_neighbours`` of their variant, by key), read back by datasets, webdataset and
    KittiC(frames=) as from the build, and verify passes."""
    monkeypatch.setenv("HF_DATASETS_OFFLINE", "1")
    import datasets
    import webdataset as wds

    from tests.helpers.trees import kitti_key
    from robodepth_cli.torch import KittiC

    out = frames_build
    files = manifest_by_output(out)
    neighbours = [kitti_key(n) for n in (1, 3, 4)]
    for fmt in ("parquet", "webdataset"):
        to = tmp_path / fmt
        res = cli("export", out, "--format", fmt, "--to", to, "--no-progress")
        assert res.exit_code == 0, res.output
        assert f"{len(files)} rows" in res.output
        res = cli("verify", to)
        assert res.exit_code == 0 and f"{len(files)} files match" in res.output, res.output
        for config, folder in (("clean", "clean"), ("fog", "fog/3")):
            split_name = "test" if config == "clean" else "level_3"
            if fmt == "parquet":
                ds = datasets.load_dataset(str(to), config, split=split_name + "_neighbours",
                                           cache_dir=str(tmp_path / "hf"))
                got = {r["key"]: np.asarray(r["image"]) for r in ds}
            else:
                shards = sorted(str(p) for p in (to / "data" / config).glob(f"{split_name}_neighbours-*.tar"))
                got = {s["json"]["key"]: s["png"] for s in wds.WebDataset(shards, shardshuffle=False).decode("rgb8")}
            assert list(got) == neighbours
            for key, pixels in got.items():
                assert np.array_equal(pixels, _pixels((out / folder / key).read_bytes()))
        a, b = KittiC(to, "fog", 3, frames=(-1, 1)), KittiC(out, "fog", 3, frames=(-1, 1))
        for i in range(len(b)):
            for x, y in zip(a[i]["neighbours"], b[i]["neighbours"]):
                assert np.array_equal(x.numpy(), y.numpy())
        assert b[1]["neighbours"][0].numpy().any()  # frame 1, read from the export


def test_an_export_that_would_leave_out_a_file_is_refused(build, tmp_path, cli):
    """A manifest row the build's record does not place (here: a key of no split) would be
    dropped: refused before any shard is written."""
    changed = tmp_path / "changed"
    shutil.copytree(build, changed)
    lines = (changed / "manifest.csv").read_text().splitlines(keepends=True)
    row = next(line for line in lines if line.startswith("clean/"))
    key = row.split(",", 1)[0]
    stray = "clean/elsewhere.png" + row[len(key):]
    shutil.copy(changed / key, changed / "clean/elsewhere.png")
    (changed / "manifest.csv").write_text("".join(lines) + stray)
    res = cli("export", changed, "--format", "parquet", "--to", tmp_path / "x", "--no-progress")
    assert res.exit_code == 2, res.output
    assert "1 file(s) of the build would not be exported (clean/elsewhere.png)" in res.output
    assert not list((tmp_path / "x").rglob("*.parquet"))


def test_depth_build_ground_truth_rows_evaluate_and_verify(tmp_path, cli, monkeypatch):
    """A build with depth (custom --depth): one ground_truth row per image, its float map as
    built (NaN kept), in datasets and webdataset; evaluate on either export gives the build's
    results; verify names a map whose values changed."""
    monkeypatch.setenv("HF_DATASETS_OFFLINE", "1")
    import datasets
    import webdataset as wds

    from tests.helpers.trees import random_image, save

    maps = {"a": np.full((40, 48), 7.5, np.float32), "sub/b": np.linspace(1, 60, 40 * 48, dtype=np.float32).reshape(40, 48)}
    maps["sub/b"][:5] = np.nan
    for i, name in enumerate(maps):
        save(tmp_path / "img" / f"{name}.png", random_image(40, 48, seed=i))
        (tmp_path / "depth" / name).parent.mkdir(parents=True, exist_ok=True)
        np.save(tmp_path / "depth" / f"{name}.npy", maps[name])
    out = tmp_path / "out"
    res = cli("build", "custom", "--root", tmp_path / "img", "--depth", tmp_path / "depth", "--out", out,
              "--corruptions", "fog", "--levels", "2", "--jobs", "1")
    assert res.exit_code == 0, res.output
    results = _evaluated_three_ways(cli, tmp_path, out)
    assert results[0] == results[1] == results[2]
    keys = json.loads((out / "build.json").read_text())["split"]["keys"]
    assert keys == ["a.png", "sub/b.png"]
    gt = datasets.load_dataset(str(tmp_path / "parquet"), "ground_truth", split="test",
                               cache_dir=str(tmp_path / "hf")).with_format("numpy")
    assert list(gt["key"]) == keys
    for row, name in zip(gt, maps):
        np.testing.assert_array_equal(row["depth"], maps[name])
    shards = sorted(str(p) for p in (tmp_path / "webdataset/data/ground_truth").glob("*.tar"))
    samples = list(wds.WebDataset(shards, shardshuffle=False, empty_check=False).decode())
    assert [s["__key__"] for s in samples] == ["a", "sub/b"]
    for s, name in zip(samples, maps):
        np.testing.assert_array_equal(s["depth.npy"], maps[name])
    # One value of b's map changed inside its tar member (same length): verify names it.
    shard = Path(shards[0])
    data = bytearray(shard.read_bytes())
    at = bytes(data).index(np.float32(60.0).tobytes())
    data[at:at + 4] = np.float32(61.0).tobytes()
    shard.write_bytes(bytes(data))
    res = cli("verify", tmp_path / "webdataset")
    assert res.exit_code == 1 and "  gt/sub/b.npy" in res.output.splitlines(), res.output


def test_the_card_describes_every_request_into_the_build(build, tmp_path, cli):
    """Two more requests into the build (fog level 1 again; contrast with the torch engine):
    the card lists what the export holds, not the last request's levels."""
    out = tmp_path / "K"
    shutil.copytree(build, out)
    root = tmp_path / "kitti_raw"
    shutil.copytree(FIXTURES / "kitti_raw", root)
    for extra in (("--corruptions", "contrast", "--levels", "2", "--engine", "torch"),
                  ("--corruptions", "fog", "--levels", "1")):
        res = cli("build", "kitti-c", "--root", root, "--split", FIXTURES / "kitti_split.txt", "--out",
                  out, "--size", "48x160", "--jobs", "1", "--no-gt", *extra)
        assert res.exit_code == 0, res.output
    res = cli("export", out, "--format", "parquet", "--to", tmp_path / "hf", "--no-progress")
    assert res.exit_code == 0, res.output
    card = (tmp_path / "hf" / "README.md").read_text()
    assert "- `fog`: levels 1, 3; seed 0; numpy engine" in card
    assert "- `gaussian_noise`: levels 1, 3; seed 0; numpy engine" in card
    assert "- `contrast`: levels 2; seed 0; torch engine" in card
    assert "- `clean`: seed 0" in card and "levels [1]" not in card


@pytest.mark.parametrize("existing", [False, True], ids=["new-folder", "empty-folder"])
def test_an_export_refused_mid_way_leaves_nothing_half_made(build, tmp_path, cli, existing):
    # A file of the build's last variant changed: the shards before it were written when the
    # refusal came (issue 42: 4 shards and export.json "running" were left).
    changed = tmp_path / "changed"
    shutil.copytree(build, changed)
    victim = sorted((changed / "gaussian_noise" / "3").rglob("*.png"))[-1]
    victim.write_bytes(victim.read_bytes() + b"x")
    to = tmp_path / "new" / "wds"
    if existing:
        to.mkdir(parents=True)
    res = cli("export", changed, "--format", "webdataset", "--to", to, "--shard-size", "20kB",
              "--no-progress")
    assert res.exit_code == 2 and f"{victim}: changed since the build" in res.output, res.output
    if existing:
        assert to.is_dir() and list(to.iterdir()) == []
    else:
        assert not (tmp_path / "new").exists()


def test_verify_of_an_unfinished_export_says_so(build, tmp_path, cli, monkeypatch):
    from robodepth_cli.export import driver

    real = driver.WRITERS["parquet"]
    calls = []

    def stopping(*args):
        calls.append(1)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return real(*args)

    monkeypatch.setitem(driver.WRITERS, "parquet", stopping)
    export = tmp_path / "hf"
    res = cli("export", build, "--format", "parquet", "--to", export, "--shard-size", "20kB",
              "--no-progress")
    assert res.exit_code == 130, res.output
    res = cli("verify", export)
    assert res.exit_code == 1, res.output
    assert f"{export}: an unfinished export (4 of 12 shards written); rerun the export command " \
           "to finish it" in res.output.splitlines(), res.output
    assert "missing" not in res.output, res.output


def test_the_card_of_one_image_of_your_own_reads_right(tmp_path, cli):
    # It said "of 1 images of your own images" (issue 42).
    from tests.helpers.trees import random_image, save

    save(tmp_path / "mine" / "a.png", random_image(32, 48, seed=0))
    out = tmp_path / "MINE_C"
    res = cli("build", "custom", "--root", tmp_path / "mine", "--out", out, "--corruptions",
              "brightness", "--levels", "1", "--jobs", "1")
    assert res.exit_code == 0, res.output
    res = cli("export", out, "--format", "webdataset", "--to", tmp_path / "wds", "--no-progress")
    assert res.exit_code == 0, res.output
    card = (tmp_path / "wds" / "README.md").read_text()
    assert "The images of a `robodepth build custom` of 1 image from your own folder of images, " \
           "byte for byte as built" in card, card
