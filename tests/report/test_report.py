"""`robodepth report`: the page, the LaTeX and Markdown tables, scores.json and the figures.

Every number the report shows is parsed back out of its files and compared with what
`robodepth score --json` prints for the same results (the user's models) or for a results
file this test writes from the paper's published per-corruption DEE (the context rows).
The results files are synthetic: the published DEE of a model spread over the levels, in
the form `robodepth evaluate` writes (abs_rel, a1 and the other metrics).
"""

from __future__ import annotations

from tests.helpers.report import tables as _tables

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.helpers.imports import imported_by_command
from tests.helpers.manifest import manifest_rows
from tests.helpers.messages import one_line_error
from tests.helpers.report import evaluate_csv, latex_tables, no_overlap, page_tables, published_csv, published_rows

def styles_csv(path: Path, model: str, shift: float = 0.0) -> Path:
    row = next(r for r in published_rows("kitti-s") if r["model"] == model)
    styles = [k for k in row if k not in ("block", "model", "mDEE")]
    lines = ["corruption,level,dee", "clean,0,0.1"]
    lines += [f"{s},0,{float(row[s]) + shift}" for s in styles]
    path.write_text("\n".join(lines) + "\n")
    return path


def score_json(cli, path, bench):
    res = cli("score", path, "--benchmark", bench, "--json")
    assert res.exit_code == 0, res.output
    return json.loads(res.output)


# --------------------------------------------------------------------------- parsing the outputs

def _unmark(cell: str) -> tuple[str, str]:
    m = re.fullmatch(r"\\(textbf|underline)\{(.*)\}", cell)
    if not m:
        return cell, ""
    return m.group(2), {"textbf": "best", "underline": "second"}[m.group(1)]


def summary_values(j: dict) -> dict[str, str]:
    """The summary row `score --json` gives, formatted as the paper prints it."""
    v = {"clean": f"{j['clean_dee']:.3f}", "mCE": f"{j['mce']:.2f}", "mRR": f"{j['mrr']:.2f}",
         "mDEE": f"{j['mdee']:.3f}"}
    for cat, g in j["categories"].items():
        v.update({f"{cat} mCE": f"{g['ce']:.2f}", f"{cat} mRR": f"{g['rr']:.2f}",
                  f"{cat} mDEE": f"{g['dee']:.3f}"})
    return v


# --------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def kitti_report(tmp_path_factory):
    """Two models on KITTI-C (named by --name) and their report."""
    from click.testing import CliRunner

    from robodepth_cli.cli import main

    tmp = tmp_path_factory.mktemp("report")
    a = evaluate_csv(tmp / "vit.csv", "kitti-c", "MonoViT")
    b = evaluate_csv(tmp / "lite.csv", "kitti-c", "Lite-Mono Large", tilt=0.1)
    out = tmp / "out"
    res = CliRunner().invoke(main, ["report", str(a), str(b), "--name", "Ours (ViT)",
                                    "--name", "Ours & Lite", "--out", str(out)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return {"out": out, "files": {"Ours (ViT)": a, "Ours & Lite": b}, "output": res.output}


# --------------------------------------------------------------------------- the outputs

def test_report_writes_every_output(kitti_report):
    out = kitti_report["out"]
    assert f"wrote {out / 'index.html'}" in kitti_report["output"]
    for name in ("index.html", "table.tex", "table.md", "scores.json"):
        assert (out / name).stat().st_size > 0
    for stem in ("radar", "ce", "levels", "summary"):
        assert (out / "figures" / f"{stem}.svg").read_bytes().startswith(b"<?xml")
        assert (out / "figures" / f"{stem}.pdf").read_bytes().startswith(b"%PDF")
        assert (out / "figures" / f"{stem}.png").read_bytes().startswith(b"\x89PNG")
    assert not [p for p in out.rglob("*") if p.name.startswith(".")]  # no probe or temp left


def test_page_numbers_are_the_score_commands(kitti_report, cli, tmp_path):
    out = kitti_report["out"]
    t = page_tables(out / "index.html")
    summary, dee, ce, rr, levels = (t.tables[k] for k in
                                    ("summary", "corruption-dee", "corruption-ce", "corruption-rr", "levels"))
    # Yours: the score command on the same files.
    expected = {name: score_json(cli, path, "kitti-c") for name, path in kitti_report["files"].items()}
    # Context: the paper's rows through the score command.
    for row in published_rows("kitti-c"):
        path = published_csv(tmp_path / "p.csv", "kitti-c", row["model"])
        expected[row["model"]] = score_json(cli, path, "kitti-c")
    assert list(summary) == list(expected)  # yours first, then the paper's order
    for name, j in expected.items():
        assert summary[name] == summary_values(j), name
        for c, cj in j["corruptions"].items():
            assert dee[name][c] == f"{cj['dee']:.3f}"
            assert ce[name][c] == f"{cj['ce']:.2f}"
            assert rr[name][c] == f"{cj['rr']:.2f}"
    for name in kitti_report["files"]:
        assert t.kinds["summary", name] == "yours"
        for c, cj in expected[name]["corruptions"].items():
            for lv, d in cj["levels"].items():
                assert levels[name][f"{c} {lv}"] == f"{d:.3f}"
    assert t.kinds["summary", "MonoDepth2 R18"] == "baseline"
    assert t.kinds["summary", "MonoViT"] == "published"


def test_best_and_second_are_marked(kitti_report):
    t = page_tables(kitti_report["out"] / "index.html")
    summary = t.tables["summary"]
    for col, better in (("mCE", min), ("mRR", max), ("sensor & movement mDEE", min)):
        values = sorted({float(row[col]) for row in summary.values()}, reverse=better is max)
        for model, row in summary.items():
            mark = t.marks.get(("summary", model, col), "")
            want = "best" if float(row[col]) == values[0] else "second" if float(row[col]) == values[1] else ""
            assert mark == want, (model, col)


def test_latex_numbers_and_marks(kitti_report, cli):
    text = (kitti_report["out"] / "table.tex").read_text()
    assert r"\toprule" in text and r"\cmidrule(lr){3-5}" in text and r"\bottomrule" in text
    assert r"\multicolumn{3}{c}{Weather \& Lighting}" in text
    # Well-formed: braces balance (escaped ones aside) and never go below zero, environments
    # nest, every row of a tabular has as many cells as its column spec.
    depth = 0
    for ch in re.sub(r"\\[{}]|%[^\n]*", "", text):
        depth += {"{": 1, "}": -1}.get(ch, 0)
        assert depth >= 0
    assert depth == 0
    stack = []
    for kind, env in re.findall(r"\\(begin|end)\{(\w+\*?)\}", text):
        if kind == "begin":
            stack.append(env)
        else:
            assert stack.pop() == env
    assert stack == []
    for spec, body in re.findall(r"\\begin\{tabular\}\{(\w+)\}(.*?)\\end\{tabular\}", text, flags=re.S):
        for line in body.splitlines():
            if line.endswith(r"\\"):
                spans = sum(int(k) - 1 for k in re.findall(r"\\multicolumn\{(\d+)\}", line))
                assert line.count(" & ") + 1 + spans == len(spec), line
    summary, dee = latex_tables(text)
    page = page_tables(kitti_report["out"] / "index.html")
    # Model names escaped for LaTeX; the baseline says so.
    assert "Ours \\& Lite" in summary and "MonoDepth2 R18 (baseline)" in summary
    cols = list(page.tables["summary"]["Ours (ViT)"])
    for tex_name, cells in summary.items():
        name = tex_name.replace("\\&", "&").replace(" (baseline)", "")
        for col, cell in zip(cols, cells):
            value, mark = _unmark(cell)
            assert value == page.tables["summary"][name][col], (name, col)
            assert mark == page.marks.get(("summary", name, col), ""), (name, col)
    # The page's numbers are the score command's (test above); the DEE table too.
    j = score_json(cli, kitti_report["files"]["Ours (ViT)"], "kitti-c")
    assert [_unmark(c)[0] for c in dee["Ours (ViT)"]] == [f"{c['dee']:.3f}" for c in j["corruptions"].values()]


def test_markdown_numbers(kitti_report):
    text = (kitti_report["out"] / "table.md").read_text()
    page = page_tables(kitti_report["out"] / "index.html")
    line = next(l for l in text.splitlines() if l.startswith("| Ours (ViT) |"))
    cells = [c.strip().strip("*") for c in line.strip("|").split("|")][1:]
    assert cells[:13] == list(page.tables["summary"]["Ours (ViT)"].values())


def test_scores_json_is_a_versioned_entry(kitti_report, cli):
    doc = json.loads((kitti_report["out"] / "scores.json").read_text())
    assert doc["schema"] == "robodepth-report" and doc["schema_version"] == 1
    from robodepth_cli import __version__

    assert doc["robodepth"] == __version__ and doc["benchmark"] == "kitti-c"
    assert doc["dataset"] is None  # no --dataset
    assert [m["model"] for m in doc["models"]] == ["Ours (ViT)", "Ours & Lite"]
    for m in doc["models"]:
        j = score_json(cli, kitti_report["files"][m["model"]], "kitti-c")
        assert (m["scores"]["mce"], m["scores"]["mrr"], m["scores"]["mdee"]) == (j["mce"], j["mrr"], j["mdee"])
        assert m["clean_dee"] == j["clean_dee"]
        for c, cj in j["corruptions"].items():
            assert m["corruptions"][c]["levels"] == cj["levels"]
            assert m["corruptions"][c]["ce"] == cj["ce"]
        # The raw per-variant metrics of the results file, as written.
        rows = list(csv.DictReader(kitti_report["files"][m["model"]].open()))
        assert len(m["variants"]) == len(rows) == 91
        assert m["variants"][5]["rmse"] == float(rows[5]["rmse"])
        assert len(m["results_sha256"]) == 64


def test_figures_name_models_and_benchmark(kitti_report):
    figs = kitti_report["out"] / "figures"
    for stem in ("radar", "ce", "levels", "summary"):
        svg = (figs / f"{stem}.svg").read_text()
        assert "KITTI-C" in svg, stem
        for name in ("Ours (ViT)", "Ours &amp; Lite"):
            assert name in svg, (stem, name)


def test_page_is_self_contained(kitti_report):
    html = (kitti_report["out"] / "index.html").read_text()
    # No reference to anything outside the page but the figure files beside it.
    refs = re.findall(r'(?:src|href)="([^"#][^"]*)"', html)
    assert all(r.startswith("figures/") or r.startswith("data:") for r in refs), refs
    assert not re.search(r"url\((?!#)|@import|<script|<link(?![^>]*href=\"data:)", html)
    assert html.count("<svg") == 4
    # Inline SVG ids are unique across the figures.
    ids = re.findall(r'\bid="([^"]+)"', html)
    assert len(ids) == len(set(ids))


@pytest.mark.slow
def test_published_none_and_baseline(tmp_path, cli):
    a = evaluate_csv(tmp_path / "a.csv", "nyudepth2-c", "DPT ViT-B")
    for which, rows in (("none", ["a"]), ("baseline", ["a", "AdaBins EB5"])):
        out = tmp_path / which
        res = cli("report", a, "--out", out, "--published", which)
        assert res.exit_code == 0, res.output
        assert list(page_tables(out / "index.html").tables["summary"]) == rows


def test_kitti_s_report(tmp_path, cli):
    a = styles_csv(tmp_path / "a.csv", "MonoViT")
    b = styles_csv(tmp_path / "b.csv", "DIFFNet", shift=0.0131)
    out = tmp_path / "out"
    res = cli("report", a, b, "--out", out)
    assert res.exit_code == 0, res.output
    t = page_tables(out / "index.html").tables["styles"]
    row = next(r for r in published_rows("kitti-s") if r["model"] == "DIFFNet")
    styles = [k for k in row if k not in ("block", "model", "mDEE")]
    assert [t["b"][s] for s in styles] == [f"{float(row[s]) + 0.0131:.3f}" for s in styles]
    assert t["b"]["mDEE"] == f"{np.mean([float(row[s]) + 0.0131 for s in styles]):.3f}"
    assert len(t) == 2 + 24
    doc = json.loads((out / "scores.json").read_text())
    assert doc["benchmark"] == "kitti-s" and doc["models"][0]["styles"]["cartoon"]["dee"] == 0.179 + 0.0
    for stem in ("radar", "styles", "ranking"):
        assert (out / "figures" / f"{stem}.png").stat().st_size > 0


# --------------------------------------------------------------------------- refusals

def test_refusals(tmp_path, cli):
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    n = evaluate_csv(tmp_path / "n.csv", "nyudepth2-c", "BTS R50")
    out = tmp_path / "out"
    # (k and n together: a report of two datasets, test_report_synreal.py)
    one_line_error(cli("report", k, k, "--out", out), "model name 'k' is also the name of")
    one_line_error(cli("report", k, n, "--name", "x", "--out", out), "--name given 1 time for 2 results files")
    one_line_error(cli("report", tmp_path / "nope.csv", "--out", out), "cannot read")
    partial = tmp_path / "p.csv"
    partial.write_text("\n".join(k.read_text().splitlines()[:-5]) + "\n")
    one_line_error(cli("report", partial, "-b", "kitti-c", "--out", out), "missing 5 of 90 variants")
    one_line_error(cli("report", k, "--pred", tmp_path, "--out", out), "--pred needs --dataset")
    one_line_error(cli("report", k, "--dataset", tmp_path, "--out", out), "not a dataset made by robodepth build")
    assert not (out / "index.html").exists()


def test_unwritable_out_is_refused_before_any_work(tmp_path, cli):
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    one_line_error(cli("report", k, "--out", blocker / "out"), "cannot write (")


def test_plain_commands_do_not_import_matplotlib(tmp_path):
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    assert imported_by_command(["score", k, "--json"], ["matplotlib"]) == []


# --------------------------------------------------------------------------- figures are legible

def test_no_text_overlaps_in_any_figure(tmp_path, cli):
    """Labels of crowded scatters, radar axes, tick labels and legends: no two texts of a
    figure overlap (the figures of several models, and of one)."""
    from robodepth_cli.report import plot
    from robodepth_cli.report import write as W

    files = [evaluate_csv(tmp_path / f"m{i}.csv", "kitti-c", m)
             for i, m in enumerate(("MonoViT", "Lite-Mono Large", "DIFFNet", "CADepth"))]
    report = W.assemble(_tables(files), ["a long model name for the legend", "b", "c", "d"], None, "all")
    W.draw(report)
    assert [f[0] for f in report.figures] == ["radar", "ce", "levels", "summary"]
    for _, _, _, fig in report.figures:
        no_overlap(fig)
    # Every one of the user's models is named next to its point in both summary panels.
    summary = report.figures[-1][3]
    for ax in summary.axes[:2]:
        named = {t.get_text() for t in ax.texts}
        assert {"a long model name for the legend", "b", "c", "d"} <= named
    single = plot.ce_figure([plot.Model("one", report.models[0].row.scores)], "kitti-c")
    no_overlap(single)


def test_radar_ring_values_cross_no_line():
    """The ring values of the radar sit where no model's line passes."""
    from robodepth_cli.report import figures

    lines = [[0.2] * 18, [0.3, 0.5] * 9]
    gap, shown = figures._radial_label_spot(lines, [0.1, 0.2, 0.3, 0.4, 0.5], 0.6)
    # Every gap is crossed at 0.2 by the first line and near 0.4 by the second.
    assert 0.2 not in shown and 0.1 in shown and 0.5 in shown


# --------------------------------------------------------------------------- with the dataset build

@pytest.mark.slow
def test_dataset_fingerprint_and_qualitative_figure(small_build, tmp_path, cli):
    import hashlib

    from robodepth_cli import open_dataset

    ds = open_dataset(small_build)
    n = len(ds.keys)
    pred = tmp_path / "PRED"
    for i, v in enumerate(ds.variants()):
        # Disparity rising towards the bottom of the image (near), different per variant.
        ramp = np.linspace(0.01, 0.3, 64, dtype=np.float32)[:, None] * np.ones((1, 96), np.float32)
        v.save_predictions(pred, [ramp * (1 + 0.1 * i)] * n)
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    out = tmp_path / "out"
    res = cli("report", k, "--dataset", small_build, "--pred", pred, "--frame", 1, "--out", out)
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "scores.json").read_text())
    # The fingerprint, recomputed here from the manifest's rows (output path and sha256).
    rows = manifest_rows(small_build)
    digest = hashlib.sha256("".join(f"{r['output']} {r['sha256']}\n"
                                    for r in sorted(rows, key=lambda r: r["output"])).encode())
    assert doc["dataset"]["fingerprint"] == digest.hexdigest()
    assert doc["dataset"]["name"] == "kitti-c" and doc["dataset"]["images"] == n
    html = (out / "index.html").read_text()
    assert 'id="fig-qualitative"' in html and doc["dataset"]["fingerprint"][:16] in html
    png = np.asarray(__import__("PIL.Image", fromlist=["Image"]).open(out / "figures" / "qualitative.png").convert("RGB"))
    assert png.std() > 20  # images and colour maps, not an empty canvas
    svg = (out / "figures" / "qualitative.svg").read_text()
    assert "k" in svg and "brightness 3" in svg and "contrast 3" in svg and ds.keys[1] in svg
    bad = cli("report", k, "--dataset", small_build, "--pred", pred, "--frame", n, "--out", out)
    one_line_error(bad, f"--frame {n}: ")
    nyu = evaluate_csv(tmp_path / "n.csv", "nyudepth2-c", "BTS R50")
    one_line_error(cli("report", nyu, "--dataset", small_build, "--out", out), "is a kitti-c build")


def test_without_matplotlib_figures_are_refused_in_one_line(tmp_path):
    """matplotlib is the figures extra: without it, report and score --plot say how to get
    it, before writing anything; score without --plot still works."""
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    code = ("import sys; sys.modules['matplotlib'] = None\n"  # import matplotlib now fails
            "from robodepth_cli.cli import main\n"
            "main(sys.argv[1:])\n")
    for args in (["report", str(k), "--out", str(tmp_path / "out")],
                 ["score", str(k), "--plot", str(tmp_path / "ce.png")]):
        res = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True)
        assert res.returncode == 2, res.stderr
        assert res.stderr == ("robodepth: error: figures need matplotlib: pip install "
                              "'robodepth-cli[figures]' (or pip install matplotlib)\n")
    assert not (tmp_path / "out").exists() and not (tmp_path / "ce.png").exists()
    res = subprocess.run([sys.executable, "-c", code, "score", str(k)], capture_output=True, text=True)
    assert res.returncode == 0 and "mCE" in res.stdout


@pytest.mark.slow
def test_two_rows_mark_only_the_best(tmp_path, cli):
    a = evaluate_csv(tmp_path / "a.csv", "nyudepth2-c", "DPT ViT-B")
    b = evaluate_csv(tmp_path / "b.csv", "nyudepth2-c", "BTS R50")
    out = tmp_path / "out"
    assert cli("report", a, b, "--out", out, "--published", "none").exit_code == 0
    t = page_tables(out / "index.html")
    marks = {m for (table, _, _), m in t.marks.items() if table == "summary"}
    assert marks == {"best"}
    # DPT is the more robust: every mCE/mRR/mDEE best is its (BTS has the better clean DEE).
    assert {model for (table, model, col), m in t.marks.items() if table == "summary" and col != "clean"} == {"a"}
