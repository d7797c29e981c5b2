"""``robodepth export``: a finished build as Hugging Face parquet or WebDataset shards."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import InvalidValueError, RobodepthError


@click.command("export")
@click.argument("out", metavar="OUT", type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["parquet", "webdataset"]), required=True,
              help="parquet: the Hugging Face layout (datasets.load_dataset reads it); "
                   "webdataset: tar shards.")
@click.option("--to", "to", required=True, type=click.Path(path_type=Path), metavar="DIR",
              help="The export's folder: new, empty, or a stopped export of the same build "
                   "and options (it resumes).")
@click.option("--shard-size", default="500MB", show_default=True, metavar="SIZE",
              help="Most bytes of images per shard (kB, MB, GB).")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bar with an ETA on stderr (only on a terminal).")
def export_command(out, fmt, to, shard_size, progress):
    """Export the finished build OUT into DIR as shards, every file byte for byte.

    \b
    parquet: DIR/data/<config>/<split>-00000-of-00002.parquet, one configuration per
    variant (clean, each corruption, style or chain, and ground_truth), one split per level
    (level_3; test without levels), and DIR/README.md, the dataset card whose YAML header
    datasets.load_dataset and the Hugging Face Hub read. webdataset: the same names as
    .tar shards, one sample per image (<key>.png, <key>.json). The ground truth: one row
    per image, its depth map as a float32 array (parquet: depth; tar: <key>.depth.npy), no
    pickle. Either way DIR/robodepth/
    carries the build's manifest.csv and build.json, and robodepth verify DIR checks every
    image against that manifest. Each shard is written whole or not at all; rerunning the
    command resumes. Nothing is uploaded.

    \b
    Examples:
      robodepth export KITTI_C --format parquet --to KITTI_C_HF
      robodepth export KITTI_C --format webdataset --to KITTI_C_WDS --shard-size 1GB
    """
    from .. import __version__
    from ..api import open_dataset
    from ..export.plan import parse_size
    from ..export.driver import export
    from .common import on_interrupt

    try:
        size = parse_size(shard_size)
    except InvalidValueError as exc:
        raise RobodepthError(f"--shard-size {exc}") from None
    on_interrupt(f"finished shards are kept in {to}; rerun the command to resume")
    summary = export(out, to, fmt, size, open_dataset=open_dataset, progress=progress,
                     version=__version__)
    ratio = summary.size / summary.source_size if summary.source_size else 1.0
    click.echo(f"{to}: {summary.rows} rows in {summary.shards} {fmt} shards "
               f"({summary.written} written now), {summary.size / 1e6:.1f} MB "
               f"({ratio:.3f} x the build's {summary.source_size / 1e6:.1f} MB)", err=True)
    if summary.no_depth:
        first, why = next(iter(summary.no_depth.items()))
        click.echo(f"robodepth: {len(summary.no_depth)} image(s) without a usable depth map have no "
                   f"ground truth and no depth-aware images in the export ({first}: {why})", err=True)
    click.echo(f"next: robodepth verify {to}", err=True)
