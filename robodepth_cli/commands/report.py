"""``robodepth report``: the paper's tables and figures for any number of models."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..errors import RobodepthError, counted
from . import common


@click.command("report")
@click.argument("results", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory to write index.html, figures/, table.tex, table.md and scores.json "
                   "into, whole or not at all (created if needed; an earlier report there is "
                   "replaced, its figures that this one does not draw removed).")
@click.option("--name", "names", multiple=True, metavar="NAME",
              help="Model name of each RESULTS file, in order (once per file); default: the "
                   "file name without .csv.")
@click.option("--benchmark", "-b", type=click.Choice(["kitti-c", "nyudepth2-c", "kitti-s"]),
              help="The benchmark of the results; default: inferred from their rows (as "
                   "robodepth score infers it).")
@click.option("--published", "context", type=click.Choice(["all", "baseline", "none"]),
              default="all", show_default=True,
              help="Published models as context rows in the tables: all of the paper's, only "
                   "its baseline, or none (the figures always show them).")
@click.option("--dataset", "dataset", type=click.Path(file_okay=False, path_type=Path),
              metavar="DIR", help="The dataset build the results come from: recorded in "
                                  "scores.json (its fingerprint) and, with --pred, the frame "
                                  "of the qualitative figure.")
@click.option("--pred", "preds", multiple=True, type=click.Path(path_type=Path), metavar="PRED",
              help="Predictions of a model on --dataset (as robodepth evaluate reads them), "
                   "once per RESULTS file in order (fewer is fine): adds a qualitative figure.")
@click.option("--frame", default=0, show_default=True, type=click.IntRange(min=0),
              help="With --pred: which image of the split (0 = first) the qualitative figure shows.")
@click.option("--kind", "kinds", multiple=True, type=click.Choice(["disp", "sigmoid", "depth"]),
              help="With --pred: what the predictions hold (as for robodepth evaluate), once per "
                   "--pred in order or once for all; default: what each PRED/predictions.json "
                   "records, else disp for KITTI and depth for NYU.")
@click.option("--on", "on", multiple=True, metavar="DATASET[:SPLIT]",
              help="The dataset (and split) of each RESULTS file, once per file in order or once "
                   "for all (drivingstereo-c:foggy, diode-c, custom:night), for results that do "
                   "not name it; default: what the file names (evaluate writes it), else "
                   "inferred from the rows (kitti-c, nyudepth2-c, kitti-s). Each dataset gets "
                   "its table.")
@click.option("--baseline", "baseline", metavar="NAME",
              help="The model (a --name) whose results are the baseline of mCE on datasets "
                   "without a published one; without it they show DEE and RR.")
@click.option("--pairs", "pairs", multiple=True, type=click.Path(dir_okay=False, path_type=Path),
              metavar="FILE", help="More pairs of a synthetic corruption and a real condition "
                                   "(CSV synthetic,corruption,real), beside the shipped table.")
@click.option("--metric", type=click.Choice(["dee", "abs_rel"]), default="dee", show_default=True,
              help="The error synthetic against real ranks the models by.")
@click.option("--bootstrap", "n_boot", default=2000, show_default=True, type=click.IntRange(min=100),
              help="Resamples of the models for the intervals of synthetic against real.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of those resamples (the same seed gives the same intervals).")
@click.option("--tag", "tags", multiple=True, metavar="MODEL:KEY=VALUE",
              help="A property of one of your models (repeatable; several as KEY=V,KEY=V): "
                   "base, modality, backbone, resolution, pretrain (compared in groups of "
                   "variants) or finetune (the corruption it was fine-tuned with, none for "
                   "the baseline).")
@click.option("--groups", "groups", type=click.Choice(["yours", "all"]), default="yours",
              show_default=True, help="Groups of variants (modality, pre-training, "
                                      "resolution) among your models, or all: the paper's too.")
@click.option("--params", "params", multiple=True, metavar="MODEL=COUNT",
              help="A model's parameters (14.3M), over what its results record (repeatable).")
@click.option("--flops", "flops", multiple=True, metavar="MODEL=COUNT",
              help="A model's FLOPs per image, a multiply-add counting 2 (16G; repeatable).")
@click.option("--sizes", "sizes", type=click.Path(dir_okay=False, path_type=Path), metavar="FILE",
              help="A CSV model,params,flops of model sizes (the paper's models' too; the "
                   "package ships none).")
def report_command(results, out, names, benchmark, context, dataset, preds, frame, kinds, on,
                   baseline, pairs, metric, n_boot, seed, tags, groups, params, flops, sizes):
    """A report of one or more models: a self-contained HTML page, the figures (SVG, PDF,
    PNG), LaTeX and Markdown tables and a versioned scores.json.

    RESULTS are results CSVs as robodepth evaluate writes them (or robodepth score reads
    them), each complete. The page and tables show your models and the RoboDepth paper's
    published models as context; figures: DEE per corruption (radar), CE per corruption,
    DEE against level, mCE and mRR against clean DEE (KITTI-S: DEE per style and the mDEE
    ranking). Results on other datasets add a table per dataset, one across them
    and, where a synthetic corruption and a real condition of the pairs table both have
    results, the rank correlation of the models between them with a scatter.

    \b
    Examples:
      robodepth report monodepth2.csv monovit.csv --out report/
      robodepth report a.csv b.csv --name "Ours" --name "Ours + aug" --out report/
      robodepth report ours.csv --dataset KITTI_C --pred PRED --out report/
      robodepth report a.csv b.csv c.csv a_fog.csv b_fog.csv c_fog.csv --name A --name B
          --name C --name A --name B --name C --out report/
      robodepth report team1/scores.json team2/scores.json --out leaderboard/

    Challenge scores.json files (robodepth challenge score) make a leaderboard instead:
    OUT/index.html and OUT/leaderboard.md, a table per track with per-corruption columns.
    """
    from ..report import write
    from ..report.leaderboard import is_challenge_scores

    challenge = [is_challenge_scores(p) for p in results]
    if any(challenge):
        return _leaderboard(results, challenge, names, out, preds, dataset)
    if preds and dataset is None:
        raise RobodepthError("--pred needs --dataset (the build the predictions were made on)")
    if len(preds) > len(results):
        raise RobodepthError(f"--pred given {counted(len(preds), 'time')} for "
                             f"{counted(len(results), 'results file')}; "
                             "give it at most once per file, in the same order")
    from ..report.plot import load_matplotlib
    from ..report.qualitative import check_kinds

    check_kinds(kinds, preds)
    load_matplotlib()  # refuse before anything is created when matplotlib is missing
    write.check_writable(out)
    from ..evaluation.csvrows import ResultsTable

    report = write.assemble([ResultsTable.read(p) for p in results], list(names), benchmark, context, dataset, on=on,
                        pairs=pairs, baseline=baseline, metric=metric, n_boot=n_boot, seed=seed,
                        n_pred=len(preds))

    say = (lambda what: click.echo(f"  {what}", err=True)) if sys.stderr.isatty() else (lambda _: None)
    write.draw(report)
    from ..report.analyses import add as add_analyses

    add_analyses(report, tags=tags, params=params, flops=flops, sizes=sizes, groups=groups)
    for m in report.models:  # judged on corruptions made from its own depth predictions
        if m.own_depth:
            click.echo(f"robodepth: warning: {m.own_depth}", err=True)
    if preds:
        _add_qualitative(report, dataset, preds, frame, kinds)
    written = write.write(report, out, progress=say,
                      published=lambda: common.on_interrupt(f"the report was written to {out}"))
    _say_written(report, written, out)


def _add_qualitative(report, dataset, preds, frame, kinds) -> None:
    """The one-frame figure of ``--pred``; a warning for each folder drawn by a guess."""
    from ..report.qualitative import qualitative

    figure, guessed = qualitative(report, dataset, list(preds), frame, kinds)
    report.figures.append(figure)
    for pred, kind in guessed:
        click.echo(f"robodepth: warning: --pred {pred}: no predictions.json says what it holds; "
                   f"drawn as {kind} (the {report.benchmark} default); give --kind if wrong",
                   err=True)


def _say_written(report, written, out: Path) -> None:
    """The closing line: what was written where, and the earlier figures removed."""
    models = ", ".join(dict.fromkeys(m.name for m in report.entries or report.models))
    where = report.benchmark
    if report.entries:
        from ..report.synreal import key_text

        where = ", ".join(dict.fromkeys(key_text(e.key) for e in report.entries))
    removed = ""
    if written.removed:
        removed = (f"; removed {len(written.removed)} figure files of the earlier report there: "
                   + ", ".join(str(p.relative_to(out)) for p in written.removed))
    click.echo(f"wrote {out / 'index.html'} ({where}: {models}; "
               f"{len(written.files)} files under {out}{removed})", err=True)


def _leaderboard(results, challenge, names, out, preds, dataset) -> None:
    """``report`` on challenge scores.json files: the leaderboard (docs/report.md)."""
    from ..report.leaderboard import write_leaderboard

    if not all(challenge):
        other = next(p for p, c in zip(results, challenge) if not c)
        raise RobodepthError(f"{other}: not a challenge scores.json; a leaderboard takes only those "
                             "(make results CSVs a report of their own)")
    if preds or dataset is not None:
        raise RobodepthError("--pred, --dataset: not for a challenge leaderboard")
    written = write_leaderboard(results, names, out)
    click.echo(f"wrote {written[0]} and {written[1]} ({counted(len(results), 'entry', 'entries')})", err=True)
