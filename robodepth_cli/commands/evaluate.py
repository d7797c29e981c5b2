"""``robodepth evaluate``: a model's predictions on a built dataset -> the results CSV (and
the scores)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click

from ..errors import RobodepthError
from . import common

DEFAULT_OUT = "results.csv"


@click.command("evaluate")
@click.argument("dataset_dir", metavar="DATASET_DIR", type=click.Path(path_type=Path))
@click.option("--pred", required=True, type=click.Path(path_type=Path),
              help="The model's predictions: PRED/clean.npy, PRED/<corruption>/<level>.npy "
                   "(N x h x w; or .npz holding one such array), or one .npy/.png per image "
                   "mirroring the dataset tree.")
@click.option("--protocol", type=click.Choice(["kitti", "nyu"]),
              help="kitti (monodepth2) or nyu (BTS/AdaBins); default: the dataset's.")
@common.evaluation_options
@click.option("--kind", type=click.Choice(["disp", "sigmoid", "depth"]),
              help="What the arrays hold: disp (scaled disparity, kitti default), sigmoid "
                   "(raw network output, in [0, 1]), depth (nyu default). PNGs are depths. "
                   "Default: what PRED/predictions.json records, if robodepth predict wrote PRED.")
@click.option("--png-scale", type=float, metavar="S",
              help="16-bit PNG predictions hold depth x S (default 256 kitti, 1000 nyu); they "
                   "are read as depths (--kind depth).")
@click.option("--gt", "gt_path", type=click.Path(path_type=Path), metavar="FILE|DIR",
              help="Ground truth instead of the dataset's own (gt_depths.npz, or a directory "
                   "of sync_depth PNGs).")
@click.option("--out", "-o", "out", type=click.Path(dir_okay=False, path_type=Path),
              help="The results CSV to write (replaced if it exists). Default: results.csv, "
                   "which is never replaced without --force.")
@click.option("--force", is_flag=True, help="Replace an existing default results.csv.")
@click.option("--score", "with_score", is_flag=True,
              help="Also print the robustness scores (as robodepth score does).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of tables.")
@click.option("--allow-partial", is_flag=True,
              help="Evaluate the variants that have predictions; the rest are listed as missing.")
@click.option("--flicker", is_flag=True,
              help="Also measure flicker over the split's consecutive frames: flicker_scale and "
                   "flicker_abs_rel columns (see docs/video.md).")
@click.option("--jobs", "-j", type=common.Jobs(), metavar="N|auto",
              help="Processes (the command's and N - 1 workers), each evaluating whole variants "
                   "(default, 'auto' or -1: one per CPU); the numbers are the same for any N.")
@common.progress_option
def evaluate_command(dataset_dir, pred, protocol, stereo, kind, align, align_space, crop,
                     min_depth, max_depth, png_scale, gt_path, out, force, with_score, as_json,
                     allow_partial, flicker, jobs, progress):
    """Evaluate a model's depth predictions on DATASET_DIR (made by robodepth build).

    Compares the predictions of every variant (clean, each corruption and level, or each
    KITTI-S style) with the ground truth under the benchmark's protocol and writes one CSV
    row per variant: corruption, level, abs_rel, sq_rel, rmse, rmse_log, a1, a2, a3 (nyu
    also log10, silog); the clean row is `clean,0`. That CSV is what `robodepth score`
    reads; --score prints the scores right away.

    0 and inf: a disparity of 0 is infinitely far, a depth of 0 is distance 0; either is
    clamped to the protocol's depth range (1e-3 to 80 m kitti, 10 m nyu). inf and NaN are
    refused, and so is a map with no positive value or, under median scaling, one that is 0
    at half of the valid pixels or more.

    The ground truth as kept (valid pixels) goes into ~/.cache/robodepth/ground-truth
    (ROBODEPTH_CACHE_DIR moves it; ROBODEPTH_GT_CACHE=off: not kept), and the next
    evaluation of the same file maps it from there instead of reading it again.

    \b
    Examples:
      robodepth evaluate KITTI_C --pred PRED --score
      robodepth evaluate KITTI_C --pred PRED --stereo --out stereo.csv
      robodepth evaluate NYU_C --pred BTS_PNGS --out bts.csv
      robodepth evaluate KITTI_C --pred DA --align scale-shift --align-space disparity
    """
    from ..progress import bar as progress_bar

    from ..evaluation import evaluate
    from ..evaluation.configure import evaluation_setup, scored_benchmark
    from ..workers import default_jobs
    from .. import open_dataset
    from ..files import check_writable
    from ..predictions import RECORD
    from ..evaluation.modelsize import with_size

    if out is None:
        out = Path(DEFAULT_OUT)
        if out.exists() and not force:
            raise RobodepthError(f"{out} exists (the default --out); give --out FILE, or --force "
                                 "to replace it")
    check_writable(out, "--out")
    common.will_write(out)
    replacing = out.exists()
    dataset = open_dataset(dataset_dir, warn=False)
    if dataset.failed:
        click.echo(f"robodepth: warning: {dataset.incomplete()}", err=True)
    setup, taken = evaluation_setup(dataset.name, _recorded(pred), protocol, kind, stereo, png_scale,
                                    align, align_space, crop, min_depth, max_depth)
    if taken:
        click.echo(f"robodepth: from {pred / RECORD}: {', '.join(taken)}", err=True)
    bench = scored_benchmark(dataset.name, dataset.variants()) if with_score else None
    with progress_bar("img", progress=progress) as bar:
        def set_total(n):
            # Restarts the clock too: the ground truth was read meanwhile, and counting that
            # time against the first image made the first estimate hours long.
            bar.reset(total=n)

        result = evaluate.evaluate(dataset, pred, setup, gt=gt_path, allow_partial=allow_partial,
                            require_clean=with_score, progress=bar.update, on_total=set_total,
                            jobs=jobs or default_jobs(), flicker=flicker)
    table = result.table(((dataset.record.config or {}).get("extra") or {}).get("severity_size"),
                         _own_depth_lines(dataset, pred))
    table = with_size(table, _record(pred))
    table.write(out)
    common.show_results(result, replace(table, source=str(out)), out, bench, as_json, replacing)


def _own_depth_lines(dataset, pred: Path) -> tuple[str, ...]:
    """The results CSV's comment lines naming the scene depth's model and this one, for a
    build whose depth-aware corruptions took a model's depth (evaluation/owndepth.py)."""
    from ..evaluation.owndepth import csv_lines

    return csv_lines(dataset.record.depth, _record(pred))


def _record(pred: Path) -> dict | None:
    """``PRED/predictions.json`` when robodepth predict wrote PRED; None otherwise."""
    from ..predictions import read_record

    return read_record(pred) if pred.is_dir() else None


def _recorded(pred: Path) -> dict:
    """The ``evaluate`` defaults (kind, align, align_space) that ``PRED/predictions.json``
    records when robodepth predict wrote PRED; {} otherwise."""
    record = _record(pred)
    return record["evaluate"] if record else {}
