"""evaluate and score with decimal levels and chains: extra rows, kept out of mCE/mRR (issue 23)."""

from __future__ import annotations

from robodepth_cli.evaluation.csvrows import ResultsTable

import csv
import json

import numpy as np
import pytest

from robodepth_cli.api import open_dataset
from robodepth_cli.benchmark_facts import BENCHMARKS
from robodepth_cli.evaluation.results import ScoreError, parse_results
from robodepth_cli.evaluation.scores import score

from tests.helpers.evaluation import GT_SHAPES, fake_disp, lidar_gt

KITTI = BENCHMARKS["kitti-c"]


@pytest.fixture(scope="module")
def built(fixtures_dir, tmp_path_factory, cli):
    out = tmp_path_factory.mktemp("kitti") / "KITTI_C"
    res = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split",
              fixtures_dir / "kitti_split.txt", "--out", out, "--size", "64x96", "--corruptions",
              "brightness", "--levels", "1,2.5", "--compose", "contrast:2+pixelate:1.5", "--jobs", "1")
    assert res.exit_code == 0, res.output
    gts = np.empty(2, object)
    for i, shape in enumerate(GT_SHAPES):
        gts[i] = lidar_gt(shape, i)
    np.savez_compressed(out / "gt_depths.npz", data=gts)
    pred = out.parent / "PRED"
    for k, v in enumerate(open_dataset(out).variants()):
        v.save_predictions(pred, np.stack([fake_disp((64, 96), i, 0.05 * (1 + k)) for i in range(2)]))
    return out, pred


def test_evaluate_writes_decimal_and_chain_rows_and_score_keeps_them_apart(built, tmp_path, cli):
    out, pred = built
    assert (pred / "brightness" / "2.5.npy").is_file() and (pred / "contrast-2+pixelate-1.5.npy").is_file()
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--score")
    assert res.exit_code == 0, res.output
    with open(tmp_path / "r.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["corruption"], r["level"]) for r in rows] == [
        ("clean", "0"), ("brightness", "1"), ("brightness", "2.5"), ("contrast:2+pixelate:1.5", "0")]
    dee = {(r["corruption"], r["level"]): (float(r["abs_rel"]) - float(r["a1"]) + 1) / 2 for r in rows}
    assert "Beyond the benchmark (not in mCE, mRR or mDEE)" in res.stdout
    assert f"brightness  1: {dee['brightness', '1']:.3f}  2.5: {dee['brightness', '2.5']:.3f}" in res.stdout
    assert f"contrast:2+pixelate:1.5  {dee['contrast:2+pixelate:1.5', '0']:.3f}" in res.stdout
    # mCE: brightness at its integer level only (the published baseline, partial)
    doc = json.loads(cli("score", tmp_path / "r.csv", "-b", "kitti-c", "--allow-partial", "--json").stdout)
    assert doc["mce"] == pytest.approx(100 * dee["brightness", "1"] / KITTI.baseline.dee["brightness"])
    assert doc["corruptions"]["brightness"]["levels"] == {"1": pytest.approx(dee["brightness", "1"])}
    assert doc["beyond_benchmark"] == {
        "severity_curves": {"brightness": {"1": pytest.approx(dee["brightness", "1"]),
                                           "2.5": pytest.approx(dee["brightness", "2.5"])}},
        "chains": {"contrast:2+pixelate:1.5": pytest.approx(dee["contrast:2+pixelate:1.5", "0"])}}


def full_csv(extra: str = "") -> str:
    lines = ["corruption,level,dee", "clean,0,0.1"]
    lines += [f"{n},{lv},{0.1 + 0.01 * lv + 0.001 * i}" for i, n in enumerate(KITTI.corruptions) for lv in range(1, 6)]
    return "\n".join(lines) + "\n" + extra


def test_extra_rows_change_no_benchmark_score():
    plain = score(parse_results(ResultsTable.parse(full_csv(), "r.csv"), KITTI), KITTI)
    extra = score(parse_results(ResultsTable.parse(full_csv("fog,2.5,0.5\nfog,1.25,0.45\nfog:3 + snow:2,0,0.6\ndark:1+contrast:5,,0.7\n"),
                                                    "r.csv"), KITTI), KITTI)
    assert (extra.overall, extra.categories, extra.corruptions) == (plain.overall, plain.categories, plain.corruptions)
    assert list(extra.curves) == ["fog"]
    assert list(extra.curves["fog"].items()) == [(1, pytest.approx(0.112)), (1.25, 0.45),
                                                  (2, pytest.approx(0.122)), (2.5, 0.5), (3, pytest.approx(0.132)),
                                                  (4, pytest.approx(0.142)), (5, pytest.approx(0.152))]
    assert extra.chains == {"dark:1+contrast:5": 0.7, "fog:3+snow:2": 0.6}


@pytest.mark.parametrize("extra,message", [
    ("fog,5.5,0.5\n", "level 5.5 of fog is outside 1..5 for kitti-c"),
    ("fog,2.5,0.5\nfog,2.50,0.4\n", "duplicate row for fog level 2.5"),
    ("fog:3+,0,0.5\n", "chain 'fog:3+': step 2 is empty"),
    ("fog:3+snow:2,2,0.5\n", "a chain's row has level 0 (its levels are in its name), not '2'"),
    ("fog:3+snow:2,0,0.5\nfog:3.0+snow:2,0,0.5\n", "duplicate row for chain fog:3+snow:2"),
])
def test_bad_extra_rows(extra, message):
    with pytest.raises(ScoreError) as info:
        parse_results(ResultsTable.parse(full_csv(extra), "r.csv"), KITTI)
    assert message in str(info.value)


def test_nyu_chains_keep_nyus_corruptions():
    nyu = BENCHMARKS["nyudepth2-c"]
    text = "corruption,level,dee\nclean,0,0.1\ndark,1,0.2\nfog:1+dark:2,0,0.4\n"
    with pytest.raises(ScoreError, match="chain fog:1\\+dark:2: fog is not a corruption of nyudepth2-c"):
        parse_results(ResultsTable.parse(text, "r.csv"), nyu)


@pytest.fixture(scope="module")
def chains_only(fixtures_dir, tmp_path_factory, cli):
    """The documented chain-set workflow: a build from configs/protocols/chains.yaml (no
    single corruption), predictions for it, its results CSV."""
    from robodepth_cli.files import data_dir

    tmp = tmp_path_factory.mktemp("chains")
    out = tmp / "KITTI_CHAINS"
    res = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split",
              fixtures_dir / "kitti_split.txt", "--out", out, "--size", "64x96",
              "--config", data_dir("configs") / "protocols" / "chains.yaml", "--jobs", "1")
    assert res.exit_code == 0, res.output
    gts = np.empty(2, object)
    for i, shape in enumerate(GT_SHAPES):
        gts[i] = lidar_gt(shape, i)
    np.savez_compressed(out / "gt_depths.npz", data=gts)
    pred = tmp / "PRED"
    for k, v in enumerate(open_dataset(out).variants()):
        v.save_predictions(pred, np.stack([fake_disp((64, 96), i, 0.05 * (1 + k)) for i in range(2)]))
    return out, pred, tmp


@pytest.mark.slow
def test_chains_only_build_is_evaluated_and_scored(chains_only, cli):
    """evaluate --score and score show the metrics and every chain's DEE, with a note
    saying why there is no mCE; nothing is refused (issue 26 item 9)."""
    out, pred, tmp = chains_only
    csv_path = tmp / "chains.csv"
    res = cli("evaluate", out, "--pred", pred, "--out", csv_path, "--score")
    assert res.exit_code == 0, res.output
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 9 and rows[0]["corruption"] == "clean"
    dee = {r["corruption"]: (float(r["abs_rel"]) - float(r["a1"]) + 1) / 2 for r in rows}
    assert "abs_rel" in res.stdout  # the metrics
    assert "no mCE, mRR or mDEE: they are defined on kitti-c's corruptions at its integer levels 1..5" in res.stdout
    assert "Beyond the benchmark (not in mCE, mRR or mDEE)" in res.stdout
    assert "dark:2+gaussian_noise:2" in res.stdout and f"{dee['dark:2+gaussian_noise:2']:.3f}" in res.stdout
    assert "warning" not in res.output and "missing" not in res.output
    score = cli("score", csv_path)
    assert score.exit_code == 0, score.output
    assert "no mCE, mRR or mDEE" in score.stdout and "mCE n/a" not in score.stdout
    doc = json.loads(cli("score", csv_path, "--json").stdout)
    assert doc["mce"] is None and doc["partial"] is False and doc["missing"] == []
    assert doc["note"].startswith("no mCE, mRR or mDEE")
    assert doc["beyond_benchmark"]["chains"] == {c: pytest.approx(d) for c, d in dee.items() if c != "clean"}
    plot = cli("score", csv_path, "--plot", tmp / "ce.png")
    assert plot.exit_code == 2 and "no CE to draw" in plot.output and not (tmp / "ce.png").exists()


def test_chains_only_results_are_reported(chains_only, cli):
    """report shows the clean DEE and each chain's DEE, with the note, and no figure that
    needs a benchmark score; mixing such a file with a benchmark one is refused."""
    pytest.importorskip("matplotlib")
    from tests.helpers.report import evaluate_csv

    out, pred, tmp = chains_only
    csv_path = tmp / "chains-r.csv"
    assert cli("evaluate", out, "--pred", pred, "--out", csv_path).exit_code == 0
    rep = tmp / "report"
    res = cli("report", csv_path, "--out", rep)
    assert res.exit_code == 0, res.output
    doc = json.loads((rep / "scores.json").read_text())
    assert doc["note"].startswith("no mCE, mRR or mDEE") and "baseline" not in doc
    chains = json.loads(cli("score", csv_path, "--json").stdout)["beyond_benchmark"]["chains"]
    assert doc["models"][0]["beyond_benchmark"]["chains"] == chains and len(chains) == 8
    assert "mce" not in doc["models"][0].get("scores", {})
    page = (rep / "index.html").read_text()
    assert "No mCE, mRR or mDEE: they are defined on" in page
    assert "frost:2 + defocus blur:1.5" in page and f"{chains['frost:2+defocus_blur:1.5']:.3f}" in page
    assert sorted(p.name for p in (rep / "figures").iterdir()) == []
    md = (rep / "table.md").read_text()
    assert "frost:2 + defocus blur:1.5" in md and "No mCE, mRR or mDEE" in md
    full = evaluate_csv(tmp / "full.csv", "kitti-c", "MonoViT")
    res = cli("report", full, csv_path, "--out", tmp / "mixed")
    assert res.exit_code == 2 and "has rows beyond the benchmark only" in res.output
