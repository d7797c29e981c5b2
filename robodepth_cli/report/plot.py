"""The plotting layer, with matplotlib (the ``figures`` extra, imported by nothing else): the
palette, figure set-up, saving, label placement (:func:`place_labels`), and the CE bar
chart that ``robodepth score --plot`` and ``robodepth report`` both draw; the report's
other figures are in :mod:`robodepth_cli.report.figures`. Figures use the object-oriented
API (no pyplot), so drawing one changes no global state of the calling program; the
conventions every figure follows (Okabe-Ito colours, a marker and line style per model,
no overlapping text) are those of docs/report.md."""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..benchmark_facts import CATEGORIES
from ..errors import RobodepthError
from ..evaluation.scores import Scores

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


def load_matplotlib():
    try:
        import matplotlib
    except ImportError:
        raise RobodepthError("figures need matplotlib: pip install 'robodepth-cli[figures]' "
                             "(or pip install matplotlib)") from None
    # Text stays text in SVG (searchable, and the page's fonts apply); the same figure
    # gives the same bytes (no random ids, no date).
    matplotlib.rcParams.update({"svg.fonttype": "none", "svg.hashsalt": "robodepth",
                                "pdf.fonttype": 42, "font.size": 10,
                                "axes.titlesize": 10, "axes.labelsize": 10})
    return matplotlib


def new_figure(width: float, height: float):
    load_matplotlib()
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


def freeze_layout(fig):
    """Run the constrained layout once and keep it: labels placed afterwards are measured
    where they will be drawn."""
    fig.canvas.draw()
    fig.set_layout_engine("none")
    return fig.canvas.get_renderer()


def figure_legend(fig, handles=None, labels=None):
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


def figure_title(fig, title: str, subtitle: str = ""):
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
    rows, y, cat_heads = _category_rows(first)
    height = 1.4 + 0.19 * y * max(1.0, 0.55 * per_group)
    fig = new_figure(8.0, height)
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
    bar_axes(ax)
    base = first.baseline.name
    if single:
        o = first.overall
        summary = "   ".join(f"{k} {v:.2f}" for k, v in (("mCE", o.ce), ("mRR", o.rr)) if v is not None)
        figure_title(fig, f"Corruption error per corruption: {models[0].name} on {bench_title(benchmark)}",
                     f"baseline {base} = 100%   {summary}" + ("   (partial)" if first.missing else ""))
    else:
        figure_title(fig, f"Corruption error per corruption on {bench_title(benchmark)}",
                     f"baseline {base} = 100%")
        figure_legend(fig)
    if notes:
        _write_bar_ends(fig, ax, notes, xmax)
    return fig


def _category_rows(first: Scores) -> tuple[dict[str, float], float, list]:
    """The y positions of the CE chart: corruptions top to bottom, a gap and a heading row
    between categories; ``(row of each corruption, the end, (category, heading row)s)``."""
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
    return rows, y, cat_heads


def _write_bar_ends(fig, ax, notes, xmax: float) -> None:
    """Each bar's value at its end, ``notes`` (CE, y, text, bar colour)."""
    renderer = freeze_layout(fig)
    x100 = ax.transData.transform((100.0, 0))[0]
    for ce, yc, note, colour in notes:
        text = ax.text(ce + xmax * 0.008, yc, note, va="center", fontsize=8, color=INK)
        box = text.get_window_extent(renderer)
        if box.x0 - 3 <= x100 <= box.x1 + 3:
            # It would cross the 100% line: inside the bar's end instead, in whichever
            # of black and white reads better on the bar's colour.
            text.set(x=ce - xmax * 0.008, ha="right",
                     color=INK if _luminance(colour) > 0.2 else "white")


def panel_grid(n: int, ncols: int, size: tuple[float, float], margins: tuple[float, float] = (0.6, 1.4),
               **shared):
    """A figure of ``n`` panels of ``size`` inches, ``ncols`` to a row, the places left over
    hidden: ``(figure, axes[row][column])``; ``shared``: ``sharex``/``sharey``."""
    nrows = math.ceil(n / ncols)
    fig = new_figure(size[0] * ncols + margins[0], size[1] * nrows + margins[1])
    axes = fig.subplots(nrows, ncols, **shared, squeeze=False)
    for k in range(n, nrows * ncols):
        axes[k // ncols][k % ncols].set_visible(False)
    return fig, axes


def panel_axes(ax, labelsize: float | None = 8) -> None:
    """A panel's faint grid behind the data, and its small tick labels."""
    ax.grid(color="#ececec", linewidth=0.7)
    ax.set_axisbelow(True)
    if labelsize is not None:
        ax.tick_params(labelsize=labelsize)


def bar_axes(ax, grid: bool = True) -> None:
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


def close(fig) -> None:
    """Free a figure's memory (figures are not in pyplot's registry; dropping the last
    reference is enough, this clears it early for large ones)."""
    fig.clear()


__all__ = ["COLOURS", "FORMATS", "Model", "OKABE_ITO", "ce_figure", "place_labels", "render",
           "save"]
