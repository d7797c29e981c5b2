"""The report's tables, built once and rendered as HTML, LaTeX (booktabs) and Markdown.

Every number is formatted by :func:`fmt` (DEE three decimals, CE/RR and their means two),
the precision the paper prints. In each column the best value is bold and the second
underlined (Markdown: italic, it has no underline), ranked among every row of the table
by the value as printed, so ties in print share their mark; a table of two rows marks only
the best (its "second" would be every other cell).
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from typing import Sequence

from ..benchmark_facts import CATEGORIES
from .inputs import Row

LOW, HIGH = "low", "high"  # which end of a column is better
CATEGORY_SHORT = {"weather & lighting": "Weather & Lighting", "sensor & movement": "Sensor & Movement",
                  "data & processing": "Data & Processing"}


@dataclass(frozen=True)
class Column:
    key: str
    header: str
    group: str  # spanning header ("" for none)
    better: str
    decimals: int


@dataclass
class Table:
    title: str
    label: str  # LaTeX label / HTML id
    caption: str
    columns: list[Column]
    rows: list[Row]
    values: list[dict[str, float | None]]  # per row, column key -> value
    marks: dict[tuple[int, str], str] = field(default_factory=dict)  # (row, key) -> best/second
    ranked: bool = True  # False: rows that are no rivals (pairs of conditions), nothing marked

    def __post_init__(self):
        for col in self.columns if self.ranked else ():
            printed = sorted({round(v[col.key], col.decimals) for v in self.values
                              if v.get(col.key) is not None}, reverse=col.better == HIGH)
            for i, v in enumerate(self.values):
                if v.get(col.key) is None:
                    continue
                r = round(v[col.key], col.decimals)
                if printed and r == printed[0]:
                    self.marks[i, col.key] = "best"
                elif len(printed) > 1 and len(self.values) > 2 and r == printed[1]:
                    self.marks[i, col.key] = "second"

    def cell(self, i: int, col: Column) -> str:
        return fmt(self.values[i].get(col.key), col.decimals)


def fmt(value: float | None, decimals: int) -> str:
    return "n/a" if value is None else f"{value:.{decimals}f}"


# --------------------------------------------------------------------------- the tables

def summary_table(rows: Sequence[Row], benchmark: str) -> Table:
    """Table 1 of the paper: overall and per-category mCE, mRR, mDEE (and the clean DEE)."""
    cols = [Column("clean", "Clean DEE", "", LOW, 3)]
    for group, prefix in [("Overall", "")] + [(CATEGORY_SHORT[c], c + " ") for c in CATEGORIES]:
        cols += [Column(prefix + "mCE", "mCE", group, LOW, 2),
                 Column(prefix + "mRR", "mRR", group, HIGH, 2),
                 Column(prefix + "mDEE", "mDEE", group, LOW, 3)]
    values = []
    for r in rows:
        s = r.scores
        v = {"clean": r.clean, "mCE": s.overall.ce, "mRR": s.overall.rr, "mDEE": s.overall.dee}
        for g in s.categories:
            v.update({f"{g.name} mCE": g.ce, f"{g.name} mRR": g.rr, f"{g.name} mDEE": g.dee})
        values.append(v)
    return Table("Robustness scores", "summary",
                 f"Robustness on {bench_name(benchmark)}: mCE (lower is better, baseline "
                 f"{rows_baseline(rows)} = 100), mRR (higher is better) and mDEE (lower is "
                 "better), overall and per category. Bold: best; underlined: second.",
                 cols, list(rows), values)


def corruption_table(rows: Sequence[Row], benchmark: str, metric: str) -> Table:
    """One metric (``dee``, ``ce`` or ``rr``) per corruption, grouped by category."""
    first = rows[0].scores
    decimals, better, header = {"dee": (3, LOW, "DEE"), "ce": (2, LOW, "CE (%)"),
                                "rr": (2, HIGH, "RR (%)")}[metric]
    cols = [Column(c.name, c.name.replace("_", " "), CATEGORY_SHORT[c.category], better, decimals)
            for c in first.corruptions]
    values = [{c.name: getattr(c, metric) for c in r.scores.corruptions} for r in rows]
    what = {"dee": "Depth estimation error (DEE, mean over the levels; lower is better)",
            "ce": f"Corruption error (CE in %, baseline {rows_baseline(rows)} = 100; lower is better)",
            "rr": "Resilience rate (RR in %, higher is better)"}[metric]
    return Table(f"{header} per corruption", f"corruption-{metric}",
                 f"{what} per corruption on {bench_name(benchmark)}. Bold: best; underlined: second.",
                 cols, list(rows), values)


def styles_table(rows: Sequence[Row]) -> Table:
    """KITTI-S: DEE per style and their mean (mDEE)."""
    styles = list(rows[0].styles)
    cols = [Column(s, s.replace("_", " "), "Style", LOW, 3) for s in styles]
    cols.append(Column("mDEE", "mDEE", "", LOW, 3))
    values = [{**r.styles, "mDEE": r.mdee} for r in rows]
    return Table("DEE per style", "styles",
                 "Depth estimation error (DEE, lower is better) per style on KITTI-S and its mean "
                 "over the styles (mDEE). Bold: best; underlined: second.", cols, list(rows), values)


def levels_table(rows: Sequence[Row], benchmark: str) -> Table:
    """The user's models: DEE at every level of every corruption (a column per level)."""
    first = rows[0].scores
    cols = [Column(f"{c.name} {lv}", str(lv), c.name.replace("_", " "), LOW, 3)
            for c in first.corruptions for lv in range(1, first.n_levels + 1)]
    values = [{f"{c.name} {lv}": d for c in r.scores.corruptions for lv, d in c.level_dee.items()}
              for r in rows]
    return Table("DEE per level", "levels",
                 f"DEE at each level of each corruption on {bench_name(benchmark)} (your models).",
                 cols, list(rows), values)


def beyond_table(rows: Sequence[Row], benchmark: str, clean: bool = False) -> Table | None:
    """Rows beyond the benchmark (decimal levels, chains) of the user's models: DEE at every
    level of each severity curve, then each chain's DEE (after the clean DEE if ``clean``).
    None when there are none."""
    from ..sourcekeys import level_text

    curves: dict[str, set] = {}
    chains: dict[str, None] = {}
    for r in rows:
        for name, curve in r.scores.curves.items():
            curves.setdefault(name, set()).update(curve)
        chains.update(dict.fromkeys(r.scores.chains))
    if not curves and not chains:
        return None
    cols = [Column("clean", "Clean DEE", "", LOW, 3)] if clean else []
    cols += [Column(f"{n} {level_text(lv)}", level_text(lv), n.replace("_", " "), LOW, 3)
             for n, levels in curves.items() for lv in sorted(levels)]
    cols += [Column(c, c.replace("_", " ").replace("+", " + "), "Chains", LOW, 3) for c in chains]
    values = [{"clean": r.clean, **{f"{n} {level_text(lv)}": d for n, curve in r.scores.curves.items()
                                    for lv, d in curve.items()}, **r.scores.chains} for r in rows]
    return Table("Beyond the benchmark", "beyond",
                 f"DEE of the variants beyond {bench_name(benchmark)} (your models): severity curves "
                 "(each corruption with decimal-level rows, at every level present) and chains of "
                 "corruptions. They are in no mCE, mRR or mDEE. Lower is better.",
                 cols, list(rows), values)


def bench_name(benchmark: str) -> str:
    return {"kitti-c": "KITTI-C", "nyudepth2-c": "NYUDepth2-C", "kitti-s": "KITTI-S"}.get(benchmark, benchmark)


def rows_baseline(rows: Sequence[Row]) -> str:
    first = next((r for r in rows if r.scores is not None), None)
    return first.scores.baseline.name if first else ""


def _groups(cols: Sequence[Column]) -> list[tuple[str, int]]:
    out: list[tuple[str, int]] = []
    for c in cols:
        if out and out[-1][0] == c.group:
            out[-1] = (c.group, out[-1][1] + 1)
        else:
            out.append((c.group, 1))
    return out


KIND_LABEL = {"yours": "", "baseline": "baseline, published", "published": "published"}


# --------------------------------------------------------------------------- HTML

def to_html(t: Table) -> str:
    """A ``<table>``: the user's rows first, then the published ones in their own body,
    each marked (class ``published``, and a tag after the name)."""
    e = html.escape
    out = [f'<p class="caption"><strong>{e(t.title)}.</strong> {e(t.caption)}</p>',
           f'<div class="scroll"><table id="{e(t.label)}" class="scores">', "<thead>"]
    groups = _groups(t.columns)
    if any(g for g, _ in groups):
        out.append('<tr><th rowspan="2" class="model">Model</th>'
                   + "".join(f'<th colspan="{n}" class="group">{e(g)}</th>' if g
                             else f'<th colspan="{n}" class="nogroup"></th>' for g, n in groups) + "</tr>")
        out.append("<tr>" + "".join(f'<th title="{e(c.key)}">{_arrow_html(c, t.ranked)}</th>'
                                    for c in t.columns) + "</tr>")
    else:
        out.append('<tr><th class="model">Model</th>'
                   + "".join(f"<th>{_arrow_html(c, t.ranked)}</th>" for c in t.columns) + "</tr>")
    out.append("</thead>")
    section = None
    for i, r in enumerate(t.rows):
        body = "yours" if r.mine else "published"
        if body != section:
            if section is not None:
                out.append("</tbody>")
            out.append(f'<tbody class="{body}">')
            if body == "published":
                out.append(f'<tr class="section"><th colspan="{len(t.columns) + 1}">Published '
                           'models (the RoboDepth paper; context, not your results)</th></tr>')
            section = body
        tag = KIND_LABEL[r.kind]
        name = e(r.name) + (f' <span class="tag">{e(tag)}</span>' if tag else "")
        cells = []
        for c in t.columns:
            mark = t.marks.get((i, c.key))
            cls = f' class="{mark}"' if mark else ""
            cells.append(f'<td{cls} data-col="{e(c.key)}">{t.cell(i, c)}</td>')
        out.append(f'<tr class="{r.kind}" data-model="{e(r.name)}"><th class="model" scope="row">'
                   f"{name}</th>{''.join(cells)}</tr>")
    if section is not None:
        out.append("</tbody>")
    out.append("</table></div>")
    return "\n".join(out)


def _arrow_html(c: Column, ranked: bool = True) -> str:
    """The header with the arrow saying which way is better (none in an unranked table)."""
    arrow = ("&nbsp;&darr;" if c.better == LOW else "&nbsp;&uarr;") if ranked else ""
    return html.escape(c.header) + arrow


# --------------------------------------------------------------------------- LaTeX

_TEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
        "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
        # The Greek of the headers (rank correlations, delta1): pdflatex has no Unicode maths.
        "ρ": r"$\rho$", "τ": r"$\tau$", "δ": r"$\delta$"}


def tex_escape(text: str) -> str:
    return "".join(_TEX.get(ch, ch) for ch in text)


def to_latex(t: Table) -> str:
    """A booktabs ``table`` (``\\usepackage{booktabs}``; ``\\resizebox`` needs graphicx):
    spanning headers with ``\\cmidrule``, published rows in their own block."""
    n = len(t.columns)
    spec = "l" + "".join("c" * k for _, k in _groups(t.columns))
    lines = [r"\begin{table*}[t]", r"\centering",
             f"\\caption{{{tex_escape(t.caption)}}}", f"\\label{{tab:robodepth-{t.label}}}",
             r"\resizebox{\linewidth}{!}{%", f"\\begin{{tabular}}{{{spec}}}", r"\toprule"]
    groups = _groups(t.columns)
    if any(g for g, _ in groups):
        heads, rules, col = [], [], 2
        for g, k in groups:
            if not g:
                heads += [""] * k
            else:
                heads.append(f"\\multicolumn{{{k}}}{{c}}{{{tex_escape(g)}}}")
                rules.append(f"\\cmidrule(lr){{{col}-{col + k - 1}}}")
            col += k
        lines.append(" & " + " & ".join(heads) + r" \\")
        lines.append(" ".join(rules))
    lines.append("Model & " + " & ".join(
        tex_escape(c.header) + (f" $\\{'downarrow' if c.better == LOW else 'uparrow'}$" if t.ranked else "")
        for c in t.columns) + r" \\")
    lines.append(r"\midrule")
    section = None
    for i, r in enumerate(t.rows):
        body = "yours" if r.mine else "published"
        if section is not None and body != section:
            lines.append(r"\midrule")
            lines.append(f"\\multicolumn{{{n + 1}}}{{l}}{{\\textit{{Published (RoboDepth, "
                         f"Kong et al., NeurIPS 2023)}}}} \\\\")
        section = body
        name = tex_escape(r.name) + (r" (baseline)" if r.kind == "baseline" else "")
        cells = []
        for c in t.columns:
            text = t.cell(i, c)
            mark = t.marks.get((i, c.key))
            cells.append(f"\\textbf{{{text}}}" if mark == "best" else
                         f"\\underline{{{text}}}" if mark == "second" else text)
        lines.append(f"{name} & " + " & ".join(cells) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}}", r"\end{table*}"]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- Markdown

def md_escape(text: str) -> str:
    return text.replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*").replace("_", "\\_")


def to_markdown(t: Table) -> str:
    """A pipe table (GitHub Markdown); spanning headers go into the column names."""
    head = ["Model"] + [f"{c.group} {c.header}".strip() + ((" ↓" if c.better == LOW else " ↑") if t.ranked else "")
                        for c in t.columns]
    lines = [f"**{t.title}.** {md_escape(t.caption)} (Markdown has no underline: second is "
             "in italics.)", "", "| " + " | ".join(md_escape(h) for h in head) + " |",
             "|" + "---|" + "---:|" * len(t.columns)]
    for i, r in enumerate(t.rows):
        tag = KIND_LABEL[r.kind]
        name = md_escape(r.name) + (f" ({tag})" if tag else "")
        cells = []
        for c in t.columns:
            text = t.cell(i, c)
            mark = t.marks.get((i, c.key))
            cells.append(f"**{text}**" if mark == "best" else f"*{text}*" if mark == "second" else text)
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def mixed_note(sizes) -> str:
    """One line when results made at different severity sizes meet in one table; ""
    otherwise."""
    distinct = sorted(set(sizes))
    if len(distinct) < 2:
        return ""
    return (f"These results were made at different severity sizes ({', '.join(distinct)}): a level "
            "is not the same corruption across them")
