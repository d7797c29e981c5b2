"""`robodepth predict`'s guards: a python: module edited between runs, PRED inside the
dataset, the memory of one batch, the `next:` hint's quoting, and the messages for a
foreign checkpoint and a mistyped hf: folder."""

from __future__ import annotations

import json
import shlex

import numpy as np
import pytest

MODULE = '''
import numpy as np

def predict(images):
    with open(__file__ + ".calls", "a") as fh:
        fh.write(f"{len(images)}\\n")
    return (OFFSET + images.mean(axis=3) / 255).astype(np.float32)

OFFSET = 1.0
'''


@pytest.fixture(scope="module")
def dataset(kitti_c_build):
    return kitti_c_build


@pytest.fixture
def module(tmp_path):
    path = tmp_path / "m.py"
    path.write_text(MODULE)
    return path


def calls(module) -> list[int]:
    path = module.parent / (module.name + ".calls")
    return [int(x) for x in path.read_text().split()] if path.exists() else []


def test_python_module_edited_between_runs_is_refused(dataset, tmp_path, cli, module):
    pred = tmp_path / "P"
    spec = f"python:{module}:predict"
    res = cli("predict", dataset, "-m", spec, "--kind", "disp", "-o", pred, "--variants", "clean")
    assert res.exit_code == 0, res.output
    record = json.loads((pred / "predictions.json").read_text())
    import hashlib

    assert record["identity"]["sha256"] == hashlib.sha256(module.read_bytes()).hexdigest()
    # the same module again: resumes (clean skipped, the rest added)
    res = cli("predict", dataset, "-m", spec, "--kind", "disp", "-o", pred)
    assert res.exit_code == 0, res.output
    assert "(1 already done, skipped)" in res.output
    # edited: refused before anything is written, the earlier predictions kept
    before = {p: p.read_bytes() for p in pred.rglob("*") if p.is_file()}
    module.write_text(MODULE.replace("OFFSET = 1.0", "OFFSET = 2.0"))
    res = cli("predict", dataset, "-m", spec, "--kind", "disp", "-o", pred)
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1, res.output
    assert "holds predictions of another model or setting" in res.output
    assert "identity differs" in res.output and "python: module's file" in res.output
    assert {p: p.read_bytes() for p in pred.rglob("*") if p.is_file()} == before


def test_out_inside_the_dataset_is_refused(dataset, tmp_path, cli, module):
    spec = f"python:{module}:predict"
    for inside in (dataset / "P", dataset, dataset / "brightness" / "P"):
        res = cli("predict", dataset, "-m", spec, "--kind", "disp", "-o", inside)
        assert res.exit_code == 2, res.output
        assert f"--out {inside}: inside the dataset {dataset}" in res.output
        assert len(res.output.strip().splitlines()) == 1, res.output
    assert not (dataset / "P").exists() and not (dataset / "brightness" / "P").exists()
    assert calls(module) == []
    # through a symlink to the dataset too
    (tmp_path / "link").symlink_to(dataset)
    res = cli("predict", dataset, "-m", spec, "--kind", "disp", "-o", tmp_path / "link" / "P")
    assert res.exit_code == 2 and "inside the dataset" in res.output
    assert cli("verify", dataset).exit_code == 0


def test_batch_limit_by_pixels():
    from robodepth_cli.models import predict as P

    assert P.BATCH_PIXELS == 2 ** 22
    assert P.batch_limit(100000, (192, 640)) == 2 ** 22 // (192 * 640) == 34
    assert P.batch_limit(100000, (375, 1242)) == 9
    assert P.batch_limit(8, (375, 1242)) == P.batch_limit(8, (480, 640)) == 8  # the default stays
    # counted at the network's input when that is larger (monodepth2's [h, w], a processor's dict)
    assert P.batch_limit(100000, (48, 64), [192, 640]) == 34
    assert P.batch_limit(100000, (48, 64), {"height": 518, "width": 518}) == 2 ** 22 // 518 ** 2
    assert P.batch_limit(100000, (48, 64), {"shortest_edge": 384}) == 2 ** 22 // (48 * 64)
    assert P.batch_limit(5, (10000, 10000)) == 1  # one image always goes


def test_huge_batch_size_is_lowered(dataset, tmp_path, cli, module, monkeypatch):
    from robodepth_cli.models import predict as P

    # a budget of one 64 x 96 image and a half: every batch holds one image
    monkeypatch.setattr(P, "BATCH_PIXELS", 64 * 96 * 3 // 2)
    res = cli("predict", dataset, "-m", f"python:{module}:predict", "--kind", "disp",
              "-o", tmp_path / "P", "-b", 100000)
    assert res.exit_code == 0, res.output
    assert "--batch-size 100000: 1 images per batch (a batch holds at most 9,216 pixels)" in res.output
    assert calls(module) == [1] * 10  # 5 variants x 2 frames
    assert np.load(tmp_path / "P" / "clean.npy").shape == (2, 64, 96)


def test_mixed_size_build_batches_by_pixels(tmp_path, cli, module, monkeypatch):
    from PIL import Image

    from robodepth_cli.models import predict as P

    root = tmp_path / "photos"
    root.mkdir()
    for i, (w, h) in enumerate([(64, 48), (64, 48), (40, 32), (64, 48)]):
        Image.new("RGB", (w, h), (40 * i, 90, 200)).save(root / f"f{i}.png")
    res = cli("build", "custom", "--root", root, "--out", tmp_path / "C", "--corruptions", "none",
              "--compose", "brightness:1", "--jobs", "1")
    assert res.exit_code == 0, res.output
    # f0 and f1 (one size) would be one batch of 2 without the budget
    monkeypatch.setattr(P, "BATCH_PIXELS", 2 * 64 * 48 - 1)
    res = cli("predict", tmp_path / "C", "-m", f"python:{module}:predict", "--kind", "disp",
              "-o", tmp_path / "P", "--variants", "clean", "-b", 100)
    assert res.exit_code == 0, res.output
    assert calls(module) == [1, 1, 1, 1]


def test_next_hint_is_shell_quoted(dataset, tmp_path, cli, module):
    pred = tmp_path / "my preds é"
    res = cli("predict", dataset, "-m", f"python:{module}:predict", "--kind", "disp",
              "-o", pred, "--variants", "clean")
    assert res.exit_code == 0, res.output
    hint = [line for line in res.output.splitlines() if line.startswith("next: ")][0]
    assert shlex.split(hint[len("next: "):]) == ["robodepth", "evaluate", str(dataset),
                                                 "--pred", str(pred)]


def test_text_file_as_checkpoint_gives_no_unsafe_advice(dataset, tmp_path, cli):
    folder = tmp_path / "ckpt"
    folder.mkdir()
    (folder / "depth.pth").write_text("x")
    for text in ("hello", "not a checkpoint", ""):
        (folder / "encoder.pth").write_text(text)
        res = cli("predict", dataset, "-m", f"monodepth2:{folder}", "-o", tmp_path / "P")
        assert res.exit_code == 2, res.output
        assert len(res.output.strip().splitlines()) == 1, res.output
        assert f"{folder / 'encoder.pth'}: not a PyTorch checkpoint of tensors" in res.output
        assert "weights_only" not in res.output and "False" not in res.output


def test_mistyped_hf_folder_is_named_as_a_missing_folder(dataset, tmp_path, cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for arg in ("nonexistent_dir", "models/a/dpt", "./dpt", "dpt/"):
        res = cli("predict", dataset, "-m", f"hf:{arg}", "-o", tmp_path / "P")
        assert res.exit_code == 2, res.output
        assert f"hf:{arg}: no folder {arg} (from {tmp_path})" in res.output, res.output
        assert "hf download" not in res.output
