"""Fine-tuning with corruptions (the paper's Fig. 6): a matrix of Abs Rel, a row per model
fine-tuned with a corruption (``--tag MODEL:finetune=<corruption>``) after the baseline
(tagged ``finetune=none``, else the one untagged model), a column per test corruption
after the clean images; a cell is the mean over the levels its results have."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from ..benchmark_facts import CLEAN, get_benchmark
from ..errors import RobodepthError
from ..evaluation.csvrows import normalise_name

NONE = "none"


@dataclass(frozen=True)
class Matrix:
    rows: tuple[str, ...]  # the fine-tuning corruption of each row; NONE for the baseline
    models: tuple[str, ...]  # each row's model
    columns: tuple[str, ...]  # clean, then the test corruptions
    values: tuple[tuple[float, ...], ...]  # Abs Rel, rows x columns


def _abs_rel(model, column: str) -> float | None:
    cells = [v["abs_rel"] for v in model.variants if v.get("corruption") == column
             and "abs_rel" in v and isinstance(v.get("level"), int)
             and (column == CLEAN or v["level"] > 0)]
    return sum(cells) / len(cells) if cells else None


def matrix(models: Sequence, tags: dict[str, dict[str, str]], benchmark: str) -> Matrix | None:
    """The matrix of the ``models`` tagged ``finetune`` (None when none is); a tag that names
    no corruption of the benchmark, two models fine-tuned with one corruption, or results
    without Abs Rel are refused."""
    bench = get_benchmark(benchmark)
    tuned: dict[str, object] = {}
    baseline = []
    for m in models:
        given = tags.get(m.name, {}).get("finetune")
        if given is None:
            continue
        name = normalise_name(given)
        if name == NONE:
            baseline.append(m)
            continue
        if name not in bench.corruptions:
            raise RobodepthError(f"--tag {m.name}:finetune={given}: not a corruption of "
                                 f"{benchmark} (or none, for the baseline)")
        if name in tuned:
            raise RobodepthError(f"--tag {m.name}:finetune={given}: {tuned[name].name} is tagged "
                                 "with it too; one model per fine-tuning corruption")
        tuned[name] = m
    if not tuned:
        return None
    if not baseline:
        baseline = [m for m in models if "finetune" not in tags.get(m.name, {})]
    if len(baseline) > 1:
        raise RobodepthError(f"--tag: {len(baseline)} models could be the fine-tuning baseline ("
                             + ", ".join(m.name for m in baseline) + "); tag one MODEL:finetune=none")
    ordered = [(NONE, m) for m in baseline] + [(c, tuned[c]) for c in bench.corruptions if c in tuned]
    columns = (CLEAN, *bench.corruptions)
    values = []
    for _, m in ordered:
        row = tuple(_abs_rel(m, c) for c in columns)
        if row[0] is None:
            raise RobodepthError(f"{m.path}: no abs_rel column; the fine-tuning matrix shows Abs Rel "
                                 "(robodepth evaluate writes it)")
        values.append(row)
    keep = [j for j in range(len(columns)) if all(r[j] is not None for r in values)]
    return Matrix(tuple(c for c, _ in ordered), tuple(m.name for _, m in ordered),
                  tuple(columns[j] for j in keep), tuple(tuple(r[j] for j in keep) for r in values))


def figure(mx: Matrix, benchmark: str):
    """The matrix as coloured cells with their values: each column shaded on its own from
    its lowest value (lightest) to its highest (darkest), the cell where a model is tested
    on the corruption it was fine-tuned with outlined."""
    import numpy as np
    from matplotlib import colormaps
    from matplotlib.patches import Rectangle

    from . import plot

    values = np.array(mx.values, dtype=float)
    lo, hi = values.min(axis=0), values.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    shade = colormaps["Blues"](0.08 + 0.72 * (values - lo) / span)
    n_rows, n_cols = values.shape
    fig = plot.new_figure(1.9 + 0.56 * n_cols, 1.9 + 0.36 * n_rows)
    ax = fig.add_subplot()
    ax.imshow(shade, aspect="auto", interpolation="nearest")
    for i in range(n_rows):
        for j in range(n_cols):
            r, g, b = (int(round(255 * v)) for v in shade[i, j, :3])
            ink = plot.INK if plot._luminance(f"#{r:02x}{g:02x}{b:02x}") > 0.3 else "white"
            ax.text(j, i, f"{values[i, j]:.3f}", ha="center", va="center", fontsize=7, color=ink)
            if mx.rows[i] == mx.columns[j]:
                ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, edgecolor=plot.INK,
                                       linewidth=1.4))
    labels = [f"none ({m})" if c == NONE else plot.pretty(c) for c, m in zip(mx.rows, mx.models)]
    ax.set_yticks(range(n_rows), labels, fontsize=8.5)
    ax.set_xticks(range(n_cols), [plot.pretty(c) for c in mx.columns], rotation=90, fontsize=8.5)
    ax.tick_params(length=0)
    for side in ax.spines.values():
        side.set_visible(False)
    ax.set_ylabel("fine-tuned with")
    ax.set_xlabel("tested on")
    plot.figure_title(fig, f"Abs Rel after fine-tuning with each corruption, on "
                           f"{plot.bench_title(benchmark)}",
                      "each column shaded from its lowest (light) to its highest (dark) value; "
                      "outlined: tested on its own corruption; lower is better")
    return fig
