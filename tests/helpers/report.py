"""Results files for the report and score tests (from the paper's published rows), and readers
of what `robodepth report` writes: the page's tables, the LaTeX tables, a figure's texts."""

from __future__ import annotations

import csv
import re
from html.parser import HTMLParser
from pathlib import Path

from robodepth_cli.report import published as P


def tables(paths) -> list:
    """The results files ``paths`` read, as the report command hands them on."""
    from robodepth_cli.evaluation.csvrows import ResultsTable

    return [ResultsTable.read(p) for p in paths]


KITTI_COLUMNS = ["corruption", "level", "abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3"]



def published_rows(bench: str) -> list[dict]:
    with (P.DATA / P.FILES[bench]).open(newline="") as fh:
        return list(csv.DictReader(fh))



def evaluate_csv(path: Path, bench: str, model: str, tilt: float = 0.04) -> Path:
    """A results CSV as `robodepth evaluate` writes it, for a published model: level l of a
    corruption has DEE d * (1 + tilt * (l - mid)), so the level mean is the published d;
    a1 is fixed and abs_rel chosen to give that DEE (DEE = (abs_rel - a1 + 1) / 2)."""
    row = next(r for r in published_rows(bench) if r["model"] == model)
    levels = 5 if bench == "kitti-c" else 4
    corruptions = [k for k in row if k in _corruption_names(bench)]
    a1 = 0.85
    lines = [KITTI_COLUMNS]

    def metrics(dee):
        return [repr(2 * dee - 1 + a1), "0.9", "4.5", "0.19", repr(a1), "0.95", "0.98"]

    lines.append(["clean", "0", *metrics(float(row["clean_dee"]))])
    for c in corruptions:
        d = float(row[c])
        for lv in range(1, levels + 1):
            lines.append([c, str(lv), *metrics(d * (1 + tilt * (lv - (levels + 1) / 2)))])
    with path.open("w", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows(lines)
    return path



def _corruption_names(bench):
    from robodepth_cli.benchmark_facts import BENCHMARKS

    return BENCHMARKS[bench].corruptions



def published_csv(path: Path, bench: str, model: str) -> Path:
    """The paper's row of ``model`` as a `dee` results file: every level at the published
    level mean."""
    row = next(r for r in published_rows(bench) if r["model"] == model)
    levels = 5 if bench == "kitti-c" else 4
    lines = ["corruption,level,dee", f"clean,0,{row['clean_dee']}"]
    lines += [f"{c},{lv},{row[c]}" for c in _corruption_names(bench) for lv in range(1, levels + 1)]
    path.write_text("\n".join(lines) + "\n")
    return path



class _Tables(HTMLParser):
    """Every ``<table class="scores">`` of the page: table id -> model -> column -> text;
    also which cells are marked best/second, and which rows are published."""

    def __init__(self):
        super().__init__()
        self.tables: dict[str, dict[str, dict[str, str]]] = {}
        self.marks: dict[tuple[str, str, str], str] = {}
        self.kinds: dict[tuple[str, str], str] = {}
        self._table = self._model = self._col = None
        self._text = ""

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table" and "scores" in (a.get("class") or ""):
            self._table = a["id"]
            self.tables[self._table] = {}
        elif tag == "tr" and self._table and "data-model" in a:
            self._model = a["data-model"]
            self.kinds[self._table, self._model] = a.get("class", "")
            self.tables[self._table][self._model] = {}
        elif tag == "td" and self._model:
            self._col, self._text = a["data-col"], ""
            if a.get("class"):
                self.marks[self._table, self._model, self._col] = a["class"]

    def handle_data(self, data):
        if self._col:
            self._text += data

    def handle_endtag(self, tag):
        if tag == "td" and self._col:
            self.tables[self._table][self._model][self._col] = self._text.strip()
            self._col = None
        elif tag == "tr":
            self._model = None
        elif tag == "table":
            self._table = None



def page_tables(path: Path) -> _Tables:
    p = _Tables()
    p.feed(path.read_text(encoding="utf-8"))
    return p



def latex_tables(text: str) -> list[dict[str, list[str]]]:
    """Each tabular's body rows: model -> cells, with the \\textbf/\\underline marks kept."""
    out = []
    for body in re.findall(r"\\midrule\n(.*?)\\bottomrule", text, flags=re.S):
        rows = {}
        for line in body.splitlines():
            if not line.endswith(r"\\") or line.startswith(r"\multicolumn") or line == r"\midrule":
                continue
            cells = [c.strip() for c in line[:-2].split(" & ")]
            rows[cells[0]] = cells[1:]
        out.append(rows)
    return out



def figure_texts(fig):
    from matplotlib.text import Text

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    # Tick labels of ticks outside an axis' view are not drawn.
    hidden = set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not lo - 1e-9 <= tick.get_loc() <= hi + 1e-9:
                    hidden.update({id(tick.label1), id(tick.label2)})
    out = []
    for t in fig.findobj(Text):
        if (t.get_visible() and t.get_text().strip() and id(t) not in hidden
                and t.get_figure(root=True) is fig):
            out.append((t.get_text(), t.get_window_extent(renderer)))
    return out



def no_overlap(fig):
    texts = figure_texts(fig)
    for i, (a, ba) in enumerate(texts):
        for b, bb in texts[i + 1:]:
            inter = ba.intersection(ba, bb)
            assert inter is None or inter.width < 1 or inter.height < 1, (a, b)


A1 = 0.85



def extra_rows(dees: dict) -> str:
    """Rows as `robodepth evaluate` writes them: ``(corruption, level) -> DEE``."""
    return "".join(f"{c},{lv},{2 * d - 1 + A1!r},0.9,4.5,0.19,{A1!r},0.95,0.98\n" for (c, lv), d in dees.items())
