"""Make a report: score the inputs, draw the figures, write the page, tables and JSON (the
files and the ``scores.json`` schema of docs/report.md). OUT is written whole or not at
all: into a temporary folder, then moved into place; an earlier report's figures that this
one does not draw are removed, so nothing stale is left."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from .. import __version__
from ..formats import stamp
from ..errors import RobodepthError, counted
from ..evaluation.csvrows import ResultsTable
from . import inputs
from . import published as published_mod
from . import flicker as FL
from . import tables as tables_mod
from .page import PageFigure
from .page import render as render_page

SCHEMA = "robodepth-report"  # its version: robodepth_cli/formats.py


@dataclass
class Report:
    benchmark: str
    models: list[inputs.Model]
    rows: list[inputs.Row]  # the user's, then the published context
    tables: list[tables_mod.Table]
    figures: list[tuple[str, str, str, object]] = field(default_factory=list)  # stem, title, caption, Figure
    dataset: dict | None = None
    note: str = ""  # why there is no mCE, mRR or mDEE (results beyond the benchmark only)
    # Results of several datasets: a section per dataset beyond the main benchmark, the
    # table across them, and synthetic against real where the pairs table resolves.
    sections: list = field(default_factory=list)
    entries: list = field(default_factory=list)
    across: tables_mod.Table | None = None
    synreal: list = field(default_factory=list)
    synreal_setup: dict = field(default_factory=dict)
    flicker: list = field(default_factory=list)  # flicker.Flicker per model with the columns


FIGURES = "figures"


def check_writable(out: Path) -> None:
    """Refuse, before any work, an OUT in which the report could not be written: by
    creating there what :func:`write` creates (a folder beside a new OUT, a file in an
    existing one), since permission bits do not tell (root, read-only mounts, /proc)."""
    from ..files import check_writable as check

    if out.exists() and not out.is_dir():
        raise RobodepthError(f"--out {out}: exists and is not a directory")
    if (out / FIGURES).exists() and not (out / FIGURES).is_dir():
        raise RobodepthError(f"--out {out}: {out / FIGURES} exists and is not a directory")
    check(out / "index.html" if out.is_dir() else out, "--out")


def assemble(tables: Sequence[ResultsTable], names: Sequence[str], benchmark: str | None, context: str,
             dataset: Path | None = None, *, on: Sequence[str] = (), pairs: Sequence[Path] = (),
             baseline: str | None = None, metric: str = "dee", n_boot: int = 2000,
             seed: int = 0, n_pred: int = 0) -> Report:
    """Check and score every results table (no figure yet). Results of one of the paper's
    benchmarks make the report as before; results of several datasets add a section per
    dataset beyond the first of the paper's (or per dataset, with none of them), a table
    across the datasets and, where the pairs table resolves, synthetic against real."""
    from . import datasets
    from . import synreal as synreal_mod

    keys = datasets.keys_of(tables, on, benchmark)
    if len(set(keys)) == 1 and keys[0][0] in datasets.PUBLISHED and not keys[0][1]:
        inputs.model_names([Path(t.source) for t in tables], names)  # flag mistakes first
        bench = keys[0][0]
        report = _main(bench, inputs.load(tables, names, bench), context,
                       inputs.dataset_info(dataset, bench) if dataset is not None else None)
        if baseline is not None:
            raise RobodepthError(f"--baseline: {bench} has a published baseline; --baseline names "
                                 "the model to score datasets without one against")
        return report
    entries = datasets.load(tables, names, keys, baseline)
    by_key = datasets.groups(entries)
    main = next((k for k in by_key if k[0] in datasets.PUBLISHED and not k[1]), None)
    if n_pred and main is None:
        raise RobodepthError("--pred: the report has no results on kitti-c, nyudepth2-c or "
                             "kitti-s for its qualitative figure")
    if main is not None and n_pred > len(by_key[main]):
        raise RobodepthError(f"--pred given {counted(n_pred, 'time')} for "
                             f"{counted(len(by_key[main]), 'results file')} on "
                             f"{main[0]}; give it at most once per file on it, in the same order")
    if main is not None:
        report = _main(main[0], [e.model for e in by_key[main]], context,
                       inputs.dataset_info(dataset, main[0]) if dataset is not None else None)
    else:
        if dataset is not None:
            raise RobodepthError("--dataset: the report has no results on kitti-c, nyudepth2-c "
                                 "or kitti-s to record it with")
        report = Report(keys[0][0], [], [], [])
    report.sections = [datasets.section(k, es, context) for k, es in by_key.items() if k != main]
    report.entries = entries
    report.across = datasets.across(entries) if len(by_key) > 1 else None
    models = list(dict.fromkeys(e.name for e in entries))
    found = {(e.name, e.key): e for e in entries}

    def value(model, key, corruption):
        e = found.get((model, key))
        return None if e is None else e.value(corruption, metric)

    report.synreal = synreal_mod.compare(models, synreal_mod.read_pairs([synreal_mod.PAIRS, *pairs]), value, metric, n_boot, seed)
    report.synreal_setup = {"metric": metric, "resamples": n_boot, "seed": seed}
    return report


def _main(bench: str, models: list[inputs.Model], context: str, info: dict | None) -> Report:
    """The report of one of the paper's benchmarks: its tables (figures: :func:`draw`),
    and the flicker of the models whose results have it."""
    rows = [m.row for m in models] + inputs.context(bench, context)
    note = inputs.beyond_only(models)
    if note:  # no benchmark score: the clean DEE and the rows beyond it, yours only
        return Report(bench, models, [m.row for m in models],
                      [tables_mod.beyond_table([m.row for m in models], bench, clean=True)], dataset=info, note=note,
                      flicker=FL.collect(models))
    if bench == inputs.KITTI_S:
        tables = [tables_mod.styles_table(rows)]
    else:
        tables = [tables_mod.summary_table(rows, bench), tables_mod.corruption_table(rows, bench, "dee"),
                  tables_mod.corruption_table(rows, bench, "ce"), tables_mod.corruption_table(rows, bench, "rr"),
                  tables_mod.levels_table([m.row for m in models], bench)]
        beyond = tables_mod.beyond_table([m.row for m in models], bench)
        if beyond is not None:
            tables.append(beyond)
    return Report(bench, models, rows, tables, dataset=info, flicker=FL.collect(models))


def draw(report: Report) -> None:
    """Add the figures (matplotlib is imported here, not before): the main benchmark's,
    then synthetic against real."""
    from . import figures as figures_mod
    from .synreal import METRICS

    if report.models:
        _draw_main(report)
    if report.flicker:
        report.figures.append(FL.figure_entry(report.flicker, report.benchmark))
    if report.synreal:
        metric = METRICS[report.synreal_setup["metric"]]
        report.figures.append((
            "synthetic-real", "Synthetic against real",
            f"Each model's {metric} on a synthetic corruption (mean over its levels) against its "
            f"{metric} on the real condition's clean images, one panel per pair of the pairs "
            "table; Spearman's ρ and Kendall's τ of the two rankings, ρ with its 95% bootstrap "
            "interval over the models.", figures_mod.synreal_figure(report.synreal, metric)))


def _draw_main(report: Report) -> None:
    from . import plot
    from . import figures as figures_mod

    bench, models = report.benchmark, report.models
    base = published_mod.baseline(bench)
    mine = [m.row for m in models]
    figs = report.figures
    if bench == inputs.KITTI_S:
        from ..evaluation.results import mean

        figs.append(("radar", "DEE per style", "Each model's DEE for each KITTI-S style; the "
                     "grey dashed line is the paper's baseline.",
                     figures_mod.radar_figure([(r.name, r.styles) for r in mine], bench,
                                       (base.name, base.dee), what="style")))
        figs.append(("styles", "DEE per style, as bars", "Each style's DEE per model, with the "
                     "published baseline for reference.",
                     figures_mod.styles_figure([(r.name, r.styles) for r in mine], bench,
                                        (base.name, base.dee))))
        figs.append(("ranking", "mDEE ranking", "Your models among the paper's KITTI-S models, "
                     "ranked by mDEE.",
                     figures_mod.ranking_figure([(r.name, r.mdee) for r in mine],
                                         [(m.name, mean(m.dee.values())) for m in published_mod.style_models()], bench)))
        return
    pm = [plot.Model(r.name, r.scores) for r in mine]
    if report.note:
        if any(r.scores.curves for r in mine):
            figs.append(_severity(pm, bench))
        return
    series = [(r.name, {c.name: c.dee for c in r.scores.corruptions}) for r in mine]
    figs.append(("radar", "DEE per corruption", "Each model's DEE per corruption (mean over the "
                 "levels), the paper's Fig. 1 form; the grey dashed line is the baseline.",
                 figures_mod.radar_figure(series, bench, (base.name, base.dee))))
    figs.append(("ce", "CE per corruption", "Corruption error per corruption against the "
                 "baseline's 100% (dashed).", plot.ce_figure(pm, bench)))
    figs.append(("levels", "DEE against level", "DEE at each level, one panel per corruption; "
                 "the grey dashed line is the baseline's published mean over the levels.",
                 figures_mod.levels_figure(pm, bench, (base.name, base.dee))))
    if any(r.scores.curves for r in mine):
        figs.append(_severity(pm, bench))
    points = [figures_mod.Point(r.name, r.clean, r.scores.overall.ce, r.scores.overall.rr) for r in mine]
    context = [figures_mod.Point(r.name, r.clean, r.scores.overall.ce, r.scores.overall.rr)
               for r in inputs.context(bench, "all")]
    figs.append(("summary", "mCE and mRR against clean DEE", "Your models (coloured) among "
                 "the paper's (grey).", figures_mod.summary_figure(points, context, bench)))


def _severity(pm: list, bench: str) -> tuple:
    from . import figures as figures_mod

    return ("severity", "DEE against continuous severity", "Beyond the benchmark: DEE at "
            "every level present, integer and decimal, for each corruption with decimal-level "
            "rows; in no mCE or mRR.", figures_mod.severity_figure([m for m in pm if m.scores.curves], bench))


def to_json(report: Report) -> dict:
    """The versioned leaderboard entry (schema ``robodepth-report`` version 1, in
    docs/report.md): one object per model of the user's, nothing of the published ones."""
    doc = {**stamp(SCHEMA),
           "benchmark": report.benchmark if report.models else None, "dataset": report.dataset,
           "models": []}
    if report.note:
        doc["note"] = report.note
    if report.benchmark != inputs.KITTI_S and not report.note and report.models:
        b = report.models[0].row.scores.baseline
        doc["baseline"] = {"name": b.name, "clean_dee": b.clean, "dee": dict(b.dee)}
    for m in report.models:
        r = m.row
        entry = {"model": m.name, "results": str(m.path), "results_sha256": m.sha256,
                 "severity_size": m.severity_size, "clean_dee": r.clean}
        if report.note:
            entry["beyond_benchmark"] = r.scores.to_json()["beyond_benchmark"]
        elif r.scores is not None:
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
        fl = next((f for f in report.flicker if f.model == m.name), None)
        if fl is not None:
            entry["flicker"] = fl.to_json()
        doc["models"].append(entry)
    if report.sections:
        doc["datasets"] = [_section_json(sec, report) for sec in report.sections]
    if report.synreal:
        setup = report.synreal_setup
        doc["synthetic_vs_real"] = [c.to_json(setup["resamples"], setup["seed"]) for c in report.synreal]
    doc["citation"] = {"text": published_mod.CITATION, "url": published_mod.CITATION_URL}
    return doc


def _section_json(sec, report: Report) -> dict:
    """A dataset beyond the main benchmark: each model's clean errors, its scores where the
    dataset has corruptions, and its rows as written."""
    from ..benchmark_facts import CLEAN

    models = []
    for e in (e for e in report.entries if e.key == sec.key):
        clean = next(v for v in e.variants if v["corruption"] == CLEAN and v["level"] == 0)
        scores = e.scores or (e.model.row.scores if e.model is not None else None)
        models.append({
            "model": e.name, "results": str(e.path), "results_sha256": e.sha256,
            "severity_size": e.severity_size,
            "clean": {"dee": e.value(None, "dee"), "abs_rel": clean.get("abs_rel"), "a1": clean.get("a1")},
            "scores": None if scores is None or scores.note else {
                "mce": scores.overall.ce if scores.baseline.name else None,
                "mrr": scores.overall.rr, "mdee": scores.overall.dee,
                "baseline": scores.baseline.name or None},
            "variants": e.variants})
    return {"dataset": sec.key[0], "split": sec.key[1] or None, "models": models}


@dataclass
class Written:
    """What :func:`write` left under OUT: the files of this report, and those of an
    earlier report there that it removed (figures it does not draw)."""

    files: list[Path]
    removed: list[Path]


def write(report: Report, out: Path, progress: Callable[[str], None] = lambda _: None,
          published: Callable[[], None] = lambda: None) -> Written:
    """Write every output of ``report`` under ``out``, whole or not at all (an interrupt or
    a write error leaves ``out`` as it was); :class:`~robodepth_cli.errors.RobodepthError` when a file cannot be
    written. ``published`` is called once the report is in place, before an interrupt
    held meanwhile acts (so the command can say what an interrupt leaves)."""
    import shutil
    import tempfile

    from ..errors import cannot_write
    from ..files import atomic_directory

    try:
        with _Publishing(published) as publishing:
            if not out.is_dir() or not any(out.iterdir()):
                with atomic_directory(out) as stage:
                    names = _write_into(report, stage, progress)
                    publishing.start()  # the rename, at the end of this block
                return Written([out / n for n in names], [])
            # An earlier report (or the user's files) is there: stage inside OUT (same file
            # system, and only OUT need be writable), then move the new files over the old.
            stage = Path(tempfile.mkdtemp(prefix=".report.", suffix=".part", dir=out))
            try:
                names = _write_into(report, stage, progress)
                publishing.start()
                removed = _replace(stage, out, names)
            finally:
                shutil.rmtree(stage, ignore_errors=True)
    except OSError as exc:
        raise RobodepthError(cannot_write(out, exc, "--out")) from None
    return Written([out / n for n in names], removed)


def _replace(stage: Path, out: Path, names: list[str]) -> list[Path]:
    """Move the staged report into ``out``: the files over the earlier ones, ``figures/``
    as a whole; return the earlier figures that are gone. Anything of the user's in the old
    ``figures/`` (not a figure file) is moved into the new one."""
    import os

    removed: list[Path] = []
    old = out / FIGURES
    if old.is_dir():
        os.replace(old, stage / ".old-figures")
        for f in sorted((stage / ".old-figures").iterdir()):
            if f.name in {Path(n).name for n in names if n.startswith(FIGURES + "/")}:
                continue
            if f.is_file() and f.suffix in (".svg", ".pdf", ".png"):
                removed.append(old / f.name)
            else:
                os.replace(f, stage / FIGURES / f.name)
    for n in names:
        if "/" not in n:
            os.replace(stage / n, out / n)
    os.replace(stage / FIGURES, old)
    return removed


class _Publishing:
    """From :meth:`start` to the end of the ``with`` block, Ctrl-C and SIGTERM are held, so
    an interrupt never leaves half of a new report beside half of an old one, nor a report
    in place after "nothing was written"; ``published`` is called when the block ends
    without error, then a held interrupt acts. (Python-level handlers, not a signal mask:
    a mask holds a signal from one thread only, and any other thread would take it.)"""

    def __init__(self, published: Callable[[], None]):
        self.published, self.previous, self.caught = published, {}, False

    def __enter__(self):
        return self

    def start(self) -> None:
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._hold)

    def _hold(self, signum, frame) -> None:
        self.caught = True

    def __exit__(self, kind, *_):
        import signal

        for sig, handler in self.previous.items():
            # None: a handler set outside Python, which cannot be put back; the default then.
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        if kind is None:
            self.published()
            if self.caught:
                raise KeyboardInterrupt
        return False


def _write_into(report: Report, out: Path, progress: Callable[[str], None]) -> list[str]:
    """Write every output of ``report`` into the empty folder ``out``; return their paths
    relative to it."""
    from . import plot
    from ..files import write_atomic

    written: list[str] = []
    page_figs = []
    for stem, title, caption, fig in report.figures:
        progress(f"{FIGURES}/{stem}")
        paths = plot.save(fig, out / FIGURES / stem)
        written += [f"{FIGURES}/{p.name}" for p in paths.values()]
        page_figs.append(PageFigure(stem, title, caption, paths["svg"].read_text(encoding="utf-8")))
        plot.close(fig)
    (out / FIGURES).mkdir(exist_ok=True)  # a report of no figure still replaces an old figures/
    context = "all"
    kinds = {r.kind for r in report.rows}
    if "published" not in kinds:
        context = "baseline" if "baseline" in kinds else "none"
    extra = [(sec.title, sec.tables, [(e.name, str(e.path), e.severity_size)
                                      for e in report.entries if e.key == sec.key])
             for sec in report.sections]
    if report.flicker:
        extra.append(("Flicker", FL.tables(report.flicker, report.benchmark), []))
    if report.across is not None:
        extra.append(("Across datasets", [report.across], []))
    if report.synreal:
        from .synreal import tables as synreal_tables

        extra.append(("Synthetic against real", synreal_tables(report.synreal), []))
    page = render_page(benchmark=report.benchmark, models=report.models, tables=report.tables,
                       figures=page_figs, dataset=report.dataset, context=context, note=report.note,
                       sections=extra)
    head = (f"% RoboDepth report on {tables_mod.bench_name(report.benchmark)}, made by robodepth {__version__}.\n"
            "% Needs \\usepackage{booktabs} and \\usepackage{graphicx} (for \\resizebox).\n"
            f"% Published rows: {published_mod.CITATION}.\n"
            + (f"% {report.note[0].upper()}{report.note[1:]}.\n" if report.note else "") + "\n")
    # LaTeX: the paper's Table 1 and its per-corruption DEE table; Markdown adds CE and RR.
    # The per-level table (90 columns on KITTI-C) stays on the page and in scores.json.
    more = [t for _, ts, _ in extra for t in ts]
    files = {"index.html": page,
             "table.tex": head + "\n".join(tables_mod.to_latex(t) for t in report.tables[:2] + more),
             "table.md": f"# RoboDepth report: {tables_mod.bench_name(report.benchmark)}\n\n"
                         + (f"{report.note[0].upper()}{report.note[1:]}.\n\n" if report.note else "")
                         + "\n".join(tables_mod.to_markdown(t) for t in report.tables[:4] + more),
             "scores.json": json.dumps(to_json(report), indent=2, allow_nan=False) + "\n"}
    for name, text in files.items():
        progress(name)
        write_atomic(out / name, text.encode("utf-8"))
        written.append(name)
    return written
