"""``robodepth predict``: a depth model over a built dataset -> PRED, as evaluate reads it."""

from __future__ import annotations

from pathlib import Path

import click

from . import common


@click.command("predict")
@click.argument("dataset_dir", metavar="DATASET_DIR", type=click.Path(path_type=Path))
@click.option("--model", "-m", "spec", required=True, metavar="SPEC",
              help="monodepth2:DIR (encoder.pth + depth.pth), hf:PATH_OR_NAME (a transformers "
                   "depth model, local folder or local cache) or python:MODULE:CALLABLE.")
@click.option("--out", "-o", "pred", required=True, type=click.Path(path_type=Path),
              metavar="PRED", help="Where the predictions go (PRED/clean.npy, "
              "PRED/<corruption>/<level>.npy, PRED/predictions.json); for a challenge's public "
              "folder, the submission zip to write.")
@click.option("--variants", metavar="LIST",
              help="Only these variants: comma-separated clean, <corruption> (all its levels), "
                   "<corruption>/<level>, <style>. Default: every variant of the build.")
@click.option("--batch-size", "-b", default=8, show_default=True, type=int,
              help="Images per forward pass, at most what 4.2 million pixels hold (34 "
                   "images of 192x640; a larger value is lowered to that).")
@common.model_device_option
@click.option("--post-process", is_flag=True,
              help="monodepth2: average with the mirror image's prediction, as its "
                   "evaluate_depth.py --post_process does (twice the work).")
@common.model_kind_option
@click.option("--metric/--relative", default=None,
              help="The maps are in metres (evaluated with no alignment) or relative (evaluated "
                   "after a least-squares scale and shift of the disparity). python: default "
                   "relative; hf: the model's own.")
@common.progress_option
def predict_command(dataset_dir, spec, pred, variants, batch_size, device, post_process, kind,
                    metric, progress):
    """Run a depth model over DATASET_DIR (made by robodepth build) and write its predictions
    to PRED in the layout robodepth evaluate reads.

    A challenge's public folder as DATASET_DIR: PRED is the submission zip (docs/challenge.md).

    Every variant (or those of --variants) is run in split order; each variant's file is
    written whole or not at all, and a run started again skips the finished variants.
    PRED/predictions.json records the model and what its maps hold; robodepth evaluate takes
    its defaults (--kind, --align, --align-space) from it.

    \b
    Examples:
      robodepth predict KITTI_C --model monodepth2:models/mono_640x192 --out PRED
      robodepth predict KITTI_C -m hf:depth-anything/Depth-Anything-V2-Small-hf -o DA
      robodepth predict NYU_C -m python:mymodel.py:predict --kind depth --metric -o P
    """
    from ..challenge.predict import is_public_folder

    if is_public_folder(dataset_dir):
        return _challenge(dataset_dir, spec, pred, variants, batch_size, device, post_process, kind, metric, progress)
    from .. import open_dataset
    from ..models import load_model
    from ..models import predict
    from ..progress import bar as progress_bar

    dataset = open_dataset(dataset_dir, warn=False)  # a failed build: images() says which, one line
    chosen = predict.select_variants(dataset, variants)
    if batch_size < 1:
        raise click.BadParameter("must be at least 1", param_hint="--batch-size")
    model = load_model(spec, device=device, kind=kind, metric=metric, post_process=post_process)
    fits = predict.batch_limit(batch_size, dataset.size, model.input_size)
    if fits < batch_size:
        click.echo(f"robodepth: --batch-size {batch_size}: {fits} images per batch (a batch "
                   f"holds at most {predict.BATCH_PIXELS:,} pixels)", err=True)
    if model.device in ("cpu", "cuda"):  # chosen here (a python: callable chooses its own)
        # Said before the run, not after: a long CPU run where a GPU was expected shows at once.
        click.echo(f"robodepth: {model.spec} runs on {model.device} (--device {device})", err=True)
    common.on_interrupt(f"the variants finished so far are kept under {pred}, each complete; "
                        "rerun the same command to continue")
    with progress_bar("img", progress=progress) as bar:
        def set_total(n):
            bar.reset(total=n)  # the clock too: the time spent before the images is not theirs

        run = predict.predict(dataset, model, pred, chosen, batch_size=batch_size,
                        progress=bar.update, on_total=set_total)
    done = f"{len(run.written)} variants x {len(dataset.keys)} images"
    skipped = f" ({len(run.skipped)} already done, skipped)" if run.skipped else ""
    click.echo(f"{model.spec} on {model.device}: {done}{skipped} -> {pred}", err=True)
    if run.no_depth:
        first, why = next(iter(run.no_depth.items()))
        click.echo(f"robodepth: {len(run.no_depth)} image(s) without a usable depth map have no "
                   f"depth-aware images; their predictions there are NaN and evaluate leaves these "
                   f"images out ({first}: {why})", err=True)
    import shlex

    click.echo(f"next: robodepth evaluate {shlex.quote(str(dataset_dir))} --pred "
               f"{shlex.quote(str(pred))}", err=True)


def _challenge(public, spec, out, variants, batch_size, device, post_process, kind, metric, progress):
    """``predict`` on a challenge's public folder: the submission zip, in list order."""
    from ..challenge.predict import predict_submission
    from ..errors import RobodepthError
    from ..models import load_model
    from ..progress import bar as progress_bar

    if variants:
        raise RobodepthError("--variants: a challenge's public folder has no variants")
    if batch_size < 1:
        raise click.BadParameter("must be at least 1", param_hint="--batch-size")
    model = load_model(spec, device=device, kind=kind, metric=metric, post_process=post_process)
    with progress_bar("img", progress=progress) as bar:
        n = predict_submission(public, model, out, batch_size, progress=bar.update)
    click.echo(f"{model.spec} on {model.device}: {n} maps -> {out}; check it with: robodepth "
               f"challenge check {out} --public {public}", err=True)
