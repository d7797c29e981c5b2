"""`robodepth report` on several datasets: synthetic against real (rank correlations with a
bootstrap interval, the pairs table, the scatter) and a table per dataset with one across
them. Rank correlations are checked against scipy's and against values worked out by hand."""

from __future__ import annotations

from tests.helpers.report import tables as _tables

import json
from pathlib import Path

import numpy as np
import pytest

from robodepth_cli.errors import RobodepthError
from robodepth_cli.evaluation import ranking as K
from robodepth_cli.report import synreal as X
from tests.helpers.messages import one_line_error
from tests.helpers.report import evaluate_csv, figure_texts, no_overlap, page_tables

MODELS = ("MonoViT", "Lite-Mono Large", "DIFFNet", "CADepth", "MonoDepth2 R18")
NAMES = ("A", "B", "C", "D", "E")
# The published KITTI-C fog DEE of MODELS (level means; evaluate_csv keeps them):
FOG = (0.116, 0.126, 0.131, 0.142, 0.155)  # ranks 1 2 3 4 5
# Real foggy DEE given to them: ranks 1 4 2 5 3.
FOGGY = (0.100, 0.145, 0.115, 0.160, 0.130)
# By hand: d = rank differences 0, -2, 1, -1, 2 -> sum d^2 = 10, rho = 1 - 6 * 10 / (5 * 24)
RHO = 0.5
# Of the 10 pairs of models, discordant: (B,C) (B,E) (D,E) -> tau = (7 - 3) / 10
TAU = 0.4


def test_rank_correlations_by_hand_and_against_scipy():
    assert K.spearman(FOG, FOGGY) == pytest.approx(RHO)
    assert K.kendall(FOG, FOGGY) == pytest.approx(TAU)
    assert K.spearman([1, 2, 3], [30, 20, 10]) == pytest.approx(-1.0)
    # Ties share their mean rank: x ranks 1.5 1.5 3 against 1 2 3 -> 1.5 / sqrt(1.5 * 2)
    assert K.spearman([5, 5, 7], [1, 2, 3]) == pytest.approx(1.5 / 3 ** 0.5)
    assert np.isnan(K.spearman([1, 1, 1], [1, 2, 3])) and np.isnan(K.kendall([1, 1, 1], [1, 2, 3]))
    rng = np.random.default_rng(5)
    for n in (4, 7, 12):
        x, y = rng.integers(0, 5, n).astype(float), rng.integers(0, 5, n).astype(float)  # ties
        assert K.spearman(x, y) == pytest.approx(_rho_by_definition(x, y), abs=1e-12)
        assert K.kendall(x, y) == pytest.approx(_tau_b_by_definition(x, y), abs=1e-12)


def _mean_ranks(x) -> list[float]:
    """1-based ranks, a tie sharing the mean of the ranks it spans: the value's rank is
    (number of smaller values) + (number of equal values + 1) / 2."""
    return [sum(v < u for v in x) + (sum(v == u for v in x) + 1) / 2 for u in x]


def _rho_by_definition(x, y) -> float:
    """Spearman's rho: the Pearson correlation of the mean ranks."""
    rx, ry = _mean_ranks([float(v) for v in x]), _mean_ranks([float(v) for v in y])
    mx, my = sum(rx) / len(rx), sum(ry) / len(ry)
    cov = sum((a - mx) * (b - my) for a, b in zip(rx, ry))
    return cov / (sum((a - mx) ** 2 for a in rx) * sum((b - my) ** 2 for b in ry)) ** 0.5


def _tau_b_by_definition(x, y) -> float:
    """Kendall's tau-b: (concordant - discordant) / sqrt((n0 - tx) (n0 - ty)), n0 all pairs,
    tx and ty the pairs tied in x and in y."""
    x, y = [float(v) for v in x], [float(v) for v in y]
    pairs = [(i, j) for i in range(len(x)) for j in range(i + 1, len(x))]
    sign = [((x[i] > x[j]) - (x[i] < x[j])) * ((y[i] > y[j]) - (y[i] < y[j])) for i, j in pairs]
    untied_x = sum(x[i] != x[j] for i, j in pairs)
    untied_y = sum(y[i] != y[j] for i, j in pairs)
    return sum(sign) / (untied_x * untied_y) ** 0.5


def test_bootstrap_is_seeded_and_holds_the_estimate():
    ci = K.bootstrap(FOG, FOGGY, n=500, seed=3)
    assert ci == K.bootstrap(FOG, FOGGY, n=500, seed=3)
    assert ci != K.bootstrap(FOG, FOGGY, n=500, seed=4)
    assert -1 <= ci["spearman"][0] <= RHO <= ci["spearman"][1] <= 1
    assert -1 <= ci["kendall"][0] <= TAU <= ci["kendall"][1] <= 1
    # Any resample of a perfect agreement agrees perfectly.
    perfect = K.bootstrap(FOG, FOG, n=200)
    assert perfect["spearman"] == pytest.approx((1.0, 1.0)) and perfect["kendall"] == pytest.approx((1.0, 1.0))


def test_pairs_tables(tmp_path):
    shipped = X.read_pairs([X.PAIRS])
    assert X.Pair(("kitti-c", ""), "fog", ("drivingstereo-c", "foggy")) in shipped
    mine = tmp_path / "mine.csv"
    mine.write_text("# my night set\nsynthetic,corruption,real\nkitti-c, Dark ,custom:night\n"
                    "drivingstereo-c:sunny,fog,drivingstereo-c:foggy\n")
    pairs = X.read_pairs([X.PAIRS, mine])
    assert pairs[:len(shipped)] == shipped  # a pair in both is listed once
    assert pairs[-1] == X.Pair(("drivingstereo-c", "sunny"), "fog", ("drivingstereo-c", "foggy"))
    bad = tmp_path / "bad.csv"
    bad.write_text("synthetic,corruption,real\nkitti-c,haze,custom:night\n")
    with pytest.raises(RobodepthError, match=r"bad.csv:2: unknown corruption 'haze'"):
        X.read_pairs([bad])
    bad.write_text("a,b,c\n")
    with pytest.raises(RobodepthError, match="header must be synthetic,corruption,real"):
        X.read_pairs([bad])


def page_text(path: Path, table: str) -> str:
    """The text of the page's table ``table`` (headers included)."""
    import re

    html = path.read_text(encoding="utf-8")
    body = re.search(rf'<table id="{table}".*?</table>', html, flags=re.S).group(0)
    return re.sub(r"<[^>]+>", " ", body).replace("&uarr;", "↑").replace("&darr;", "↓")


def _clean(path: Path, dee: float, a1: float = 0.9) -> Path:
    path.write_text(f"corruption,level,abs_rel,a1\nclean,0,{2 * dee - 1 + a1!r},{a1}\n")
    return path


def _synreal_args(tmp_path):
    args = []
    for i, (m, real) in enumerate(zip(MODELS, FOGGY)):
        args += [evaluate_csv(tmp_path / f"k{i}.csv", "kitti-c", m), _clean(tmp_path / f"f{i}.csv", real)]
    for name in NAMES:
        args += ["--name", name, "--name", name]
    for _ in NAMES:
        args += ["--on", "kitti-c", "--on", "drivingstereo-c:foggy"]
    return args


@pytest.fixture(scope="module")
def synreal_report(tmp_path_factory):
    from click.testing import CliRunner

    from robodepth_cli.cli import main

    tmp = tmp_path_factory.mktemp("synreal")
    args = [str(a) for a in _synreal_args(tmp)]
    res = CliRunner().invoke(main, ["report", *args, "--bootstrap", "300", "--out", str(tmp / "out")],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return tmp, args


def test_synthetic_against_real_in_the_report(synreal_report):
    from robodepth_cli.report import write as W

    tmp, args = synreal_report
    out = tmp / "out"
    doc = json.loads((out / "scores.json").read_text())
    (fog,) = [c for c in doc["synthetic_vs_real"] if c["synthetic"]["corruption"] == "fog"]
    assert fog["real"] == {"dataset": "drivingstereo-c", "split": "foggy"}
    assert fog["spearman"] == pytest.approx(RHO) and fog["kendall"] == pytest.approx(TAU)
    assert [fog["models"][n]["synthetic"] for n in NAMES] == pytest.approx(FOG)
    assert [fog["models"][n]["real"] for n in NAMES] == pytest.approx(FOGGY)
    ci = fog["interval"]
    assert ci["over"] == "models" and ci["resamples"] == 300 and ci["seed"] == 0
    assert ci["spearman"][0] <= RHO <= ci["spearman"][1]
    # The same seed, the same interval (as scores.json writes it); the page shows the
    # table and the figure.
    files = [Path(a) for a in args if a.endswith(".csv")]
    names = [b for a, b in zip(args, args[1:]) if a == "--name"]
    on = [b for a, b in zip(args, args[1:]) if a == "--on"]
    again = W.to_json(W.assemble(_tables(files), names, None, "all", on=on, n_boot=300))
    assert json.loads(json.dumps(again))["synthetic_vs_real"] == doc["synthetic_vs_real"]
    # By AbsRel: the files have abs_rel = 2 DEE - 1 + a1 (a1 0.85 on KITTI-C, 0.9 on foggy).
    by_abs = W.assemble(_tables(files), names, None, "all", on=on, metric="abs_rel", n_boot=100).synreal
    (fog_abs,) = [c for c in by_abs if c.pair.corruption == "fog"]
    assert fog_abs.synthetic == pytest.approx([2 * d - 0.15 for d in FOG])
    assert fog_abs.real == pytest.approx([2 * d - 0.1 for d in FOGGY])
    assert fog_abs.spearman == pytest.approx(RHO) and fog_abs.metric == "abs_rel"
    page = page_tables(out / "index.html")
    row = page.tables["synthetic-real"]["fog (kitti-c) : drivingstereo-c:foggy"]
    assert row["spearman"] == "0.50" and row["kendall"] == "0.40" and row["n"] == "5"
    assert row["spearman low"] == f"{ci['spearman'][0]:.2f}"
    assert page.tables["synthetic-real-errors"]["C"]["0 r"] == "0.115"
    html = (out / "index.html").read_text()
    assert 'id="fig-synthetic-real"' in html and "Synthetic against real" in html
    assert (out / "figures" / "synthetic-real.png").read_bytes()[:4] == b"\x89PNG"
    # The main benchmark's report is all there, and drivingstereo-c has its table.
    assert {"summary", "dataset-drivingstereo-c-foggy", "across"} <= set(page.tables)
    assert page.tables["dataset-drivingstereo-c-foggy"]["B"]["clean"] == "0.145"
    # The Markdown and LaTeX carry the agreement table too.
    assert "Synthetic against real" in (out / "table.md").read_text()
    tex = (out / "table.tex").read_text()
    assert r"\label{tab:robodepth-synthetic-real}" in tex and r"$\rho$ & 95\% low" in tex
    assert "↑" not in page_text(out / "index.html", "synthetic-real")  # pairs are no rivals


def test_synreal_figure_is_legible():
    from robodepth_cli.report import figures as F

    few = X.compare(["x", "a model with a long name"], [X.Pair(("kitti-c", ""), "fog", ("d", "s"))],
                    lambda m, k, c: {("x", True): 0.2, ("x", False): 0.3}.get((m, c is not None), 0.25))
    pairs = [X.Pair(("kitti-c", ""), "fog", ("drivingstereo-c", "foggy")),
             X.Pair(("kitti-c", ""), "contrast", ("drivingstereo-c", "foggy"))]
    values = {c: dict(zip(NAMES, v)) for c, v in (("fog", FOG), ("contrast", (0.12, 0.12, 0.121, 0.19, 0.18)),
                                                   (None, FOGGY))}
    found = X.compare(NAMES, pairs, lambda m, k, c: values[c][m], n_boot=200)
    assert few[0].spearman is None and "a ranking needs 3" in few[0].note
    for comparisons in (found, found + few):
        fig = F.synreal_figure(comparisons)
        no_overlap(fig)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        page = fig.bbox
        for ax in fig.axes:
            if not ax.get_visible():
                continue
            frame = ax.get_window_extent(renderer)
            names = {t.get_text() for t in ax.texts}
            assert set(comparisons[fig.axes.index(ax)].models) <= names  # every model named
            for t in ax.texts:  # inside its panel
                b = t.get_window_extent(renderer)
                assert frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1
        for text, b in figure_texts(fig):  # nothing clipped at the figure's edge
            assert page.x0 <= b.x0 and b.x1 <= page.x1 and page.y0 <= b.y0 and b.y1 <= page.y1, text


@pytest.mark.slow
def test_datasets_side_by_side(tmp_path, cli):
    """KITTI-C and NYUDepth2-C in one report (the rows say which), and a dataset with no
    published baseline scored against a model the user names."""
    from robodepth_cli.evaluation import results as R

    k = [evaluate_csv(tmp_path / f"k{i}.csv", "kitti-c", m) for i, m in enumerate(MODELS[:2])]
    n = [evaluate_csv(tmp_path / f"n{i}.csv", "nyudepth2-c", m) for i, m in enumerate(("BTS R50", "DPT ViT-B"))]
    res = cli("report", *k, *n, "--name", "A", "--name", "B", "--name", "A", "--name", "B",
              "--out", tmp_path / "kn")
    assert res.exit_code == 0, res.output
    page = page_tables(tmp_path / "kn" / "index.html")
    nyu = json.loads(cli("score", n[1], "--json").stdout)
    assert page.tables["dataset-nyudepth2-c"]["B"]["mCE"] == f"{nyu['mce']:.2f}"
    assert page.tables["across"]["B"]["nyudepth2-c mDEE"] == f"{nyu['mdee']:.3f}"
    assert page.tables["across"]["A"]["kitti-c clean"] == page.tables["summary"]["A"]["clean"]
    # drivingstereo-c with corruption rows: a fog 1-2 and a dark 1-2 row per model.
    rows = {"A": (0.10, 0.20, 0.22, 0.30, 0.34), "B": (0.12, 0.30, 0.36, 0.33, 0.39)}
    files = []
    for m, (clean, f1, f2, d1, d2) in rows.items():
        p = tmp_path / f"ds_{m}.csv"
        p.write_text("corruption,level,dee\n" + f"clean,0,{clean}\nfog,1,{f1}\nfog,2,{f2}\n"
                     f"dark,1,{d1}\ndark,2,{d2}\n")
        files.append(p)
    args = [*files, "--name", "A", "--name", "B", "--on", "drivingstereo-c:sunny"]
    res = cli("report", *args, "--out", tmp_path / "ds")
    assert res.exit_code == 0, res.output
    tables = page_tables(tmp_path / "ds" / "index.html").tables
    assert "across" not in tables  # one dataset
    table = tables["dataset-drivingstereo-c-sunny"]
    assert "mCE" not in table["B"] and "abs_rel" not in table["B"]  # no baseline; DEE alone
    # B: fog mean 0.33, dark 0.36 -> mDEE 0.345; RR fog (1-.30 + 1-.36)/2/(1-.12), dark likewise
    assert table["B"]["mDEE"] == "0.345"
    rr = (R.resilience_rate([0.30, 0.36], 0.12) + R.resilience_rate([0.33, 0.39], 0.12)) / 2
    assert table["B"]["mRR"] == f"{rr:.2f}"
    res = cli("report", *args, "--baseline", "A", "--out", tmp_path / "dsb")
    assert res.exit_code == 0, res.output
    table = page_tables(tmp_path / "dsb" / "index.html").tables["dataset-drivingstereo-c-sunny"]
    # CE against A: fog 100 * 0.33 / 0.21, dark 100 * 0.36 / 0.32; A itself 100.
    assert table["A"]["mCE"] == "100.00"
    assert table["B"]["mCE"] == f"{(100 * 0.33 / 0.21 + 100 * 0.36 / 0.32) / 2:.2f}"
    doc = json.loads((tmp_path / "dsb" / "scores.json").read_text())
    assert doc["benchmark"] is None and doc["models"] == []
    (sec,) = doc["datasets"]
    assert (sec["dataset"], sec["split"]) == ("drivingstereo-c", "sunny")
    assert sec["models"][1]["scores"]["baseline"] == "A"


def _named(path: Path, dataset: str, split: str = "") -> Path:
    """``path`` with the dataset and split columns robodepth evaluate writes."""
    lines = path.read_text().splitlines()
    path.write_text("\n".join([lines[0] + ",dataset,split"] + [f"{ln},{dataset},{split}" for ln in lines[1:]])
                    + "\n")
    return path


def test_results_that_name_their_dataset_need_no_on(tmp_path, cli):
    """Six models on KITTI-C and six on DrivingStereo foggy, each file saying which (as
    evaluate writes them): no --on at all; --on still names a file that says nothing, and
    one that contradicts its file is refused."""
    args = []
    for i, (m, real) in enumerate(zip(MODELS, FOGGY)):
        args += [_named(evaluate_csv(tmp_path / f"k{i}.csv", "kitti-c", m), "kitti-c"),
                 _named(_clean(tmp_path / f"f{i}.csv", real), "drivingstereo-c", "foggy")]
    for name in NAMES:
        args += ["--name", name, "--name", name]
    res = cli("report", *args, "--bootstrap", "100", "--out", tmp_path / "out")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "out" / "scores.json").read_text())
    assert [(d["dataset"], d["split"]) for d in doc["datasets"]] == [("drivingstereo-c", "foggy")]
    assert "drivingstereo-c:foggy" in res.output
    old = _clean(tmp_path / "old.csv", 0.1)  # results from elsewhere: no dataset column
    res = cli("report", args[0], old, "--name", "A", "--name", "A", "--on", "kitti-c",
              "--on", "drivingstereo-c:foggy", "--bootstrap", "100", "--out", tmp_path / "out2")
    assert res.exit_code == 0, res.output
    one_line_error(cli("report", args[1], "--on", "drivingstereo-c:rainy", "--out", tmp_path / "o3"),
                    "--on drivingstereo-c:rainy: " + str(args[1]) + " says its results are on drivingstereo-c:foggy")
    mixed = tmp_path / "mixed.csv"
    mixed.write_text(args[1].read_text() + "fog,1,0.2,0.9,kitti-c,\n")
    one_line_error(cli("score", mixed), "rows are on different datasets (drivingstereo-c:foggy, kitti-c)")


def test_refusals(tmp_path, cli):
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    f = _clean(tmp_path / "f.csv", 0.1)
    out = tmp_path / "out"
    one_line_error(cli("report", k, f, "--out", out), "name it with --on DATASET[:SPLIT]")
    one_line_error(cli("report", k, f, "--on", "kitti-c", "--on", "a", "--on", "b", "--out", out),
                    "--on given 3 times for 2 results files")
    one_line_error(cli("report", k, f, "--on", "kitti-c", "--on", "x:foggy", "--baseline", "nobody",
                        "--out", out), "--baseline 'nobody': no results file has that model name")
    one_line_error(cli("report", k, "--baseline", "k", "--out", out), "has a published baseline")
    bad = tmp_path / "pairs.csv"
    bad.write_text("synthetic,corruption\n")
    one_line_error(cli("report", k, f, "--on", "kitti-c", "--on", "x:foggy", "--pairs", bad,
                        "--out", out), "header must be synthetic,corruption,real")
    g = tmp_path / "g.csv"
    g.write_text("corruption,level,dee\nfog,1,0.2\n")
    one_line_error(cli("report", g, "--on", "x", "--out", out), "no clean row")
    g.write_text("corruption,level,dee\nclean,0,0.1\nfog,0,0.2\n")
    one_line_error(cli("report", g, "--on", "x", "--out", out), "corruption levels start at 1")
    g.write_text("corruption,level,dee\nclean,0,0.1\nfog,1,0.2\n")
    one_line_error(cli("report", g, f, "--name", "g", "--name", "f", "--on", "x", "--baseline", "f",
                        "--out", out), "--baseline f: has no results with corruption rows on x")
    one_line_error(cli("report", k, f, "--on", "kitti-c", "--on", "x:foggy", "--dataset", tmp_path,
                        "--pred", tmp_path, "--pred", tmp_path, "--out", out),
                    "--pred given 2 times for 1 results file on kitti-c")
    one_line_error(cli("report", f, "--on", "x:foggy", "--pred", tmp_path, "--out", out),
                    "--pred needs --dataset")
    missing = cli("report", tmp_path / "nope.csv", "--out", out)
    one_line_error(missing, "cannot read")
    assert "--on" not in missing.output
    assert not out.exists()
