"""``robodepth score``: mCE, mRR and DEE of a model from its per-corruption results."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import RobodepthError
from ..sources.datasets import DATASETS, unpublished
from . import common

@click.command("score")
@click.argument("results", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--benchmark", "-b", type=click.Choice([n for n, d in DATASETS.items() if d.leveled]),
              help="Which benchmark the results are on (sets corruptions, levels, baseline); "
                   "default: the dataset the CSV names (robodepth evaluate writes it), else "
                   "inferred from the rows (the benchmark they are a complete set of). "
                   "A dataset without a published baseline (custom, diode-c, ...) must be named: "
                   "its corruptions and levels are those of the rows, CE needs --baseline.")
@click.option("--baseline", "baseline_file", type=click.Path(dir_okay=False, path_type=Path),
              help="Baseline results in the same CSV form (complete), instead of the published one.")
@click.option("--allow-partial", is_flag=True,
              help="Score the variants present; missing ones are a warning, not an error.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--plot", "plot_path", type=click.Path(),
              help="Also draw CE per corruption (needs matplotlib, the figures extra): a .png, "
                   ".svg or .pdf file, or a directory (or a name ending with /) that receives "
                   "RESULTS_ce.png. Prints the path written.")
def score_command(results, benchmark, baseline_file, allow_partial, as_json, plot_path):
    """Robustness scores of a model from its per-corruption results (DEE, CE and RR as the benchmark defines them).

    RESULTS is a CSV with a header row naming the columns corruption, level, abs_rel, a1
    (or dee instead of abs_rel and a1), one row per corruption and level, plus a row
    `clean,0,...`. Prints DEE, CE and RR per corruption, category means, mCE, mRR, mDEE,
    and the flicker of each variant when the CSV has evaluate --flicker's columns.

    \b
    Example:
      robodepth score monovit.csv --plot ce.png
      robodepth score monovit.csv --benchmark kitti-c --json
    """
    from ..evaluation import results as results_mod, scores
    from ..evaluation.csvrows import ResultsTable

    plot_file = None
    if plot_path is not None:
        from ..report.plot import load_matplotlib

        plot_file = common.figure_output(plot_path, f"{results.stem}_ce.png", "--plot")
        load_matplotlib()  # refuse before scoring when matplotlib is missing
    table = ResultsTable.read(results)
    bench = _benchmark(table, benchmark)
    res = results_mod.read_results(table, bench)
    _warn_own_depth(table)
    base = None
    if baseline_file is not None:
        base = results_mod.baseline_from_results(results_mod.read_results(ResultsTable.read(baseline_file), bench), bench)
    missing = results_mod.missing_message(res, bench)
    if missing and not allow_partial:
        raise RobodepthError(missing if res.looks_like else f"{missing} (--allow-partial scores what is there)")
    if missing:
        click.echo(f"robodepth: warning: {missing}; scoring what is present", err=True)
    result = scores.score(res, bench, base, allow_partial=True)
    if plot_file is not None and result.note:
        raise RobodepthError(f"--plot: {results}: {result.note} (no CE to draw)")
    if plot_file is not None:
        from ..report.plot import Model, ce_figure, render

        fig = ce_figure([Model(results.stem, result)], bench.name)
        common.write_bytes(plot_file, render(fig, plot_file.suffix.lower().lstrip(".")))
        common.wrote(plot_file)
    _show(table, result, as_json)


def _benchmark(table, benchmark: str | None):
    """The benchmark the results are scored on: ``--benchmark``, or the dataset the CSV
    names, or the one their rows name; KITTI-S results are refused (no CE or RR)."""
    from .. import benchmark_facts
    from ..evaluation import results as results_mod

    benchmark = _benchmark_of(table, benchmark)
    if benchmark is None:
        from ..report.inputs import style_names

        benchmark = results_mod.infer_benchmark(table, style_names())
    if benchmark not in benchmark_facts.BENCHMARKS and benchmark not in unpublished():
        raise RobodepthError(f"{table.source}: KITTI-S results (styles) have no CE or RR to score; "
                             "robodepth report shows their DEE per style and mDEE")
    if benchmark in unpublished():
        return _unpublished(benchmark, results_mod.read_results(table, benchmark_facts.unpublished(benchmark)))
    return benchmark_facts.get_benchmark(benchmark)


def _show(table, result, as_json: bool) -> None:
    """The scores as a table (or JSON), with the flicker when the CSV has evaluate
    --flicker's columns."""
    import json

    from ..evaluation import scores
    from ..evaluation.flicker import format_flicker, read_flicker

    flicker = read_flicker(table)
    if as_json:
        click.echo(json.dumps({**result.to_json(), **({"flicker": flicker} if flicker else {})},
                              indent=2, allow_nan=False))
    else:
        click.echo(scores.format_table(result), nl=False)
        if flicker:
            click.echo(format_flicker(flicker), nl=False)


def _benchmark_of(table, given: str | None) -> str | None:
    """``given``, or the dataset the results ``table`` names in its dataset column (None:
    neither); refused when the two differ."""
    from .. import benchmark_facts
    from ..report.inputs import KITTI_S

    path = table.source
    own = table.dataset()
    if own is None:
        return given
    if own[0] not in (*benchmark_facts.BENCHMARKS, *unpublished(), KITTI_S):
        raise RobodepthError(f"{path}: dataset {own[0]!r} (its dataset column) is none robodepth "
                             f"scores; valid: {', '.join((*benchmark_facts.BENCHMARKS, *unpublished()))}")
    if given is not None and given != own[0]:
        raise RobodepthError(f"--benchmark {given}: {path} says its results are on {own[0]} "
                             "(its dataset column)")
    return own[0]


def _unpublished(name: str, res):
    """The benchmark of ``name`` (no published baseline) that ``res`` is on: the corruptions
    it has rows of, at the levels among them."""
    from .. import benchmark_facts

    return benchmark_facts.unpublished(name, tuple(res.dee), levels=[lv for d in res.dee.values() for lv in d])


def _warn_own_depth(table) -> None:
    """One line on stderr when RESULTS judge a model on corruptions made from its own depth."""
    from ..evaluation.owndepth import warning

    text = warning(table)
    if text:
        click.echo(f"robodepth: warning: {text}", err=True)
