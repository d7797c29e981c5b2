"""``robodepth run``: a model's robustness on a benchmark, without writing the dataset."""

from __future__ import annotations

from pathlib import Path

import click

from . import common


@click.command("run")
@click.argument("dataset", metavar="DATASET")
@click.option("--root", required=True, type=click.Path(path_type=Path),
              help="KITTI raw root (with the velodyne scans), or the NYU Depth V2 test root or "
                   "labeled .mat, as for build.")
@click.option("--model", "-m", "spec", required=True, metavar="SPEC",
              help="The model, as for predict: monodepth2:DIR, hf:PATH_OR_NAME or "
                   "python:MODULE:CALLABLE.")
@click.option("--out", "-o", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The results CSV to write (replaced if it exists), as evaluate writes it.")
@common.selection_options
@click.option("--split", metavar="NAME|FILE", help="Standard split name (eigen_test, kitti_sequences, nyu_test) or a split file.")
@click.option("--compose", metavar="CHAIN,CHAIN", help="Also judge these chains of corruptions, e.g. fog:3+gaussian_noise:2.5.")
@click.option("--size", metavar="HxW", help="Image size HxW (preset: the benchmark's).")
@click.option("--engine", type=click.Choice(["numpy", "torch"]), default="numpy", show_default=True,
              help="The corruption engine (numpy: the published builds' bytes).")
@click.option("--batch-size", "-b", default=8, show_default=True, type=click.IntRange(min=1),
              help="Images per forward pass, as for predict (at most 4.2 million pixels).")
@common.model_device_option
@click.option("--post-process", is_flag=True,
              help="monodepth2: average with the mirror image's prediction (twice the work).")
@common.model_kind_option
@click.option("--metric/--relative", default=None,
              help="The maps are in metres or relative, as for predict.")
@common.severity_size_option("default: none, the benchmark's pixels")
@common.evaluation_options
@click.option("--keep-predictions", type=click.Path(file_okay=False, path_type=Path), metavar="DIR",
              help="Also write the predictions to DIR, in predict's layout (DIR/clean.npy, "
                   "DIR/<corruption>/<level>.npy, DIR/predictions.json).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of tables.")
@common.progress_option
def run_command(dataset, root, spec, out, config_file, engine, batch_size, device, post_process,
                kind, metric, stereo, align, align_space, crop, min_depth, max_depth,
                keep_predictions, as_json, progress, **flags):
    """Judge a model on DATASET (kitti-c, kitti-c-hr, nyudepth2-c) built in memory from ROOT:
    the results CSV of build -> predict -> evaluate, without writing the images.

    Each source image is decoded once; every variant's images are made from it in memory
    with the build's renderers and seeds (the bytes a build would write), predicted by the
    model in predict's batches and evaluated against the ground truth read from ROOT (KITTI:
    the velodyne scans, as build and gt make gt_depths.npz; NYU: the depth PNGs or the
    labeled file). The results CSV is the one evaluate writes; the scores follow, as
    evaluate --score prints them.

    The finished variants' rows are kept in OUT.state.json (written whole after each
    variant): a run stopped by Ctrl-C, a kill or a crash, started again with the same
    settings, skips them. The state is removed once OUT is written.

    \b
    Examples:
      robodepth run kitti-c --root KITTI_RAW --model monodepth2:models/mono_640x192 --out r.csv
      robodepth run nyudepth2-c --root NYU_TEST -m python:m.py:predict --kind depth --metric -o n.csv
      robodepth run kitti-c --root KITTI_RAW -m monodepth2:M --corruptions fog --levels 3 \\
          --limit 50 --keep-predictions PRED --out fog.csv
    """
    from ..running.session import RunSettings, run

    def on_state(path):
        common.on_interrupt(f"the finished variants are kept in {path}; rerun the same "
                            "command to continue")

    settings = RunSettings(
        dataset, root, out, spec, config_file, flags, engine=engine, batch_size=batch_size,
        device=device, post_process=post_process, kind=kind, metric=metric,
        evaluation=dict(stereo=stereo, align=align, align_space=align_space, crop=crop,
                        min_depth=min_depth, max_depth=max_depth),
        keep=keep_predictions, progress=progress)
    result, table, bench, replacing = run(settings, note=lambda line: click.echo(line, err=True),
                                          on_state=on_state)
    common.show_results(result, table, out, bench, as_json, replacing)
