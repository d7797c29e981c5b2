"""``robodepth transfer``: how well a synthetic corruption's ranking of models predicts the
ranking under the matching real condition."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import RobodepthError
from . import common


def _split(text: str, flag: str, parts: int) -> tuple[str, ...]:
    """``MODEL=CSV`` (parts 2) or ``MODEL:CONDITION=CSV`` (parts 3)."""
    head, eq, path = text.partition("=")
    names = head.split(":") if parts == 3 else [head]
    if not eq or not path or len(names) != parts - 1 or not all(n.strip() for n in names):
        form = "MODEL=CSV" if parts == 2 else "MODEL:CONDITION=CSV"
        raise RobodepthError(f"{flag} {text!r}: expected {form}")
    return (*(n.strip() for n in names), path)


@click.command("transfer")
@click.option("--synthetic", "synthetic", multiple=True, required=True, metavar="MODEL=CSV",
              help="A model's results on a synthetic benchmark (a results CSV with corruption "
                   "rows, e.g. KITTI-C); once per model.")
@click.option("--real", "real", multiple=True, required=True, metavar="MODEL:CONDITION=CSV",
              help="A model's results on a real condition's build (its clean row is used, e.g. "
                   "drivingstereo-c --split foggy --corruptions none); once per model and condition.")
@click.option("--pairs", "pairs_file", type=click.Path(dir_okay=False, path_type=Path),
              metavar="FILE", help="Which corruption stands for which condition (YAML 'pairs:' "
                                   "of {synthetic, real}); default: the shipped table.")
@click.option("--bootstrap", "n_boot", default=2000, show_default=True,
              type=click.IntRange(min=100), help="Bootstrap resamples of the interval.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the bootstrap.")
@click.option("--plot", "plot_path", type=click.Path(), metavar="FILE",
              help="Also draw the scatter of the models per pair (.png, .svg or .pdf; needs "
                   "matplotlib, the figures extra).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
def transfer_command(synthetic, real, pairs_file, n_boot, seed, plot_path, as_json):
    """Rank correlation of models between synthetic corruptions and real conditions.

    For each pair of the table (fog and a real foggy set, dark and a night set, ...), the
    models with results on both sides are ranked by DEE on each; prints Spearman's rho
    with a 95% bootstrap interval over the models (at least 3 models per pair).

    \b
    Example:
      robodepth transfer --synthetic m2=m2_kittic.csv --synthetic mv=mv_kittic.csv \\
          --synthetic da=da_kittic.csv --real m2:foggy=m2_foggy.csv \\
          --real mv:foggy=mv_foggy.csv --real da:foggy=da_foggy.csv --plot fog.png
    """
    import json

    from ..evaluation import transfer as T

    plot_file = None
    if plot_path is not None:
        from ..evaluation.plot import _mpl

        plot_file = common.figure_output(plot_path, "transfer.png", "--plot")
        _mpl()
    pairs = T.read_pairs(pairs_file or T.PAIRS_FILE)
    syn, rea = {}, {}
    for text in synthetic:
        model, path = _split(text, "--synthetic", 2)
        if model in syn:
            raise RobodepthError(f"--synthetic: model {model!r} given twice")
        syn[model] = T.synthetic_dees(Path(path))
    for text in real:
        model, condition, path = _split(text, "--real", 3)
        if condition in rea.get(model, {}):
            raise RobodepthError(f"--real: {model}:{condition} given twice")
        rea.setdefault(model, {})[condition] = T.real_dee(Path(path))
    found = T.compare(syn, rea, pairs, n_boot, seed)
    if not found:
        raise RobodepthError(f"no pair of the table has results of at least {T.MIN_MODELS} models "
                             f"on both sides (pairs: {', '.join(f'{p.synthetic}-{p.real}' for p in pairs)})")
    if plot_file is not None:
        from ..evaluation.plot import render

        common.write_bytes(plot_file, render(T.figure(found), plot_file.suffix.lower().lstrip(".")))
        common.wrote(plot_file)
    if as_json:
        click.echo(json.dumps([t.to_json() for t in found], indent=2))
    else:
        click.echo(T.table(found), nl=False)
