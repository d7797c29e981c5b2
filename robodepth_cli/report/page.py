"""The report's one HTML page: self-contained (inline CSS, figures inline as SVG, no script,
no font or stylesheet fetched), so it opens from ``file://`` and from a mail attachment."""

from __future__ import annotations

import html
import re
from dataclasses import dataclass
from typing import Sequence

from .. import __version__
from . import published
from .tables import Table, bench_name, mixed_note, to_html

CSS = """
:root { --ink:#1e1e1e; --muted:#666; --rule:#d0d0d0; --mine:#eef5fb; --context:#8a8a8a; }
* { box-sizing: border-box; }
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif;
       color: var(--ink); margin: 0; background: #fff; }
main { max-width: 1320px; margin: 0 auto; padding: 24px 28px 60px; }
h1 { font-size: 1.6em; margin: 0 0 4px; }
h2 { font-size: 1.2em; margin: 36px 0 10px; border-bottom: 1px solid var(--rule); padding-bottom: 4px; }
p.meta, p.note, p.caption, figcaption { color: var(--muted); font-size: 0.9em; }
ul.models { padding-left: 1.2em; }
ul.models code { font-size: 0.85em; }
.scroll { overflow-x: auto; margin: 8px 0 4px; }
p.caption { margin: 14px 0 0; }
table.scores { border-collapse: collapse; font-size: 12.5px; font-variant-numeric: tabular-nums; }
table.scores th, table.scores td { padding: 2px 6px; text-align: right; white-space: nowrap; }
table.scores th.model { text-align: left; }
table.scores thead th { border-bottom: 1px solid var(--ink); font-weight: 600; }
table.scores thead th.nogroup { border-bottom: none; }
table.scores thead th.group { border-bottom: 1px solid var(--rule); text-align: center; }
table.scores thead tr:first-child th { border-top: 2px solid var(--ink); }
table.scores tbody:last-of-type tr:last-child > * { border-bottom: 2px solid var(--ink); }
table.scores tbody.yours tr { background: var(--mine); }
table.scores tbody.published tr.published, table.scores tbody.published tr.baseline { color: var(--context); }
table.scores tbody.published th.model { font-weight: normal; }
table.scores tr.section th { text-align: left; font-weight: 600; color: var(--muted);
       border-top: 1px solid var(--ink); padding-top: 8px; font-style: italic; }
td.best { font-weight: 700; }
td.second { text-decoration: underline; }
span.tag { font-size: 0.78em; border: 1px solid var(--context); border-radius: 3px;
       padding: 0 4px; margin-left: 4px; font-weight: normal; }
figure { margin: 18px 0 28px; }
figure svg { max-width: 100%; height: auto; display: block; }
figcaption a { color: inherit; }
pre.bib { background: #f6f6f6; padding: 10px; font-size: 12px; overflow-x: auto; }
"""


@dataclass(frozen=True)
class PageFigure:
    stem: str
    title: str
    caption: str
    svg: str  # the SVG document as matplotlib wrote it


def inline_svg(svg: str, prefix: str, label: str = "") -> str:
    """An SVG document as an element of the page: no XML prolog or doctype, sized by CSS,
    and every id (and reference to one) prefixed, so two figures' ids cannot collide."""
    svg = re.sub(r"^\s*<\?xml[^>]*\?>\s*", "", svg)
    svg = re.sub(r"<!DOCTYPE[^>]*>\s*", "", svg, flags=re.S)
    svg = re.sub(r"\s*<metadata>.*?</metadata>", "", svg, flags=re.S)
    svg = re.sub(r'\bid="([^"]+)"', lambda m: f'id="{prefix}-{m.group(1)}"', svg)
    svg = re.sub(r'url\(#([^)]+)\)', lambda m: f"url(#{prefix}-{m.group(1)})", svg)
    svg = re.sub(r'href="#([^"]+)"', lambda m: f'href="#{prefix}-{m.group(1)}"', svg)
    svg = re.sub(r"<svg\b", f'<svg role="img" aria-label="{html.escape(label)}"', svg, count=1)
    return svg


def render(*, benchmark: str, models: Sequence, tables: Sequence[Table], figures: Sequence[PageFigure],
           dataset: dict | None, context: str, note: str = "",
           sections: Sequence[tuple[str, Sequence[Table], Sequence[tuple[str, str]]]] = ()) -> str:
    """The page: title, the models and their files, the summary table, the figures, the
    per-corruption tables, then each of ``sections`` (a heading, its tables and the
    (model, results file) pairs they come from: other datasets, synthetic against real),
    notes on the scores and the paper to cite."""
    e = html.escape
    bname = bench_name(benchmark) if tables else "several datasets"
    names = ", ".join(dict.fromkeys([m.name for m in models]
                                    + [n for *_, files in sections for n, *_ in files]))
    n_files = len(models) + sum(len(files) for *_, files in sections)
    parts = ["<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             # No request may leave the page: not even the browser's favicon probe.
             '<link rel="icon" href="data:,">',
             f"<title>RoboDepth report: {e(names)} on {e(bname)}</title>",
             f"<style>{CSS}</style>", "</head>", "<body>", "<main>",
             f"<h1>RoboDepth robustness report: {e(bname)}</h1>",
             f'<p class="meta">Made by robodepth {e(__version__)} from {n_files} results '
             f"file{'s' if n_files != 1 else ''}. Your models are shaded; grey rows are the "
             "RoboDepth paper's published models, for context.</p>",
             *_model_items(models)]
    if dataset:
        parts.append(f'<p class="meta">Dataset build: <code>{e(dataset["path"])}</code> '
                     f'({e(str(dataset["name"]))}, {dataset["images"]} images, seed '
                     f'{e(str(dataset["seed"]))}), fingerprint <code>{e(dataset["fingerprint"][:16])}</code>.</p>')
    tables = list(tables)
    if tables:
        parts += ["<h2>Scores</h2>", to_html(tables[0])]
        if note:
            parts.append(f'<p class="note">{e(note[0].upper() + note[1:])}.</p>')
        elif context != "all":
            parts.append(f'<p class="note">Published rows shown: {e(context)} (--published).</p>')
    if figures:
        parts.append("<h2>Figures</h2>")
    parts += [_figure_html(f) for f in figures]
    if len(tables) > 1:
        parts.append("<h2>Per corruption</h2>" if benchmark != "kitti-s" else "<h2>Per style</h2>")
        for t in tables[1:]:
            parts.append(to_html(t))
    for title, more, files in sections:
        parts.append(f"<h2>{e(title)}</h2>")
        if files:
            parts.append('<ul class="models">' + "".join(
                f"<li><strong>{e(n)}</strong>: <code>{e(p)}</code>"
                + "".join(f", severity size {e(x)}" for x in more) + "</li>"
                for n, p, *more in files) + "</ul>")
        parts += [to_html(t) for t in more]
    parts += ["<h2>How the scores are computed</h2>", f'<p class="note">{NOTES}</p>',
              '<p class="note">Published rows are scored from the paper\'s per-corruption DEE '
              "and clean DEE by the same code as <code>robodepth score</code>; where the paper "
              "is inconsistent (see the package's published/README.md) they can differ from its "
              "printed summary.</p>",
              "<h2>Cite</h2>", f"<p>{e(published.CITATION)}. {e(published.CITATION_URL)}</p>",
              f'<pre class="bib">{e(published.BIBTEX)}</pre>', "</main>", "</body>", "</html>"]
    return "\n".join(parts) + "\n"


def _model_items(models: Sequence) -> list[str]:
    """The list of the models: each one's results file, clean DEE and severity size, and its
    warning if any; then a note when their severity sizes differ."""
    e = html.escape
    items = ['<ul class="models">']
    for m in models:
        clean = "" if m.row.clean is None else f", clean DEE {m.row.clean:.3f}"
        items.append(f"<li><strong>{e(m.name)}</strong>: <code>{e(str(m.path))}</code>{clean}, "
                     f"severity size {e(m.severity_size)}</li>")
        if getattr(m, "own_depth", ""):
            items.append(f'<li class="note">Warning: {e(m.own_depth)}.</li>')
    items.append("</ul>")
    mixed = mixed_note(m.severity_size for m in models)
    if mixed:
        items.append(f'<p class="note">{e(mixed)}.</p>')
    return items


def _figure_html(f: PageFigure) -> str:
    """A figure inline, with links to its SVG, PDF and PNG files."""
    e = html.escape
    links = " ".join(f'<a href="figures/{e(f.stem)}.{ext}">{ext.upper()}</a>'
                     for ext in ("svg", "pdf", "png"))
    return (f'<figure id="fig-{e(f.stem)}" class="figure">'
            f'<div class="svg">{inline_svg(f.svg, "fig-" + f.stem, f.title)}</div>'
            f"<figcaption><strong>{e(f.title)}.</strong> {e(f.caption)} ({links})</figcaption>"
            "</figure>")


NOTES = html.escape(
    "DEE = (abs_rel - a1 + 1) / 2 per variant. CE of a corruption = its DEE averaged over the "
    "levels, divided by the baseline's, in percent; RR = mean over the levels of (1 - DEE), "
    "divided by (1 - clean DEE), in percent. mCE, mRR and mDEE average CE, RR and DEE over the "
    "corruptions (a category's, over its corruptions). KITTI-S: mDEE is the mean DEE over the "
    "12 styles.")
