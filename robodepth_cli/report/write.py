"""Make a report: score the inputs, draw the figures, write the page, tables and JSON.

Output layout under OUT (every file written atomically; an existing OUT is updated in place):

    index.html       the page (self-contained)
    table.tex        booktabs tables (summary like the paper's Table 1, then the details)
    table.md         the same tables in Markdown
    scores.json      the leaderboard entry (schema in docs/report.md, SCHEMA below)
    figures/<name>.svg|.pdf|.png
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from .. import __version__
from . import inputs as I
from . import published as P
from . import tables as T
from .page import PageFigure
from .page import render as render_page

SCHEMA = "robodepth-report"
SCHEMA_VERSION = 1


@dataclass
class Report:
    benchmark: str
    models: list[I.Model]
    rows: list[I.Row]  # the user's, then the published context
    tables: list[T.Table]
    figures: list[tuple[str, str, str, object]] = field(default_factory=list)  # stem, title, caption, Figure
    dataset: dict | None = None


def check_writable(out: Path) -> None:
    """Refuse, before any work, an OUT in which the report's files could not be created."""
    from ..files import check_writable as check

    if out.exists() and not out.is_dir():
        raise I.ReportError(f"--out {out}: exists and is not a directory")
    check(out / "figures" / "radar.svg", "--out")


def assemble(paths: Sequence[Path], names: Sequence[str], benchmark: str | None, context: str,
             dataset: Path | None = None) -> Report:
    """Read, check and score everything (no figure yet)."""
    I.model_names(paths, names)  # flag mistakes first: they need no file read
    bench = I.infer(paths, benchmark)
    models = I.load(paths, names, bench)
    rows = [m.row for m in models] + I.context(bench, context)
    info = I.dataset_info(dataset, bench) if dataset is not None else None
    if bench == I.KITTI_S:
        tables = [T.styles_table(rows)]
    else:
        tables = [T.summary_table(rows, bench), T.corruption_table(rows, bench, "dee"),
                  T.corruption_table(rows, bench, "ce"), T.corruption_table(rows, bench, "rr"),
                  T.levels_table([m.row for m in models], bench)]
        beyond = T.beyond_table([m.row for m in models], bench)
        if beyond is not None:
            tables.append(beyond)
    return Report(bench, models, rows, tables, dataset=info)


def draw(report: Report) -> None:
    """Add the figures (matplotlib is imported here, not before)."""
    from ..evaluation import plot
    from . import figures as F

    bench, models = report.benchmark, report.models
    base = P.baseline(bench)
    mine = [m.row for m in models]
    figs = report.figures
    if bench == I.KITTI_S:
        figs.append(("radar", "DEE per style", "Each model's DEE for each KITTI-S style; the "
                     "grey dashed line is the paper's baseline.",
                     F.radar_figure([(r.name, r.styles) for r in mine], bench,
                                       (base.name, base.dee), what="style")))
        figs.append(("styles", "DEE per style, as bars", "Each style's DEE per model, with the "
                     "published baseline for reference.",
                     F.styles_figure([(r.name, r.styles) for r in mine], bench,
                                        (base.name, base.dee))))
        figs.append(("ranking", "mDEE ranking", "Your models among the paper's KITTI-S models, "
                     "ranked by mDEE.",
                     F.ranking_figure([(r.name, r.mdee) for r in mine],
                                         [(m.name, S_mean(m.dee)) for m in P.style_models()], bench)))
        return
    series = [(r.name, {c.name: c.dee for c in r.scores.corruptions}) for r in mine]
    figs.append(("radar", "DEE per corruption", "Each model's DEE per corruption (mean over the "
                 "levels), the paper's Fig. 1 form; the grey dashed line is the baseline.",
                 F.radar_figure(series, bench, (base.name, base.dee))))
    pm = [plot.Model(r.name, r.scores) for r in mine]
    figs.append(("ce", "CE per corruption", "Corruption error per corruption against the "
                 "baseline's 100% (dashed).", plot.ce_figure(pm, bench)))
    figs.append(("levels", "DEE against level", "DEE at each level, one panel per corruption; "
                 "the grey dashed line is the baseline's published mean over the levels.",
                 F.levels_figure(pm, bench, (base.name, base.dee))))
    if any(r.scores.curves for r in mine):
        figs.append(("severity", "DEE against continuous severity", "Beyond the benchmark: DEE at "
                     "every level present, integer and decimal, for each corruption with decimal-level "
                     "rows; in no mCE or mRR.",
                     F.severity_figure([m for m in pm if m.scores.curves], bench)))
    points = [F.Point(r.name, r.clean, r.scores.overall.ce, r.scores.overall.rr) for r in mine]
    context = [F.Point(r.name, r.clean, r.scores.overall.ce, r.scores.overall.rr)
               for r in I.context(bench, "all")]
    figs.append(("summary", "mCE and mRR against clean DEE", "Your models (coloured) among "
                 "the paper's (grey).", F.summary_figure(points, context, bench)))


def S_mean(values: dict) -> float:
    from ..evaluation.results import mean

    return mean(values.values())


def to_json(report: Report) -> dict:
    """The versioned leaderboard entry (schema ``robodepth-report`` version 1, in
    docs/report.md): one object per model of the user's, nothing of the published ones."""
    doc = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "robodepth": __version__,
           "benchmark": report.benchmark, "dataset": report.dataset, "models": []}
    if report.benchmark != I.KITTI_S:
        b = report.models[0].row.scores.baseline
        doc["baseline"] = {"name": b.name, "clean_dee": b.clean, "dee": dict(b.dee)}
    for m in report.models:
        r = m.row
        entry = {"model": m.name, "results": str(m.path), "results_sha256": m.sha256,
                 "clean_dee": r.clean}
        if r.scores is not None:
            s = r.scores
            entry["scores"] = {"mce": s.overall.ce, "mrr": s.overall.rr, "mdee": s.overall.dee,
                               "categories": {g.name: {"mce": g.ce, "mrr": g.rr, "mdee": g.dee}
                                              for g in s.categories}}
            entry["corruptions"] = {c.name: {"category": c.category, "dee": c.dee, "ce": c.ce,
                                             "rr": c.rr,
                                             "levels": {str(lv): d for lv, d in c.level_dee.items()}}
                                    for c in s.corruptions}
            beyond = s.to_json().get("beyond_benchmark")
            if beyond:
                entry["beyond_benchmark"] = beyond
        else:
            entry["scores"] = {"mdee": r.mdee}
            entry["styles"] = {k: {"dee": v} for k, v in r.styles.items()}
        entry["variants"] = m.variants
        doc["models"].append(entry)
    doc["citation"] = {"text": P.CITATION, "url": P.CITATION_URL}
    return doc


def write(report: Report, out: Path, progress: Callable[[str], None] = lambda _: None) -> list[Path]:
    """Write every output of ``report`` under ``out``; return the paths written."""
    from ..evaluation import plot
    from ..files import write_atomic

    written: list[Path] = []
    page_figs = []
    for stem, title, caption, fig in report.figures:
        progress(f"figures/{stem}")
        paths = plot.save(fig, out / "figures" / stem)
        written += paths.values()
        page_figs.append(PageFigure(stem, title, caption, paths["svg"].read_text(encoding="utf-8")))
        plot.close(fig)
    context = "all"
    kinds = {r.kind for r in report.rows}
    if "published" not in kinds:
        context = "baseline" if "baseline" in kinds else "none"
    page = render_page(benchmark=report.benchmark, models=report.models, tables=report.tables,
                       figures=page_figs, dataset=report.dataset, context=context)
    head = (f"% RoboDepth report on {T.bench_name(report.benchmark)}, made by robodepth {__version__}.\n"
            "% Needs \\usepackage{booktabs} and \\usepackage{graphicx} (for \\resizebox).\n"
            f"% Published rows: {P.CITATION}.\n\n")
    # LaTeX: the paper's Table 1 and its per-corruption DEE table; Markdown adds CE and RR.
    # The per-level table (90 columns on KITTI-C) stays on the page and in scores.json.
    files = {"index.html": page,
             "table.tex": head + "\n".join(T.to_latex(t) for t in report.tables[:2]),
             "table.md": f"# RoboDepth report: {T.bench_name(report.benchmark)}\n\n"
                         + "\n".join(T.to_markdown(t) for t in report.tables[:4]),
             "scores.json": json.dumps(to_json(report), indent=2, allow_nan=False) + "\n"}
    for name, text in files.items():
        progress(name)
        write_atomic(out / name, text.encode("utf-8"))
        written.append(out / name)
    return written
