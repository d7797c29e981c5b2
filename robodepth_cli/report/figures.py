"""The figures of ``robodepth report`` beyond the CE chart: DEE per corruption (radar),
DEE per level, mCE and mRR against clean DEE, the KITTI-S figures and the one-frame
qualitative figure. They use the palette, set-up and label placement of
:mod:`robodepth_cli.report.plot` (imported with it, so matplotlib loads only here)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from .plot import (CONTEXT, INK, MUTED, Model, bar_axes, new_figure, freeze_layout, figure_legend,
                   figure_title, bench_title, panel_axes, panel_grid, place_labels, pretty, style)

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
    fig = new_figure(7.2, 7.6)
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
    figure_title(fig, f"Depth estimation error (DEE) per {what} on {bench_title(benchmark)}",
                 ("mean over the levels; " if what == "corruption" else "")
                 + "lower (nearer the centre) is better")
    figure_legend(fig)
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
    fig, axes = panel_grid(len(names), ncols, (1.75, 1.55), sharex=True, sharey=True)
    nrows = len(axes)
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
        panel_axes(ax)
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
    figure_title(fig, f"DEE against corruption level on {bench_title(benchmark)}", "lower is better")
    figure_legend(fig)
    return fig


# --------------------------------------------------------------------------- scores vs clean error

def severity_figure(models: Sequence[Model], benchmark: str):
    """Severity curves: DEE against the level ``s`` (integer and decimal levels together),
    one panel per corruption that has decimal-level rows, one line per model. Rows beyond
    the benchmark: they are in no mCE or mRR."""
    names = list(dict.fromkeys(n for m in models for n in m.scores.curves))
    ncols = min(len(names), 4)
    fig, axes = panel_grid(len(names), ncols, (2.3, 1.9), sharey=True)
    top = models[0].scores.n_levels
    for k, name in enumerate(names):
        ax = axes[k // ncols][k % ncols]
        for i, m in enumerate(models):
            curve = m.scores.curves.get(name)
            if not curve:
                continue
            st = style(i)
            ax.plot(list(curve), list(curve.values()), color=st["color"], linestyle=st["linestyle"],
                    marker=st["marker"], markersize=3.5, linewidth=1.4, label=m.name)
        ax.set_title(pretty(name), fontsize=9, pad=3)
        ax.set_xlim(0.8, top + 0.2)
        ax.set_xticks(range(1, top + 1))
        ax.set_xlabel("level s")
        panel_axes(ax)
    for row in axes:
        row[0].set_ylabel("DEE")
    figure_title(fig, f"DEE against continuous severity on {bench_title(benchmark)}",
                 "beyond the benchmark: not in mCE or mRR; lower is better")
    figure_legend(fig)
    return fig


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

    fig = new_figure(11.0, 5.4)
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
        panel_axes(ax, None)
        if ref is not None:
            ax.axhline(ref, color=MUTED, linestyle=":", linewidth=1.0, zorder=1)
    figure_title(fig, f"Robustness against clean error on {bench_title(benchmark)}",
                 "grey: the paper's models; the baseline has mCE 100 by definition")
    figure_legend(fig)
    renderer = freeze_layout(fig)
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
    fig = new_figure(8.0, 1.6 + 0.2 * len(styles) * max(1.0, 0.5 * len(entries)))
    ax = fig.add_subplot()
    for i, (name, dee, colour) in enumerate(entries):
        ys = [k - band / 2 + bar_h * (i + 0.5) for k in range(len(styles))]
        mdee = sum(dee[s] for s in styles) / len(styles)
        ax.barh(ys, [dee[s] for s in styles], height=bar_h * 0.9, color=colour,
                antialiased=False, label=f"{name}  (mDEE {mdee:.3f})")
    ax.set_yticks(range(len(styles)), [pretty(s) for s in styles])
    ax.set_ylim(len(styles) - 0.5, -0.5)
    ax.set_xlabel("DEE, lower is better")
    bar_axes(ax)
    figure_title(fig, f"Depth estimation error per style on {bench_title(benchmark)}")
    figure_legend(fig)
    return fig


def ranking_figure(models: Sequence[tuple[str, float]], published: Sequence[tuple[str, float]],
                   benchmark: str, metric: str = "mDEE"):
    """Every model ranked by one score (lower is better), the published ones grey, the
    user's coloured and in bold."""
    rows = [(n, v, True) for n, v in models] + [(n, v, False) for n, v in published]
    rows.sort(key=lambda r: r[1])
    fig = new_figure(7.0, 1.3 + 0.2 * len(rows))
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
    bar_axes(ax, grid=False)
    figure_title(fig, f"{metric} on {bench_title(benchmark)}: your models and the paper's",
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
    from matplotlib.transforms import offset_copy

    h, w = np.asarray(images[0]).shape[:2]
    cols, nrows = len(images), 1 + len(rows)
    panel_w = 2.7
    names = [_wrap(name, panel_w * cols) for name, _ in rows]
    extra_lines = sum(name.count("\n") for name in names)
    fig = new_figure(panel_w * cols + 1.2,
                     panel_w * h / w * nrows + 0.35 * nrows + 0.9 + 0.17 * extra_lines)
    axes = fig.subplots(nrows, cols, squeeze=False)
    for k, (label, image) in enumerate(zip(labels, images)):
        axes[0][k].imshow(image, extent=(0, w, h, 0))
        axes[0][k].set_title(pretty(label), fontsize=9)
    axes[0][0].set_ylabel("input", fontsize=9)
    for r, ((_, maps), name) in enumerate(zip(rows, names), start=1):
        clean = np.asarray(maps[0])
        lo, hi = np.percentile(clean, 2), np.percentile(clean, 98)
        if not hi > lo:
            lo, hi = float(clean.min()), float(clean.min()) + 1.0
        im = None
        for k, m in enumerate(maps):
            im = axes[r][k].imshow(m, cmap="magma", vmin=lo, vmax=hi, extent=(0, w, h, 0),
                                   interpolation="nearest")
        # The name above its row, across the row (a rotated label is only as long as the row
        # is high: long names ran into each other); wrapped where it is wider than the row.
        # Out of the layout, which would widen the first column to the name's width (even
        # as a title); the row's empty titles keep the lines' height free above it.
        above = offset_copy(axes[r][0].transAxes, fig=fig, y=TITLE_PAD, units="points")
        axes[r][0].text(0, 1, name, transform=above, ha="left", va="bottom", fontsize=9,
                        color=style(r - 1)["color"], fontweight="bold").set_in_layout(False)
        for ax in axes[r]:
            ax.set_title("\n".join(" " * (name.count("\n") + 1)), fontsize=9)
        bar = fig.colorbar(im, ax=axes[r].tolist(), shrink=0.85, pad=0.01, ticks=[lo, hi])
        bar.ax.set_yticklabels(["far", "near"], fontsize=8)
    for row in axes:
        for ax in row:
            ax.set_xticks([])
            ax.set_yticks([])
    figure_title(fig, f"One frame of {bench_title(benchmark)}: {frame}",
                 "top: the input; below: each model's prediction (inverse depth, bright is near)")
    return fig


TITLE_PAD = 6.0  # points between an axes and its title: matplotlib's axes.titlepad


def _wrap(text: str, width_in: float, fontsize: float = 9.0) -> str:
    """``text`` in lines that fit ``width_in`` inches of bold ``fontsize`` type (at most
    0.7 em a character, wider than the average), broken at spaces, else anywhere."""
    import textwrap

    per_line = max(8, int(width_in * 72 / (0.7 * fontsize)))
    return "\n".join(textwrap.wrap(text, per_line, break_long_words=True)) or text


# --------------------------------------------------------------------------- synthetic against real

def synreal_figure(comparisons: Sequence, metric: str = "DEE"):
    """One scatter per pair of a synthetic corruption and a real condition: each model's
    error on the corruption (x) against its error under the real condition (y), named at
    its point; the rank correlations and their intervals above each panel. A model keeps
    its colour and marker in every panel."""
    from matplotlib.ticker import MaxNLocator

    models = list(dict.fromkeys(m for c in comparisons for m in c.models))
    ncols = min(len(comparisons), 3)
    fig, axes = panel_grid(len(comparisons), ncols, (4.3, 4.0), (0.4, 0.9))
    for k, c in enumerate(comparisons):
        ax = axes[k // ncols][k % ncols]
        for m, x, y in zip(c.models, c.synthetic, c.real):
            st = style(models.index(m))
            ax.scatter([x], [y], s=50, color=st["color"], marker=st["marker"], edgecolor="white",
                       linewidth=0.6, zorder=3)
        xs, ys = c.synthetic, c.real
        for lim, vals in ((ax.set_xlim, xs), (ax.set_ylim, ys)):
            pad = (max(vals) - min(vals)) * 0.35 + 0.01
            lim(min(vals) - pad, max(vals) + pad)
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_locator(MaxNLocator(nbins=5, prune="lower"))
        ax.set_xlabel(f"{metric}, {pretty(c.pair.corruption)} on {_key_title(c.pair.synthetic)}",
                      fontsize=9)
        ax.set_ylabel(f"{metric}, real: {_key_title(c.pair.real)}", fontsize=9)
        if c.spearman is None:
            stats = f"no correlation: {c.note}"
        else:
            lo = f" [{c.spearman_ci[0]:.2f}, {c.spearman_ci[1]:.2f}]" if c.spearman_ci else ""
            stats = f"Spearman ρ {c.spearman:.2f}{lo}   Kendall τ {c.kendall:.2f}"
        ax.set_title(f"{pretty(c.pair.corruption)} against {_key_title(c.pair.real)}\n{stats}",
                     fontsize=9, color=INK)
        panel_axes(ax)
    figure_title(fig, "Synthetic against real: does the corruption rank the models as the real "
                "condition does?", f"{metric}, lower is better; one point per model; ρ and τ: "
                "rank correlations, 95% bootstrap interval over the models")
    renderer = freeze_layout(fig)
    for k, c in enumerate(comparisons):
        ax = axes[k // ncols][k % ncols]
        place_labels(ax, [(x, y, m, {"fontsize": 8.5, "color": style(models.index(m))["color"],
                                     "fontweight": "bold"}, True)
                          for m, x, y in zip(c.models, c.synthetic, c.real)], renderer=renderer)
    return fig


def _key_title(key: tuple[str, str]) -> str:
    return bench_title(key[0]) + (f" {key[1]}" if key[1] else "")
