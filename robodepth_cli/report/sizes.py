"""Size and complexity against robustness (the paper's Fig. 5, left and middle): each model's
mCE against its parameters and against its GFLOPs per image, on log axes.

A model's size comes from, in this order: ``--params``/``--flops``, the ``--sizes`` CSV, the
``params`` and ``flops`` columns of its results (``robodepth evaluate`` writes them from what
``robodepth predict`` measured). The package ships no sizes of the paper's models: they
appear where the user's ``--sizes`` file gives them. FLOPs are per image, a multiply-add
counted as 2 (as :mod:`robodepth_cli.models.size` measures them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence


@dataclass(frozen=True)
class SizePoint:
    name: str
    mce: float
    params: float | None
    flops: float | None  # per image
    mine: bool
    index: int = 0  # the user's model's place in the report (its colour in every figure)


def collect(models: Sequence, context: Sequence, given: dict[str, dict[str, float]]) -> list[SizePoint]:
    """The points of the figure: ``models`` (the report's, :class:`~.inputs.Model`) with a
    size from ``given`` (model -> {"params", "flops"}, the flags and the sizes file) or from
    their results' columns, then the published rows of ``context`` that ``given`` sizes."""
    out = []
    for i, m in enumerate(models):
        s = m.row.scores
        if s is None or s.note or s.overall.ce is None:
            continue
        first = m.variants[0] if m.variants else {}
        own = {k: first.get(k) for k in ("params", "flops")}
        size = {**{k: v for k, v in own.items() if v}, **given.get(m.name, {})}
        if size:
            out.append(SizePoint(m.name, s.overall.ce, size.get("params"), size.get("flops"), True, i))
    for r in context:
        size = given.get(r.name)
        if size and r.scores is not None and r.scores.overall.ce is not None:
            out.append(SizePoint(r.name, r.scores.overall.ce, size.get("params"), size.get("flops"), False))
    return out


def figure(points: Sequence[SizePoint], benchmark: str):
    """Two panels, mCE against parameters (millions) and against GFLOPs per image, both on
    log axes: the user's models coloured, marked and named (the colour of their place in
    the report), the paper's grey and named where a label fits; the baseline's 100% dotted."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

    from . import plot

    fig = plot.new_figure(11.0, 5.0)
    axes = fig.subplots(1, 2)
    panels = ((axes[0], "params", 1e6, "parameters (millions, log scale)"),
              (axes[1], "flops", 1e9, "GFLOPs per image (log scale; a multiply-add is 2 FLOPs)"))
    for ax, key, unit, label in panels:
        shown = [p for p in points if getattr(p, key)]
        for p in shown:
            x = getattr(p, key) / unit
            if p.mine:
                st = plot.style(p.index)
                ax.scatter([x], [p.mce], s=55, color=st["color"], marker=st["marker"],
                           edgecolor="white", linewidth=0.6, zorder=4)
            else:
                ax.scatter([x], [p.mce], s=22, color=plot.CONTEXT, zorder=2)
        ax.set_xscale("log")
        # 1, 2, 5 per decade, each labelled: a span of less than a decade still has values.
        ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_minor_locator(NullLocator())
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        if shown:
            xs = [getattr(p, key) / unit for p in shown]
            ys = [p.mce for p in shown]
            ax.set_xlim(min(xs) / 1.6, max(xs) * 1.6)
            pad = (max(ys) - min(ys)) * 0.15 + 4.0
            ax.set_ylim(min(ys + [100.0]) - pad, max(ys + [100.0]) + pad)
        else:
            ax.text(0.5, 0.5, f"no model has its {'parameters' if key == 'params' else 'FLOPs'}",
                    transform=ax.transAxes, ha="center", color=plot.MUTED)
        ax.axhline(100.0, color=plot.MUTED, linestyle=":", linewidth=1.0, zorder=1)
        ax.set_xlabel(label)
        ax.set_ylabel("mCE (%), lower is better")
        ax.grid(color="#ececec", linewidth=0.7, which="major")
        ax.set_axisbelow(True)
    grey = "; grey: the paper's models (sizes from --sizes)" if any(not p.mine for p in points) else ""
    plot.figure_title(fig, f"Robustness against model size on {plot.bench_title(benchmark)}",
                      f"coloured: your models{grey}; the baseline has mCE 100 by definition")
    renderer = plot.freeze_layout(fig)
    for ax, key, unit, _ in panels:
        obstacles = [line.get_window_extent(renderer) for line in ax.get_lines()]
        labels = [(getattr(p, key) / unit, p.mce, p.name,
                   {"fontsize": 9, "color": plot.style(p.index)["color"],
                    "fontweight": "bold"}, True) for p in points if p.mine and getattr(p, key)]
        labels += [(getattr(p, key) / unit, p.mce, p.name, {"fontsize": 6.5, "color": plot.MUTED},
                    False) for p in points if not p.mine and getattr(p, key)]
        plot.place_labels(ax, labels, obstacles, renderer=renderer)
    return fig
