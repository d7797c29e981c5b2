"""Every figure robodepth draws, with matplotlib: the CE bar chart of ``robodepth score
--plot`` and the figures of ``robodepth report``.

matplotlib is the ``figures`` extra (``pip install 'robodepth-cli[figures]'``); nothing
else imports this module, so a build or a plain ``score`` never loads it. Figures are made
with the object-oriented API (:class:`matplotlib.figure.Figure`, no pyplot), so drawing
one changes no global state of a program that also uses matplotlib.

Conventions every figure follows: colours from the Okabe-Ito palette (distinguishable
with the common colour-vision deficiencies), a marker and a line style per model as well
(so print in grey still tells models apart), the benchmark and the model(s) named in the
title or legend, and text placed where it crosses no line and no other text (labels of
points are placed by :func:`place_labels`, which drops a context label rather than let it
overlap).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..benchmarks import CATEGORIES
from ..errors import RobodepthError
from .scores import Scores

# Okabe & Ito (2008), "Color Universal Design"; the yellow is last, it is faint on white.
OKABE_ITO = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000",
             "#F0E442")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
LINESTYLES = ("-", "--", "-.", ":")
# One colour per category, in CATEGORIES order (Okabe-Ito blue, orange, bluish green).
COLOURS = {cat: c for cat, c in zip(CATEGORIES, ((0, 114, 178), (230, 159, 0), (0, 158, 115)))}
CONTEXT = "#9a9a9a"  # published models, the baseline: context, not the subject
INK = "#1e1e1e"
MUTED = "#666666"
FORMATS = ("svg", "pdf", "png")
PNG_DPI = 150

BENCHMARK_TITLE = {"kitti-c": "KITTI-C", "nyudepth2-c": "NYUDepth2-C", "kitti-s": "KITTI-S"}


class FiguresUnavailable(RobodepthError):
    """matplotlib (the ``figures`` extra) is not installed."""


def _mpl():
    try:
        import matplotlib
    except ImportError:
        raise FiguresUnavailable("figures need matplotlib: pip install 'robodepth-cli[figures]' "
                                 "(or pip install matplotlib)") from None
    # Text stays text in SVG (searchable, and the page's fonts apply); the same figure
    # gives the same bytes (no random ids, no date).
    matplotlib.rcParams.update({"svg.fonttype": "none", "svg.hashsalt": "robodepth",
                                "pdf.fonttype": 42, "font.size": 10,
                                "axes.titlesize": 10, "axes.labelsize": 10})
    return matplotlib


def _figure(width: float, height: float):
    _mpl()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)  # a renderer to measure text with (label placement)
    return fig


def style(i: int) -> dict:
    """Line/marker style of the ``i``-th model (colour, marker, line style)."""
    return {"color": OKABE_ITO[i % len(OKABE_ITO)], "marker": MARKERS[i % len(MARKERS)],
            "linestyle": LINESTYLES[(i // len(OKABE_ITO)) % len(LINESTYLES)]}


def pretty(name: str) -> str:
    """``defocus_blur`` -> ``defocus blur`` (labels on figures)."""
    return name.replace("_", " ")


def bench_title(name: str) -> str:
    return BENCHMARK_TITLE.get(name, name)


@dataclass(frozen=True)
class Model:
    """A model as the figures see it: its name and its scores."""

    name: str
    scores: Scores


# --------------------------------------------------------------------------- saving

def render(fig, fmt: str) -> bytes:
    """The bytes of ``fig`` as ``fmt`` (svg, pdf or png). SVG and PDF carry no date, so the
    same figure gives the same file."""
    buf = io.BytesIO()
    metadata = {"svg": {"Date": None}, "pdf": {"CreationDate": None, "ModDate": None}}.get(fmt)
    fig.savefig(buf, format=fmt, dpi=PNG_DPI, metadata=metadata, facecolor="white")
    return buf.getvalue()


def save(fig, stem: Path, formats: Sequence[str] = FORMATS) -> dict[str, Path]:
    """Write ``fig`` as ``stem.<fmt>`` for each format (atomically); return fmt -> path."""
    from ..files import write_atomic

    written = {}
    for fmt in formats:
        path = stem.with_name(f"{stem.name}.{fmt}")
        write_atomic(path, render(fig, fmt))
        written[fmt] = path
    return written


# --------------------------------------------------------------------------- label placement

def _overlaps(a, b, pad: float = 3.0) -> bool:
    return not (a.x1 + pad <= b.x0 or b.x1 + pad <= a.x0 or a.y1 + pad <= b.y0 or b.y1 + pad <= a.y0)


def _points_to_px(fig, pts: float) -> float:
    return pts * fig.dpi / 72.0


# Offsets (in points) tried for a point's label, nearest first: right, left, above, below,
# then the diagonals, then the same further out.
_OFFSETS = ((7, 0), (-7, 0), (0, 7), (0, -7), (6, 5), (-6, 5), (6, -5), (-6, -5))


def _text_box(ann, renderer):
    # The text alone: an annotation's own extent includes its leader line, which starts at
    # the point and so always "overlaps" the point's marker.
    from matplotlib.text import Text

    ann.update_positions(renderer)
    return Text.get_window_extent(ann, renderer)


def _segment_clear(p0, p1, boxes, skip) -> bool:
    """Whether the straight segment p0-p1 (display coordinates) misses every box but ``skip``."""
    for k in range(1, 24):
        t = k / 24
        x, y = p0[0] + (p1[0] - p0[0]) * t, p0[1] + (p1[1] - p0[1]) * t
        for b in boxes:
            if b is not skip and b.x0 <= x <= b.x1 and b.y0 <= y <= b.y1:
                return False
    return True


def place_labels(ax, labels, obstacles=(), *, renderer=None) -> list:
    """Label points without overlap.

    ``labels`` is a list of ``(x, y, text, kwargs, required)`` in data coordinates, most
    important first. Each label is tried at the offsets of ``_OFFSETS`` (nearest first) and
    kept at the first where its box overlaps no earlier label, no point of ``labels``, no
    box of ``obstacles`` (display-coordinate bounding boxes, e.g. of lines) and stays inside
    the axes. A label that fits nowhere near is dropped when not ``required``; a required
    one goes to the nearest free spot further out, joined to its point by a thin leader line
    that crosses no other label or point. Returns the texts placed.
    """
    from matplotlib.transforms import Bbox

    fig = ax.figure
    renderer = renderer or fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    marker_r = _points_to_px(fig, 4.5)
    taken = list(obstacles)
    own = []
    for x, y, *_ in labels:
        px, py = ax.transData.transform((x, y))
        own.append(Bbox.from_extents(px - marker_r, py - marker_r, px + marker_r, py + marker_r))
    taken += own
    placed = []

    def fits(box) -> bool:
        return (box.x0 >= frame.x0 + 2 and box.x1 <= frame.x1 - 2 and box.y0 >= frame.y0 + 2
                and box.y1 <= frame.y1 - 2 and not any(_overlaps(box, t) for t in taken))

    for (x, y, text, kwargs, required), marker in zip(labels, own):
        ann = None
        for dx, dy in _OFFSETS:
            ha = "left" if dx > 0 else "right" if dx < 0 else "center"
            va = "bottom" if dy > 0 else "top" if dy < 0 else "center"
            ann = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset points",
                              ha=ha, va=va, **kwargs)
            if fits(_text_box(ann, renderer)):
                break
            ann.remove()
            ann = None
        if ann is None and required:
            ann = _leader_label(ax, x, y, text, kwargs, taken, marker, fits, renderer)
        if ann is not None:
            taken.append(_text_box(ann, renderer))
            placed.append(ann)
    return placed


def _leader_label(ax, x, y, text, kwargs, taken, marker, fits, renderer):
    px, py = ax.transData.transform((x, y))
    for r in range(24, 420, 10):
        for angle in range(0, 360, 15):
            dx, dy = r * math.cos(math.radians(angle)), r * math.sin(math.radians(angle))
            ann = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset pixels",
                              ha="left" if dx >= 0 else "right", va="center",
                              arrowprops={"arrowstyle": "-", "color": MUTED, "lw": 0.6,
                                          "shrinkA": 1, "shrinkB": 5}, **kwargs)
            box = _text_box(ann, renderer)
            if fits(box) and _segment_clear((px, py), (px + dx, py + dy), taken, marker):
                return ann
            ann.remove()
    return None


def _freeze_layout(fig):
    """Run the constrained layout once and keep it: labels placed afterwards are measured
    where they will be drawn."""
    fig.canvas.draw()
    fig.set_layout_engine("none")
    return fig.canvas.get_renderer()


def _legend(fig, handles=None, labels=None):
    """A legend under the plot with as many columns as fit the figure's width (a legend
    wider than the figure would be cut off at both sides)."""
    if handles is None:
        handles, labels = [], []
        for ax in fig.axes:
            for h, lab in zip(*ax.get_legend_handles_labels()):
                if lab not in labels:
                    handles.append(h)
                    labels.append(lab)
    width_pt = fig.get_figwidth() * 72 * 0.94
    entry_pt = max(len(lab) for lab in labels) * 0.58 * 10 + 48  # text + marker + gaps
    ncols = max(1, min(len(labels), int(width_pt // entry_pt)))
    return fig.legend(handles, labels, loc="outside lower center", ncols=ncols, frameon=False)


def _title(fig, title: str, subtitle: str = ""):
    fig.suptitle(title + (f"\n{subtitle}" if subtitle else ""), fontsize=11, color=INK)


# --------------------------------------------------------------------------- CE per corruption

def ce_figure(models: Sequence[Model], benchmark: str):
    """CE per corruption (horizontal bars, grouped by category) against the baseline's 100%
    line. One model: bars coloured by category with their values; several: one bar per
    model in each corruption's group, coloured by model."""
    first = models[0].scores
    names = [c.name for c in first.corruptions]
    single = len(models) == 1
    per_group = len(models)
    band = 0.8
    bar_h = band / per_group
    # y positions: corruptions top to bottom, a gap and a heading row between categories.
    rows, y, cat_heads = {}, 0.0, []
    for cat in CATEGORIES:
        members = [c.name for c in first.corruptions if c.category == cat]
        if not members:
            continue
        cat_heads.append((cat, y))
        y += 1.0
        for n in members:
            rows[n] = y
            y += 1.0
        y += 0.4
    height = 1.4 + 0.19 * y * max(1.0, 0.55 * per_group)
    fig = _figure(8.0, height)
    ax = fig.add_subplot()
    values = [c.ce for m in models for c in m.scores.corruptions if c.ce is not None]
    xmax = max(125.0, 25.0 * (math.floor(max(values, default=0.0) / 25.0) + 1))
    notes = []  # (CE, y, text) of the values written at the bar ends
    for i, m in enumerate(models):
        by_name = {c.name: c for c in m.scores.corruptions}
        for n in names:
            c = by_name[n]
            yc = rows[n] - band / 2 + bar_h * (i + 0.5)
            if c.ce is None:
                ax.text(2, yc, "n/a (missing)", va="center", fontsize=8, color=MUTED)
                continue
            colour = _rgb(COLOURS[c.category]) if single else style(i)["color"]
            # No antialiasing: each bar is one flat colour, so its length can be measured.
            ax.barh(yc, c.ce, height=bar_h * 0.9, color=colour, antialiased=False,
                    label=m.name if n == names[0] and not single else None)
            if single:
                note = f"{c.ce:.1f}"
                if len(c.level_dee) < first.n_levels:
                    note += f"  ({len(c.level_dee)} of {first.n_levels} levels)"
                notes.append((c.ce, yc, note, colour))
    ax.axvline(100.0, color=INK, linestyle=(0, (4, 3)), linewidth=1.2, zorder=3)
    ax.set_yticks([rows[n] for n in names], [pretty(n) for n in names])
    for cat, yh in cat_heads:
        group = next(g for g in first.categories if g.name == cat)
        head = cat if not single or group.ce is None else f"{cat}   (mean CE {group.ce:.2f})"
        ax.text(-0.01, yh, head, transform=ax.get_yaxis_transform(), ha="right", va="center",
                fontsize=9, fontweight="bold", color=INK)
    ax.set_ylim(y - 0.2, -0.8)
    ax.set_xlim(0, xmax * (1.12 if single else 1.0))
    ax.set_xlabel("CE (%), lower is better; the dashed line is the baseline (100%)")
    _bar_axes(ax)
    base = first.baseline.name
    if single:
        o = first.overall
        summary = "   ".join(f"{k} {v:.2f}" for k, v in (("mCE", o.ce), ("mRR", o.rr)) if v is not None)
        _title(fig, f"Corruption error per corruption: {models[0].name} on {bench_title(benchmark)}",
               f"baseline {base} = 100%   {summary}" + ("   (partial)" if first.missing else ""))
    else:
        _title(fig, f"Corruption error per corruption on {bench_title(benchmark)}",
               f"baseline {base} = 100%")
        _legend(fig)
    if notes:
        renderer = _freeze_layout(fig)
        x100 = ax.transData.transform((100.0, 0))[0]
        for ce, yc, note, colour in notes:
            text = ax.text(ce + xmax * 0.008, yc, note, va="center", fontsize=8, color=INK)
            box = text.get_window_extent(renderer)
            if box.x0 - 3 <= x100 <= box.x1 + 3:
                # It would cross the 100% line: inside the bar's end instead, in whichever
                # of black and white reads better on the bar's colour.
                text.set(x=ce - xmax * 0.008, ha="right",
                         color=INK if _luminance(colour) > 0.2 else "white")
    return fig


def _bar_axes(ax, grid: bool = True) -> None:
    """Horizontal bar charts: names without tick marks, no box on the top and right, and
    (``grid``) faint vertical lines behind the bars."""
    if grid:
        ax.grid(axis="x", color="#e4e4e4", linewidth=0.8)
        ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    ax.tick_params(axis="y", length=0)


def _luminance(colour: str) -> float:
    """WCAG relative luminance of ``#rrggbb``."""
    def lin(v):
        v /= 255.0
        return v / 12.92 if v <= 0.03928 else ((v + 0.055) / 1.055) ** 2.4
    r, g, b = (int(colour[k:k + 2], 16) for k in (1, 3, 5))
    return 0.2126 * lin(r) + 0.7152 * lin(g) + 0.0722 * lin(b)


def _rgb(c) -> str:
    return "#%02x%02x%02x" % tuple(c)


# --------------------------------------------------------------------------- radar

def radar_figure(series: Sequence[tuple[str, dict]], benchmark: str,
                 baseline: tuple[str, dict] | None = None, what: str = "corruption"):
    """DEE per corruption (or per style) on a polar chart, the paper's Fig. 1 form: one
    closed line per model of ``series`` (name, {axis: DEE}); the published baseline's DEE
    as a grey dashed line for context."""
    import numpy as np

    names = list(series[0][1])
    angles = np.linspace(0, 2 * np.pi, len(names), endpoint=False)
    closed = np.concatenate([angles, angles[:1]])
    fig = _figure(7.2, 7.6)
    ax = fig.add_subplot(projection="polar")
    ax.set_theta_offset(np.pi / 2)
    ax.set_theta_direction(-1)
    top = 0.0
    if baseline is not None:
        bname, bdee = baseline
        vals = [bdee[n] for n in names]
        top = max(top, max(vals))
        ax.plot(closed, vals + vals[:1], color=CONTEXT, linestyle="--", linewidth=1.3,
                label=f"{bname} (baseline, published)")
    for i, (name, dee) in enumerate(series):
        vals = [dee[n] for n in names]
        top = max(top, max(vals))
        st = style(i)
        ax.plot(closed, vals + vals[:1], color=st["color"], linestyle=st["linestyle"],
                marker=st["marker"], markersize=4, linewidth=1.6, label=name)
    rmax = math.ceil(top * 10 + 0.5) / 10
    ax.set_ylim(0, rmax)
    ax.set_xticks(angles, [])
    # Axis names outside the circle, aligned away from it so none touches the rim.
    for a, n in zip(angles, names):
        screen = (np.pi / 2 - a) % (2 * np.pi)  # angle on screen, counter-clockwise from east
        c, s_ = math.cos(screen), math.sin(screen)
        ax.text(a, rmax * 1.07, pretty(n), fontsize=9, color=INK,
                ha="left" if c > 0.2 else "right" if c < -0.2 else "center",
                va="bottom" if s_ > 0.2 else "top" if s_ < -0.2 else "center")
    ticks = [round(t, 1) for t in np.arange(0.1, rmax + 1e-9, 0.1)]
    ax.set_yticks(ticks, [])
    lines = [[dee[n] for n in names] for _, dee in series]
    if baseline is not None:
        lines.append([baseline[1][n] for n in names])
    gap, shown = _radial_label_spot(lines, ticks, rmax)
    for t in shown:
        if t < rmax - 1e-9:  # the rim itself is a line
            # On a white patch: the faint ring through the number stops short of it.
            ax.text(angles[gap] + np.pi / len(names), t, f"{t:.1f}", fontsize=7, color=MUTED,
                    ha="center", va="center", zorder=5,
                    bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.8})
    ax.grid(color="#dddddd")
    _title(fig, f"Depth estimation error (DEE) per {what} on {bench_title(benchmark)}",
           ("mean over the levels; " if what == "corruption" else "")
           + "lower (nearer the centre) is better")
    _legend(fig)
    return fig


# --------------------------------------------------------------------------- DEE per level

def _radial_label_spot(lines, ticks, rmax):
    """Where the ring values go: the gap between two spokes (index of its first spoke) at
    whose middle the fewest ring values would be crossed by a model's line, and the ring
    values clear there. A line between spokes with values r1, r2 crosses the gap's middle
    at a radius between the chord's and the spiral's (matplotlib draws polar lines as
    straight segments), so a value near either is not written."""
    n = len(lines[0])
    half = math.pi / n
    margin = 0.045 * rmax
    best = (-1, 0, [])
    for g in range(n):
        crossings = []
        for vals in lines:
            r1, r2 = vals[g], vals[(g + 1) % n]
            crossings.append((r1 + r2) / 2)
            crossings.append(2 * r1 * r2 * math.cos(half) / (r1 + r2) if r1 + r2 > 0 else 0.0)
        clear = [t for t in ticks if all(abs(t - c) > margin for c in crossings)]
        if len(clear) > best[0]:
            best = (len(clear), g, clear)
    return best[1], best[2]


def levels_figure(models: Sequence[Model], benchmark: str, baseline: tuple[str, dict] | None = None):
    """DEE against level, one small panel per corruption, one line per model (shared y
    axis); the baseline's published level mean as a grey dashed line."""
    first = models[0].scores
    names = [c.name for c in first.corruptions]
    ncols = 6 if len(names) > 15 else 5
    nrows = math.ceil(len(names) / ncols)
    fig = _figure(1.75 * ncols + 0.6, 1.55 * nrows + 1.4)
    axes = fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False)
    levels = list(range(1, first.n_levels + 1))
    top = 0.0
    for k, name in enumerate(names):
        ax = axes[k // ncols][k % ncols]
        if baseline is not None:
            ax.axhline(baseline[1][name], color=CONTEXT, linestyle="--", linewidth=1.0,
                       label=f"{baseline[0]} (baseline, published mean over levels)" if k == 0 else None)
            top = max(top, baseline[1][name])
        for i, m in enumerate(models):
            c = next(c for c in m.scores.corruptions if c.name == name)
            xs = [lv for lv in levels if lv in c.level_dee]
            ys = [c.level_dee[lv] for lv in xs]
            top = max([top, *ys])
            st = style(i)
            ax.plot(xs, ys, color=st["color"], linestyle=st["linestyle"], marker=st["marker"],
                    markersize=3.5, linewidth=1.4, label=m.name if k == 0 else None)
        ax.set_title(pretty(name), fontsize=9, pad=3)
        ax.grid(color="#ececec", linewidth=0.7)
        ax.set_axisbelow(True)
        ax.tick_params(labelsize=8)
    for k in range(len(names), nrows * ncols):
        axes[k // ncols][k % ncols].set_visible(False)
    axes[0][0].set_xticks(levels)
    axes[0][0].set_xlim(levels[0] - 0.3, levels[-1] + 0.3)
    axes[0][0].set_ylim(0, math.ceil(top * 10 + 0.5) / 10)
    for row in axes:
        row[0].set_ylabel("DEE")
    for ax in axes[-1]:
        ax.set_xlabel("level")
    # Panels of the last row that are hidden leave the row above without x labels.
    for k in range(len(names) - ncols, len(names)):
        if k >= 0 and k + ncols >= len(names) and k // ncols < nrows - 1:
            axes[k // ncols][k % ncols].xaxis.set_tick_params(labelbottom=True)
            axes[k // ncols][k % ncols].set_xlabel("level")
    _title(fig, f"DEE against corruption level on {bench_title(benchmark)}", "lower is better")
    _legend(fig)
    return fig


# --------------------------------------------------------------------------- scores vs clean error

@dataclass(frozen=True)
class Point:
    """A model in the summary scatter: clean DEE and its overall mCE and mRR."""

    name: str
    clean: float
    mce: float
    mrr: float


def summary_figure(models: Sequence[Point], published: Sequence[Point], benchmark: str):
    """mCE and mRR against clean DEE (two panels): the published models as grey points
    (named where a label fits), the user's models coloured, marked and always named."""
    from matplotlib.ticker import MaxNLocator

    fig = _figure(11.0, 5.4)
    axes = fig.subplots(1, 2)
    for ax, key, label, ref in ((axes[0], "mce", "mCE (%), lower is better", 100.0),
                                (axes[1], "mrr", "mRR (%), higher is better", None)):
        xs = [p.clean for p in (*published, *models)]
        ys = [getattr(p, key) for p in (*published, *models)]
        ax.scatter([p.clean for p in published], [getattr(p, key) for p in published],
                   s=22, color=CONTEXT, zorder=2,
                   label=f"published ({len(published)} models)" if key == "mce" else None)
        for i, p in enumerate(models):
            st = style(i)
            ax.scatter([p.clean], [getattr(p, key)], s=55, color=st["color"], marker=st["marker"],
                       edgecolor="white", linewidth=0.6, zorder=4, label=p.name if key == "mce" else None)
        xpad = (max(xs) - min(xs)) * 0.18 + 0.004
        ypad = (max(ys) - min(ys)) * 0.12 + 1.0
        ax.set_xlim(min(xs) - xpad, max(xs) + xpad)
        ax.set_ylim(min(ys) - ypad, max(ys) + ypad)
        ax.set_xlabel("clean DEE, lower is better")
        ax.set_ylabel(label)
        # No x value at the left end: it would touch the lowest y value in the corner.
        ax.xaxis.set_major_locator(MaxNLocator(nbins=7, steps=[1, 2, 2.5, 5, 10], prune="lower"))
        ax.grid(color="#ececec", linewidth=0.7)
        ax.set_axisbelow(True)
        if ref is not None:
            ax.axhline(ref, color=MUTED, linestyle=":", linewidth=1.0, zorder=1)
    _title(fig, f"Robustness against clean error on {bench_title(benchmark)}",
           "grey: the paper's models; the baseline has mCE 100 by definition")
    _legend(fig)
    renderer = _freeze_layout(fig)
    for ax, key in ((axes[0], "mce"), (axes[1], "mrr")):
        obstacles = [line.get_window_extent(renderer) for line in ax.get_lines()]
        labels = [(p.clean, getattr(p, key), p.name,
                   {"fontsize": 9, "color": style(i)["color"], "fontweight": "bold"}, True)
                  for i, p in enumerate(models)]
        labels += [(p.clean, getattr(p, key), p.name, {"fontsize": 6.5, "color": MUTED}, False)
                   for p in published]
        place_labels(ax, labels, obstacles, renderer=renderer)
    return fig


# --------------------------------------------------------------------------- KITTI-S

def styles_figure(models: Sequence[tuple[str, dict]], benchmark: str = "kitti-s",
                  baseline: tuple[str, dict] | None = None):
    """DEE per KITTI-S style: one bar per model in each style's group (and the published
    baseline's DEE in grey for context)."""
    styles = list(models[0][1])
    entries = ([(f"{baseline[0]} (baseline, published)", baseline[1], CONTEXT)] if baseline else [])
    entries += [(name, dee, style(i)["color"]) for i, (name, dee) in enumerate(models)]
    band = 0.8
    bar_h = band / len(entries)
    fig = _figure(8.0, 1.6 + 0.2 * len(styles) * max(1.0, 0.5 * len(entries)))
    ax = fig.add_subplot()
    for i, (name, dee, colour) in enumerate(entries):
        ys = [k - band / 2 + bar_h * (i + 0.5) for k in range(len(styles))]
        mdee = sum(dee[s] for s in styles) / len(styles)
        ax.barh(ys, [dee[s] for s in styles], height=bar_h * 0.9, color=colour,
                antialiased=False, label=f"{name}  (mDEE {mdee:.3f})")
    ax.set_yticks(range(len(styles)), [pretty(s) for s in styles])
    ax.set_ylim(len(styles) - 0.5, -0.5)
    ax.set_xlabel("DEE, lower is better")
    _bar_axes(ax)
    _title(fig, f"Depth estimation error per style on {bench_title(benchmark)}")
    _legend(fig)
    return fig


def ranking_figure(models: Sequence[tuple[str, float]], published: Sequence[tuple[str, float]],
                   benchmark: str, metric: str = "mDEE"):
    """Every model ranked by one score (lower is better), the published ones grey, the
    user's coloured and in bold."""
    rows = [(n, v, True) for n, v in models] + [(n, v, False) for n, v in published]
    rows.sort(key=lambda r: r[1])
    fig = _figure(7.0, 1.3 + 0.2 * len(rows))
    ax = fig.add_subplot()
    ours = {n: i for i, (n, _) in enumerate(models)}
    for k, (name, value, mine) in enumerate(rows):
        colour = style(ours[name])["color"] if mine else CONTEXT
        ax.barh(k, value, height=0.75, color=colour, antialiased=False)
        ax.text(value, k, f" {value:.3f}", va="center", fontsize=7.5,
                color=INK if mine else MUTED, fontweight="bold" if mine else "normal")
    ax.set_yticks(range(len(rows)), [n for n, _, _ in rows], fontsize=8)
    for label, (_, _, mine) in zip(ax.get_yticklabels(), rows):
        if mine:
            label.set_fontweight("bold")
    ax.set_ylim(len(rows) - 0.4, -0.6)
    ax.set_xlim(0, max(v for _, v, _ in rows) * 1.15)
    ax.set_xlabel(f"{metric}, lower is better")
    _bar_axes(ax, grid=False)
    _title(fig, f"{metric} on {bench_title(benchmark)}: your models and the paper's",
           "grey: published; coloured and bold: yours")
    return fig


# --------------------------------------------------------------------------- qualitative

def qualitative_figure(labels: Sequence[str], images: Sequence, rows: Sequence[tuple[str, Sequence]],
                       benchmark: str, frame: str):
    """One frame: each variant's image (top row) and, under it, each model's prediction as
    inverse depth (near is bright) in the perceptually uniform ``magma`` map. One colour
    scale per model, set by its clean prediction (2nd-98th percentile), so a corruption's
    effect shows as a change of colour."""
    import numpy as np

    h, w = np.asarray(images[0]).shape[:2]
    cols, nrows = len(images), 1 + len(rows)
    panel_w = 2.7
    fig = _figure(panel_w * cols + 1.2, panel_w * h / w * nrows + 0.35 * nrows + 0.9)
    axes = fig.subplots(nrows, cols, squeeze=False)
    for k, (label, image) in enumerate(zip(labels, images)):
        axes[0][k].imshow(image, extent=(0, w, h, 0))
        axes[0][k].set_title(pretty(label), fontsize=9)
    axes[0][0].set_ylabel("input", fontsize=9)
    for r, (name, maps) in enumerate(rows, start=1):
        clean = np.asarray(maps[0])
        lo, hi = np.percentile(clean, 2), np.percentile(clean, 98)
        if not hi > lo:
            lo, hi = float(clean.min()), float(clean.min()) + 1.0
        im = None
        for k, m in enumerate(maps):
            im = axes[r][k].imshow(m, cmap="magma", vmin=lo, vmax=hi, extent=(0, w, h, 0),
                                   interpolation="nearest")
        axes[r][0].set_ylabel(name, fontsize=9, color=style(r - 1)["color"], fontweight="bold")
        bar = fig.colorbar(im, ax=axes[r].tolist(), shrink=0.85, pad=0.01, ticks=[lo, hi])
        bar.ax.set_yticklabels(["far", "near"], fontsize=8)
    for row in axes:
        for ax in row:
            ax.set_xticks([])
            ax.set_yticks([])
    _title(fig, f"One frame of {bench_title(benchmark)}: {frame}",
           "top: the input; below: each model's prediction (inverse depth, bright is near)")
    return fig


def close(fig) -> None:
    """Free a figure's memory (figures are not in pyplot's registry; dropping the last
    reference is enough, this clears it early for large ones)."""
    fig.clear()


__all__ = ["COLOURS", "FORMATS", "Model", "OKABE_ITO", "Point",
           "ce_figure", "levels_figure", "place_labels", "qualitative_figure", "radar_figure",
           "ranking_figure", "render", "save", "styles_figure", "summary_figure"]
