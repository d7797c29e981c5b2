"""A dataset is its spec (robodepth_cli.sources.datasets.DATASETS): a new one declared here
builds, evaluates and scores with no other change to the package, and the preset files of
configs/ say what the specs say."""

from __future__ import annotations

import csv
from dataclasses import replace

import pytest

from robodepth_cli.building.config import CONFIG_DIR, load_yaml, resolve
from robodepth_cli.sources import datasets
from robodepth_cli.sources.datasets import DATASETS, Dataset
from tests.helpers.paths import FIXTURES
from tests.helpers.trees import expected_paths, fixture_kitti_with_scans, tree

# A KITTI-like set of its own: the Eigen split format, two corruptions at two levels, a
# smaller size, no published baseline.
TINY = Dataset("tiny-c", "eigen", size="96x320", corruptions=("fog", "gaussian_noise"), n_levels=2)
FRAMES = (69, 54)  # the fixture split's frames
# A model that ignores the image: 10 m everywhere.
MODEL = '''
import numpy as np

def ten_metres(images):
    return np.full(images.shape[:3], 10.0, np.float32)
'''


@pytest.fixture
def tiny(monkeypatch):
    """TINY registered as a dataset for one test."""
    monkeypatch.setitem(DATASETS, TINY.name, TINY)
    return TINY


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_a_new_spec_builds_evaluates_and_scores(tiny, tmp_path, cli):
    root, split = fixture_kitti_with_scans(tmp_path), FIXTURES / "kitti_split.txt"
    out = tmp_path / "tiny"
    res = cli("build", "tiny-c", "--root", root, "--split", split, "--out", out, "--jobs", 1)
    assert res.exit_code == 0, res.output
    keys = [f"kitti_data/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/{f:010d}.png" for f in FRAMES]
    # 'all' is the spec's two corruptions, at its two levels
    built = {p for p in tree(out) if not p.startswith("gt")}
    assert built == expected_paths(keys, ["fog", "gaussian_noise"], [1, 2])
    assert cli("verify", out).exit_code == 0
    (tmp_path / "m.py").write_text(MODEL)
    pred = tmp_path / "P"
    res = cli("predict", out, "-m", f"python:{tmp_path / 'm.py'}:ten_metres", "--kind", "depth",
              "--metric", "-o", pred)
    assert res.exit_code == 0, res.output
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--score")
    assert res.exit_code == 0 and "mCE n/a" in res.output, res.output
    rows = _rows(tmp_path / "r.csv")
    assert [(r["corruption"], r["level"]) for r in rows] == [
        ("clean", "0"), ("fog", "1"), ("fog", "2"), ("gaussian_noise", "1"), ("gaussian_noise", "2")]

    # The same frames built as kitti-c (the same split format and protocol) evaluate the same.
    ref = tmp_path / "ref"
    res = cli("build", "kitti-c", "--root", root, "--split", split, "--out", ref, "--size", "96x320",
              "--corruptions", "fog,gaussian_noise", "--levels", "1,2", "--jobs", 1)
    assert res.exit_code == 0, res.output
    res = cli("evaluate", ref, "--pred", pred, "--out", tmp_path / "ref.csv")
    assert res.exit_code == 0, res.output
    ref_rows = _rows(tmp_path / "ref.csv")
    assert [{k: v for k, v in r.items() if k != "dataset"} for r in rows] == \
        [{k: v for k, v in r.items() if k != "dataset"} for r in ref_rows]

    # No published baseline: DEE and RR only, or CE against a baseline CSV
    assert tiny.name in datasets.unpublished()
    res = cli("score", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    assert "baseline: none" in res.output and "mCE n/a" in res.output
    res = cli("score", tmp_path / "r.csv", "--baseline", tmp_path / "r.csv")
    assert res.exit_code == 0 and "mCE 100.00" in res.output, res.output


def test_a_new_spec_refuses_what_it_does_not_have(tiny, tmp_path, cli):
    res = cli("build", "tiny-c", "--root", tmp_path, "--out", tmp_path / "o", "--levels", "3")
    assert res.exit_code == 2 and "tiny-c" in res.output and "3" in res.output, res.output
    res = cli("build", "tiny-c", "--root", tmp_path, "--out", tmp_path / "o", "--corruptions", "snow")
    assert res.exit_code == 2 and "tiny-c has no corruption 'snow'; valid: fog, gaussian_noise" in res.output


@pytest.mark.parametrize("path", sorted(CONFIG_DIR.glob("*.yaml")), ids=lambda p: p.stem)
def test_each_preset_file_says_what_its_spec_says(path, monkeypatch):
    """configs/NAME.yaml, for the user to read, resolves to what the spec of its dataset
    makes (another preset of a dataset, kitti-c-hr, is listed by it and differs in size)."""
    name = path.stem
    ds = DATASETS[load_yaml(path)["dataset"]]
    assert name == ds.name or name in ds.presets
    from_file = resolve(name)
    monkeypatch.setitem(DATASETS, "spec-only", replace(ds, name="spec-only"))
    from_spec = resolve("spec-only")
    if name != ds.name:  # kitti-c-hr: its own size
        from_spec = replace(from_spec, size=from_file.size)
    assert replace(from_spec, preset=name, dataset=ds.name) == from_file


def test_only_the_benchmarks_have_a_published_baseline():
    from robodepth_cli.benchmark_facts import BENCHMARKS

    assert {n for n, d in DATASETS.items() if d.baseline is not None} == set(BENCHMARKS)
    assert all(DATASETS[n].baseline == b.baseline and DATASETS[n].corruptions == b.corruptions
               and DATASETS[n].n_levels == b.n_levels for n, b in BENCHMARKS.items())
