"""`robodepth report`'s further analyses: mCE against size, variants that differ in one
property (modality, pre-training, resolution), the fine-tuning matrix.

Expected values are computed here from the inputs: the published per-corruption DEE divided
by the baseline's (CE), the results' abs_rel averaged over the levels, the counts given.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from tests.helpers.messages import one_line_error
from tests.helpers.report import evaluate_csv, no_overlap, published_rows


def _with_size(path: Path, params: int, flops: int) -> Path:
    """The results as `evaluate` writes them from a predictions.json with a size."""
    lines = path.read_text().splitlines()
    path.write_text("\n".join([lines[0] + ",params,flops"]
                              + [f"{line},{params},{flops}" for line in lines[1:]]) + "\n")
    return path


def _assemble(files, names, **kw):
    from robodepth_cli.report import write as W
    from robodepth_cli.report.analyses import add

    from robodepth_cli.evaluation.csvrows import ResultsTable

    report = W.assemble([ResultsTable.read(f) for f in files], names, None, "all")
    before = len(report.figures)
    add(report, **kw)
    return {stem: fig for stem, _, _, fig in report.figures[before:]}


def _published_ce(model: str) -> dict[str, float]:
    rows = {r["model"]: r for r in published_rows("kitti-c")}
    from robodepth_cli.benchmark_facts import BENCHMARKS

    names = BENCHMARKS["kitti-c"].corruptions
    return {c: 100 * float(rows[model][c]) / float(rows["MonoDepth2 R18"][c]) for c in names}


def _mce(model: str) -> float:
    ce = _published_ce(model)
    return sum(ce.values()) / len(ce)


# --------------------------------------------------------------------------- size

def test_size_points_from_results_flags_and_the_sizes_file(tmp_path):
    a = _with_size(evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT"), 27_900_000, 32_000_000_000)
    b = evaluate_csv(tmp_path / "b.csv", "kitti-c", "DNet R18")
    sizes = tmp_path / "sizes.csv"
    sizes.write_text("# sizes of the paper's models, from their papers\nmodel,params,flops\n"
                     "MonoDepth2 R18,14.3M,16G\nLite-Mono Large,8.7M,\n")
    figs = _assemble([a, b], ["A", "B"], params=["B=20M"], flops=["A=40G"], sizes=sizes)
    fig = figs["size"]
    left, right = fig.axes[:2]

    def points(ax):
        return sorted((round(float(x), 6), round(float(y), 4)) for c in ax.collections
                      for x, y in c.get_offsets())
    # A: params from its results, FLOPs from --flops (over its results' 32G); B: --params only
    assert points(left) == sorted([(27.9, round(_mce("MonoViT"), 4)), (20.0, round(_mce("DNet R18"), 4)),
                                   (14.3, 100.0), (8.7, round(_mce("Lite-Mono Large"), 4))])
    assert points(right) == sorted([(40.0, round(_mce("MonoViT"), 4)), (16.0, 100.0)])
    assert left.get_xscale() == right.get_xscale() == "log"
    no_overlap(fig)


def test_no_size_no_figure_and_the_page_says_nothing(tmp_path, cli):
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT")
    res = cli("report", a, "--out", tmp_path / "out")
    assert res.exit_code == 0, res.output
    page = (tmp_path / "out" / "index.html").read_text()
    for stem in ("size", "groups-modality", "finetune"):
        assert f"fig-{stem}" not in page
        assert not (tmp_path / "out" / "figures" / f"{stem}.png").exists()
    assert "FLOPs" not in page and "fine-tun" not in page.lower()
    res = cli("report", a, "--params", "a=10M", "--out", tmp_path / "out2")
    assert res.exit_code == 0, res.output
    assert 'id="fig-size"' in (tmp_path / "out2" / "index.html").read_text()


@pytest.mark.parametrize("flags,message", [
    (["--params", "nobody=3M"], "--params 'nobody=3M': no model is named 'nobody'"),
    (["--params", "a=lots"], "'lots' is not a count"),
    (["--flops", "a=-4G"], "must be a positive finite number"),
    (["--flops", "a"], "expected MODEL=COUNT"),
    (["--tag", "a:colour=red"], "unknown key 'colour'"),
    (["--tag", "b:modality=Mono"], "no model is named 'b'"),
    (["--tag", "a:modality"], "expected MODEL:KEY=VALUE"),
    (["--tag", "a:modality=Mono,pretrain"], "expected KEY=VALUE, got 'pretrain'"),
    (["--tag", "a:finetune=sunshine"], "a:finetune=sunshine: not a corruption of kitti-c"),
])
def test_bad_flags_are_one_line_refusals(tmp_path, cli, flags, message):
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT")
    res = cli("report", a, *flags, "--out", tmp_path / "out")
    one_line_error(res, message)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text,message", [
    ("name,params\nx,1\n", ":1: the header must be model,params,flops"),
    ("model,params,flops\nNo Such Model,1M,1G\n", ":2: no model of the report is named 'No Such Model'"),
    ("model,params,flops\nMonoViT,1M\n", ":2: expected three cells"),
    ("model,params,flops\nMonoViT,nan,1G\n", "'nan' is not a count"),
    ("", "no header row"),
])
def test_bad_sizes_files_are_refused_naming_the_line(tmp_path, cli, text, message):
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT")
    (tmp_path / "s.csv").write_text(text)
    res = cli("report", a, "--sizes", tmp_path / "s.csv", "--out", tmp_path / "out")
    one_line_error(res, message)


# --------------------------------------------------------------------------- groups

def _bars(ax) -> dict[str, list[float]]:
    """Each legend entry's bar heights, in corruption order."""
    handles, labels = ax.get_legend_handles_labels()
    return {lab: [p.get_height() for p in h.patches] for h, lab in zip(handles, labels)}


def test_published_alone_reproduce_the_modality_comparison(tmp_path):
    """With --groups all and no tag, the paper's MonoDepth2 R18 in Mono, Stereo and M+S is
    one panel: bars are the published DEE over the baseline's."""
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "DNet R18")
    figs = _assemble([a], ["A"], groups="all")
    assert {"groups-modality", "groups-pretrain", "groups-resolution"} <= set(figs)
    panel = next(ax for ax in figs["groups-modality"].axes
                 if ax.get_title(loc="left") == "MonoDepth2 (ResNet-18, 640 x 192, ImageNet)")
    bars = _bars(panel)
    want = {"Mono": "MonoDepth2 R18", "Stereo": "MonoDepth2 R18 (stereo)",
            "M+S": "MonoDepth2 R18 (mono+stereo)"}
    assert [lab.split(":")[0] for lab in bars] == list(want)
    for label, heights in bars.items():
        ce = _published_ce(want[label.split(":")[0]])
        assert heights == pytest.approx(list(ce.values()), rel=1e-9)
        assert f"(mCE {_mce(want[label.split(':')[0]]):.1f})" in label
    # pre-training: MonoDepth2 R18 (ImageNet) against nopt (None), Mono, the rest equal
    titles = [ax.get_title(loc="left") for ax in figs["groups-pretrain"].axes]
    assert "MonoDepth2 (Mono, ResNet-18, 640 x 192)" in titles
    for fig in figs.values():
        no_overlap(fig)


def test_your_tagged_variants_make_a_group_and_untagged_none(tmp_path):
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT")
    b = evaluate_csv(tmp_path / "b.csv", "kitti-c", "MonoViT (mono+stereo)")
    assert _assemble([a, b], ["Ours", "Ours MS"]) == {}  # no tag, --groups yours: nothing
    figs = _assemble([a, b], ["Ours", "Ours MS"],
                     tags=["Ours:modality=Mono,base=Ours", "Ours MS:base=Ours", "Ours MS:modality=M+S"])
    assert set(figs) == {"groups-modality"}
    (panel,) = figs["groups-modality"].axes
    bars = _bars(panel)
    assert list(bars) == [f"Mono: Ours  (mCE {_mce('MonoViT'):.1f})",
                          f"M+S: Ours MS  (mCE {_mce('MonoViT (mono+stereo)'):.1f})"]
    assert bars[list(bars)[0]] == pytest.approx(list(_published_ce("MonoViT").values()))


# --------------------------------------------------------------------------- fine-tuning

def _abs_rel(path: Path, corruption: str) -> float:
    rows = [r for r in csv.DictReader(path.open()) if r["corruption"] == corruption]
    return sum(float(r["abs_rel"]) for r in rows) / len(rows)


def test_finetune_matrix_cells_are_the_level_means_of_abs_rel(tmp_path, cli):
    base = evaluate_csv(tmp_path / "base.csv", "kitti-c", "MonoDepth2 R18")
    fog = evaluate_csv(tmp_path / "fog.csv", "kitti-c", "MonoDepth2 HR", tilt=0.1)
    snow = evaluate_csv(tmp_path / "snow.csv", "kitti-c", "MonoDepth2 nopt")
    figs = _assemble([snow, base, fog], ["S", "B", "F"],
                     tags=["F:finetune=fog", "S:finetune=Snow"])
    from robodepth_cli.report import finetune as FT
    from robodepth_cli.report import write as W
    from robodepth_cli.report.tags import parse_tags

    from robodepth_cli.evaluation.csvrows import ResultsTable

    report = W.assemble([ResultsTable.read(f) for f in (snow, base, fog)], ["S", "B", "F"], None, "all")
    mx = FT.matrix(report.models, parse_tags(["F:finetune=fog", "S:finetune=Snow"], ["S", "B", "F"]),
                   "kitti-c")
    assert mx.rows == ("none", "fog", "snow") and mx.models == ("B", "F", "S")
    assert mx.columns[0] == "clean" and len(mx.columns) == 19
    for row, path in zip(mx.values, (base, fog, snow)):
        assert row == pytest.approx([_abs_rel(path, c) for c in mx.columns], rel=1e-12)
    fig = figs["finetune"]
    cells = [t.get_text() for t in fig.axes[0].texts]
    assert cells[:19] == [f"{v:.3f}" for v in mx.values[0]]
    # each column shaded from its lowest (lightest) to its highest (darkest)
    image = fig.axes[0].images[0].get_array()
    for j in range(len(mx.columns)):
        col = [v[j] for v in mx.values]
        light = [sum(image[i, j, :3]) for i in range(3)]
        assert light.index(max(light)) == col.index(min(col))
        assert light.index(min(light)) == col.index(max(col))
    no_overlap(fig)
    res = cli("report", base, fog, "--tag", "fog:finetune=fog", "--out", tmp_path / "out")
    assert res.exit_code == 0, res.output
    assert 'id="fig-finetune"' in (tmp_path / "out" / "index.html").read_text()


def test_finetune_refusals(tmp_path, cli):
    files = [evaluate_csv(tmp_path / f"{n}.csv", "kitti-c", m) for n, m in
             (("a", "MonoDepth2 R18"), ("b", "MonoDepth2 HR"), ("c", "DNet R18"))]
    res = cli("report", *files, "--tag", "b:finetune=fog", "--out", tmp_path / "o")
    one_line_error(res, "2 models could be the fine-tuning baseline (a, c); tag one MODEL:finetune=none")
    res = cli("report", *files, "--tag", "b:finetune=fog", "--tag", "c:finetune=fog",
              "--out", tmp_path / "o")
    one_line_error(res, "b is tagged with it too")
    dee = tmp_path / "dee.csv"
    rows = list(csv.DictReader(files[1].open()))
    dee.write_text("corruption,level,dee\n" + "".join(
        f"{r['corruption']},{r['level']},{(float(r['abs_rel']) - float(r['a1']) + 1) / 2}\n" for r in rows))
    res = cli("report", files[0], dee, "--tag", "dee:finetune=fog", "--out", tmp_path / "o")
    one_line_error(res, "dee.csv: no abs_rel column")
    assert not (tmp_path / "o").exists()
