"""Flicker in the report: the results of ``evaluate --flicker`` (the columns
``flicker_scale`` and ``flicker_abs_rel``) as two tables, a figure and an entry per model in
``scores.json``. Results without the columns add nothing, so such a report is unchanged.

A corruption's flicker is the mean over its levels (integer levels 1 and up, as the DEE of
a corruption is); rows beyond the benchmark (decimal levels, chains) are left out here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from ..benchmark_facts import ALL_CATEGORY, CLEAN, TEMPORAL
from ..evaluation.flicker import COLUMNS
from ..evaluation.results import mean
from .tables import CATEGORY_SHORT, LOW, Column, Table, bench_name

LABEL = {"flicker_scale": "scale change per frame", "flicker_abs_rel": "AbsRel change per frame"}
OVER_TIME = "Over time"


@dataclass
class Flicker:
    """One model's flicker: clean, and per corruption the mean over the levels with each
    level's values (``levels``: level -> {column: value})."""

    model: str
    index: int  # the model's place among the report's models: its colour in every figure
    row: object  # the model's inputs.Row (the tables' rows)
    clean: dict[str, float] | None
    corruptions: dict[str, dict] = field(default_factory=dict)

    def value(self, corruption: str, column: str) -> float | None:
        if corruption == CLEAN:
            return None if self.clean is None else self.clean[column]
        c = self.corruptions.get(corruption)
        return None if c is None else c[column]

    def to_json(self) -> dict:
        return {"clean": self.clean,
                "corruptions": {n: {**{k: c[k] for k in COLUMNS},
                                    "levels": {str(lv): v for lv, v in c["levels"].items()}}
                                for n, c in self.corruptions.items()}}


def collect(models: Sequence) -> list[Flicker]:
    """The flicker of every model (inputs.Model) whose results have the columns; [] when
    none has them."""
    out = []
    for index, m in enumerate(models):
        rows = [v for v in m.variants if all(c in v for c in COLUMNS)]
        if not rows:
            continue
        clean = next(({c: v[c] for c in COLUMNS} for v in rows
                      if v["corruption"] == CLEAN and v.get("level") == 0), None)
        levels: dict[str, dict] = {}
        for v in rows:
            lv = v.get("level")
            if v["corruption"] != CLEAN and isinstance(lv, int) and lv >= 1:
                levels.setdefault(v["corruption"], {})[lv] = {c: v[c] for c in COLUMNS}
        corruptions = {n: {**{c: mean(x[c] for x in per.values()) for c in COLUMNS},
                           "levels": dict(sorted(per.items()))} for n, per in levels.items()}
        out.append(Flicker(m.name, index, m.row, clean, corruptions))
    return out


def corruption_names(flicker: Sequence[Flicker]) -> list[str]:
    """Every corruption any model has flicker for, in the order of the results files."""
    return list(dict.fromkeys(n for f in flicker for n in f.corruptions))


def _group(name: str) -> str:
    if name in TEMPORAL:
        return OVER_TIME
    return CATEGORY_SHORT.get(ALL_CATEGORY.get(name, ""), "")


def tables(flicker: Sequence[Flicker], benchmark: str) -> list[Table]:
    """One table per measure: each model's flicker on the clean images and under each
    corruption (mean over the levels). Lower is better."""
    names = corruption_names(flicker)
    out = []
    for col in COLUMNS:
        cols = [Column(CLEAN, "clean", "", LOW, 4)]
        cols += [Column(n, n.replace("_", " "), _group(n), LOW, 4) for n in names]
        values = [{CLEAN: f.value(CLEAN, col), **{n: f.value(n, col) for n in names}} for f in flicker]
        what = ("flicker_scale: the typical relative change of the model's scale (median "
                "ground truth over median prediction) from one frame to the next"
                if col == "flicker_scale" else
                "flicker_abs_rel: the mean change of AbsRel from one frame to the next")
        out.append(Table(f"Flicker: {LABEL[col]}", col.replace("_", "-"),
                         f"{what}, over the consecutive frames of the split, on the clean images "
                         f"and under each corruption (mean over the levels) on "
                         f"{bench_name(benchmark)} (evaluate --flicker; your models). Lower is "
                         "steadier. Bold: best; underlined: second.",
                         cols, [f.row for f in flicker], values))
    return out


def figure(flicker: Sequence[Flicker], benchmark: str):
    """Two panels (flicker_scale, flicker_abs_rel): a bar per model for the clean images
    and each corruption, and each model's clean value as a dotted line of its colour, the
    reference a corruption's bar is read against."""
    from .plot import bar_axes, new_figure, figure_legend, figure_title, bench_title, pretty, style

    names = [CLEAN, *corruption_names(flicker)]
    band = 0.8
    bar_h = band / len(flicker)
    fig = new_figure(10.0, 1.8 + 0.2 * len(names) * max(1.0, 0.5 * len(flicker)))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, col in zip(axes, COLUMNS):
        top = 0.0
        for i, f in enumerate(flicker):
            colour = style(f.index)["color"]
            ys, ws = [], []
            for k, n in enumerate(names):
                v = f.value(n, col)
                if v is not None:
                    ys.append(k - band / 2 + bar_h * (i + 0.5))
                    ws.append(v)
            top = max([top, *ws])
            # No antialiasing: each bar is one flat colour, so its length can be measured.
            ax.barh(ys, ws, height=bar_h * 0.9, color=colour, antialiased=False,
                    label=f.model if col == COLUMNS[0] else None)
            if f.clean is not None:
                ax.axvline(f.clean[col], color=colour, linestyle=":", linewidth=1.2, zorder=3)
        ax.set_xlim(0, top * 1.08 if top > 0 else 1.0)
        ax.set_xlabel(f"{col} ({LABEL[col]}), lower is steadier", fontsize=9)
        bar_axes(ax)
    axes[0].set_yticks(range(len(names)), [pretty(n) for n in names])
    axes[0].set_ylim(len(names) - 0.5, -0.5)
    figure_title(fig, f"Flicker on consecutive frames of {bench_title(benchmark)}",
                 "clean and each corruption (mean over the levels); dotted: each model's clean value")
    figure_legend(fig)
    return fig


def figure_entry(flicker: Sequence[Flicker], benchmark: str) -> tuple:
    """The report's figure entry: stem, title, caption and the figure."""
    return ("flicker", "Flicker per corruption",
            "Each model's flicker over consecutive frames (evaluate --flicker): the change of its "
            "scale (left) and of its AbsRel (right) from one frame to the next, clean and under "
            "each corruption (mean over the levels); the dotted lines are each model's clean "
            "value.", figure(flicker, benchmark))
