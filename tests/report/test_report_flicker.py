"""`robodepth report` draws the flicker of `evaluate --flicker` results: two tables (page,
table.md, table.tex), a figure and an entry per model in scores.json; results without the
flicker columns give the same report as before."""

from __future__ import annotations

from tests.helpers.report import tables as _tables

import csv
import json

import pytest

from tests.helpers.report import evaluate_csv, figure_texts, latex_tables, no_overlap, page_tables


def with_flicker(plain, path, scale_of, abs_rel_of):
    """``plain`` with the two flicker columns: ``scale_of(corruption, level)`` and
    ``abs_rel_of(corruption, level)`` give each row's values."""
    rows = list(csv.reader(plain.read_text().splitlines()))
    rows[0] += ["flicker_scale", "flicker_abs_rel"]
    for r in rows[1:]:
        lv = int(r[1])
        r += [repr(scale_of(r[0], lv)), repr(abs_rel_of(r[0], lv))]
    with path.open("w", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows(rows)
    return path


def scale_a(c, lv):
    return 0.02 if c == "clean" else 0.03 + 0.01 * lv + (0.05 if c == "fog" else 0.0)


def abs_rel_a(c, lv):
    return 0.001 if c == "clean" else 0.002 * lv


@pytest.fixture
def two_models(tmp_path):
    a = with_flicker(evaluate_csv(tmp_path / "pa.csv", "kitti-c", "MonoViT"), tmp_path / "a.csv",
                     scale_a, abs_rel_a)
    b = with_flicker(evaluate_csv(tmp_path / "pb.csv", "kitti-c", "DIFFNet"), tmp_path / "b.csv",
                     lambda c, lv: 0.01 if c == "clean" else 0.015 * lv, lambda c, lv: 0.0005 * (lv + 1))
    return a, b


@pytest.mark.slow
def test_flicker_tables_and_json_equal_the_csv(tmp_path, cli, two_models):
    pytest.importorskip("matplotlib")
    out = tmp_path / "out"
    res = cli("report", *two_models, "--name", "A", "--name", "B", "--out", out)
    assert res.exit_code == 0, res.output
    # By hand: fog's flicker_scale for A is the mean over levels 1..5 of 0.08 + 0.01 l = 0.11.
    tables = page_tables(out / "index.html").tables
    scale, err = tables["flicker-scale"], tables["flicker-abs-rel"]
    assert set(scale) == {"A", "B"}  # the user's models only: the paper has no flicker
    assert scale["A"]["clean"] == "0.0200" and scale["B"]["clean"] == "0.0100"
    assert scale["A"]["fog"] == "0.1100" and scale["A"]["snow"] == "0.0600"
    assert scale["B"]["fog"] == "0.0450"
    assert err["A"]["dark"] == "0.0060" and err["B"]["clean"] == "0.0005"
    marks = page_tables(out / "index.html").marks
    assert marks["flicker-scale", "B", "fog"] == "best"
    md = (out / "table.md").read_text()
    assert "Flicker: scale change per frame" in md and "| A | **0.0200** |" not in md
    assert "| B | **0.0100** |" in md
    tex = latex_tables((out / "table.tex").read_text())
    assert any(t.get("A", [None])[0] == "0.0200" for t in tex)
    doc = json.loads((out / "scores.json").read_text())
    fl = doc["models"][0]["flicker"]
    assert fl["clean"] == {"flicker_scale": 0.02, "flicker_abs_rel": 0.001}
    assert fl["corruptions"]["fog"]["flicker_scale"] == pytest.approx(0.11)
    assert fl["corruptions"]["fog"]["levels"]["3"] == {"flicker_scale": pytest.approx(0.11),
                                                       "flicker_abs_rel": pytest.approx(0.006)}
    assert len(fl["corruptions"]) == 18
    svg = (out / "figures" / "flicker.svg").read_text()
    assert "Flicker on consecutive frames of KITTI-C" in svg and "fog" in svg
    assert 'id="fig-flicker"' in (out / "index.html").read_text()


def test_flicker_figure_bars_are_the_values_and_legible(two_models):
    pytest.importorskip("matplotlib")
    from matplotlib.patches import Rectangle

    from robodepth_cli.report import write as W

    report = W.assemble(_tables(list(two_models)), ["a long model name for the legend", "B"], None, "all")
    W.draw(report)
    assert [f[0] for f in report.figures][-1] == "flicker"
    fig = report.figures[-1][3]
    no_overlap(fig)
    edge = fig.bbox
    for text, box in figure_texts(fig):  # nothing cut off by the figure's edge
        assert edge.x0 <= box.x0 and box.x1 <= edge.x1 and edge.y0 <= box.y0 and box.y1 <= edge.y1, text
    left, right = fig.axes[:2]
    widths = sorted(round(p.get_width(), 9) for p in left.patches if isinstance(p, Rectangle)
                    and p.get_width() > 0)
    # 19 bars per model: clean and the 18 corruptions.
    want_a = [0.02] + [sum(scale_a(c, lv) for lv in range(1, 6)) / 5 for c in
                       ("brightness", "dark", "fog", "frost", "snow", "contrast") + ("x",) * 12]
    assert len(widths) == 38
    for w in want_a:
        assert round(w, 9) in widths
    assert max(p.get_width() for p in right.patches if isinstance(p, Rectangle)) == pytest.approx(0.006)
    # The clean reference lines are each model's clean value.
    assert sorted(round(line.get_xdata()[0], 9) for line in left.get_lines()) == [0.01, 0.02]


@pytest.mark.slow
def test_without_flicker_the_report_is_unchanged(tmp_path, cli, two_models):
    pytest.importorskip("matplotlib")
    plain = evaluate_csv(tmp_path / "plain.csv", "kitti-c", "MonoViT")
    out = tmp_path / "out"
    assert cli("report", plain, "--out", out).exit_code == 0
    assert not (out / "figures" / "flicker.svg").exists()
    assert "Flicker" not in (out / "index.html").read_text()
    assert "Flicker" not in (out / "table.md").read_text() + (out / "table.tex").read_text()
    assert "flicker" not in json.loads((out / "scores.json").read_text())["models"][0]
    # The same results with the flicker columns: every other table as before.
    out2 = tmp_path / "out2"
    assert cli("report", two_models[0], "--name", "plain", "--out", out2).exit_code == 0
    md, md2 = (out / "table.md").read_text(), (out2 / "table.md").read_text()
    assert md2.startswith(md)


def test_a_model_without_flicker_beside_one_with_it(tmp_path, two_models):
    """Only the model whose results have the columns is in the flicker tables and figure,
    drawn in its own colour (the one it has in every other figure)."""
    pytest.importorskip("matplotlib")
    from matplotlib.colors import to_hex

    from robodepth_cli.report.plot import style
    from robodepth_cli.report import write as W

    plain = evaluate_csv(tmp_path / "plain.csv", "kitti-c", "CADepth")
    report = W.assemble(_tables([plain, two_models[0]]), ["plain", "A"], None, "all")
    W.draw(report)
    assert [f.model for f in report.flicker] == ["A"]
    assert report.flicker[0].row.name == "A"
    fig = report.figures[-1][3]
    colours = {to_hex(p.get_facecolor()) for p in fig.axes[0].patches}
    assert colours == {style(1)["color"].lower()}
    doc = W.to_json(report)
    assert "flicker" not in doc["models"][0] and doc["models"][1]["flicker"]["clean"]["flicker_scale"] == 0.02
