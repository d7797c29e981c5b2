"""``robodepth build`` and ``robodepth verify``: whole datasets and their manifests."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

import click

from ..errors import RobodepthError
from ..sources.datasets import DATASETS, CustomDataset, preset_names, zero_shot
from . import common

_LISTED = 20  # paths shown per kind of problem by verify
_ZERO_SHOT = ", ".join(zero_shot())
# The datasets' own split names and their default severity sizes, from their specs
_SPLITS = "".join(f"; {n}: {', '.join(dict(d.splits))}" for n, d in DATASETS.items() if d.splits)
_SEVERITY = "".join(f"; {d.severity_size} for {n}" for n, d in DATASETS.items()
                    if d.depth_in_root and d.severity_size != CustomDataset.severity_size)


def _naming_datasets(command):
    """The docstring with the datasets' names filled in (click reads it as the help)."""
    names = ", ".join(preset_names(lambda d: not d.depth_in_root))
    command.__doc__ = command.__doc__.replace("{datasets}", names).replace("{zero_shot}", _ZERO_SHOT)
    return command


@click.command("build")
@click.argument("dataset", metavar="DATASET")
@click.option("--root", required=True, type=click.Path(path_type=Path),
              help="KITTI raw root (holds 2011_09_26/...), the NYU Depth V2 test root, (custom) any folder of images, "
                   f"or a zero-shot set's download ({_ZERO_SHOT}).")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="Output directory; rerunning into it resumes.")
@common.selection_options
@click.option("--split", metavar="NAME|FILE", help=f"Standard split name (eigen_test, kitti_sequences, nyu_test{_SPLITS}) or a split file.")
@click.option("--compose", metavar="CHAIN,CHAIN", help="Also build these chains of corruptions, e.g. "
              "fog:3+gaussian_noise:2.5 (into OUT/fog-3+gaussian_noise-2.5/); --corruptions none: only them.")
@click.option("--size", metavar="HxW", help="Output size HxW (e.g. 320x1024); custom: each image's own size unless given.")
@click.option("--jobs", "-j", metavar="N|auto", help="Worker processes (preset: 2); 'auto' or -1: one per CPU.")
@click.option("--frames", metavar="-1,1", help="kitti-c: also write these neighbours of every test frame "
              "from its raw drive (offsets), corrupted consistently with it; see docs/video.md.")
@click.option("--pattern", metavar="GLOB,GLOB", help="custom: which files under ROOT (default: png, jpg, jpeg, bmp, tif, tiff, webp at any depth, any case), e.g. '**/*_leftImg8bit.png'.")
@click.option("--list", metavar="FILE", help="custom: build exactly these images, in this order (one path relative to ROOT a line).")
@click.option("--depth", metavar="DIR", help="custom: the depth maps of the images, paired by --depth-pattern "
              "(default: the image's relative path with a depth extension), written to OUT/gt/ for evaluate.")
@click.option("--depth-pattern", metavar="TEMPLATE", help="custom/zero-shot: where an image's depth map is under "
              "the depth directory, from {path} {dir} {stem} {name} {ext} {digits} {prefix} {parts[i]}, e.g. '{dir}/{stem}_depth.npy'.")
@click.option("--depth-mask", metavar="TEMPLATE", help="custom/zero-shot: a mask file per image (0 = invalid), "
              "a template like --depth-pattern.")
@click.option("--depth-camera", metavar="TEMPLATE", help="custom/zero-shot: the camera file of each "
              "Cityscapes disparity (--depth-format cityscapes), a template like --depth-pattern.")
@click.option("--depth-scale", metavar="S", help="custom/zero-shot: the depth files hold depth x S (256 "
              "KITTI-style PNGs, 1000 millimetres); needed for 16-bit PNGs.")
@click.option("--depth-format", type=click.Choice(["png", "npy", "npz", "pfm", "exr", "dpt", "raw", "cityscapes"]),
              help="custom/zero-shot: read every depth file in this form (default: by its extension).")
@click.option("--depth-size", type=click.Choice(["match", "any"]), help="custom/zero-shot: match (default): "
              "a depth map must have its image's size; any: any size.")
@click.option("--scene-depth", metavar="PRED", help="The depth of the depth-aware corruptions (fog_3d, ...) "
              "from a model's predictions for the clean images (robodepth predict's --out) instead of the "
              "dataset's own; relative maps are median-scaled to the dataset's depth.")
@common.severity_size_option(
    "default: none for " + ", ".join(preset_names(lambda d: d.leveled and not d.severity_size))
    + f", the benchmark's pixels{_SEVERITY}; {CustomDataset.severity_size} for custom and the "
    "other zero-shot sets; see docs/severity-and-chains.md")
@click.option("--styles", metavar="DIR", help="kitti-s: the style images, <style>.jpg/.jpeg/.png.")
@click.option("--only-styles", metavar="A,B|all", help="kitti-s: comma-separated style names, or 'all'.")
@click.option("--vgg", metavar="FILE", help="kitti-s: AdaIN encoder checkpoint (vgg_normalised.pth).")
@click.option("--decoder", metavar="FILE", help="kitti-s: AdaIN decoder checkpoint (decoder.pth).")
@click.option("--alpha", metavar="A", help="kitti-s: style strength 0..1 (preset: 1).")
@click.option("--style-size", metavar="N", help="kitti-s: shorter side of the style images (preset: 512).")
@click.option("--engine", type=click.Choice(["numpy", "torch"]),
              help="kitti-c, nyudepth2-c, custom: the corruption engine (default numpy, the published "
                   "bytes; torch: the torch engine on --device, see docs/torch-engine.md).")
@click.option("--device", metavar="auto|cpu|cuda", help="kitti-s: where AdaIN runs (preset: auto, a CUDA GPU "
              "when there is one, else the CPU; the build says which). With --engine torch: where the "
              "corruptions run (default auto).")
@click.option("--scheduler", metavar="ADDR", help="Run on the Dask cluster of this scheduler (tcp://HOST:8786); "
              "ROOT and OUT must be shared paths every worker sees.")
@click.option("--scheduler-file", metavar="FILE", help="Like --scheduler, with the address read from the "
              "scheduler's JSON file (dask scheduler --scheduler-file, dask-jobqueue, dask-mpi).")
@click.option("--png", type=click.Choice(["fast", "compact"]),
              help="How the PNGs are written, same pixels either way: fast (fpng, ~8x less CPU, "
                   "files ~25% larger) or compact (libpng, smaller files). Default: the way OUT "
                   "was built, else fast.")
@click.option("--gt/--no-gt", default=True, show_default=True,
              help="Also write the ground truth: OUT/gt_depths.npz (KITTI, from the velodyne scans), "
                   "OUT/gt/<scene>/sync_depth_N.png (NYU) or OUT/gt/<image>.npy (custom --depth, "
                   "the zero-shot sets).")
@common.progress_option
@_naming_datasets
def build_command(dataset, root, out, config_file, progress, gt, **flags):
    """Build DATASET ({datasets}, or a zero-shot set: {zero_shot}) from ROOT into OUT.

    Writes OUT/clean/<image>, OUT/<corruption>/<level>/<image> and (--compose)
    OUT/<chain>/<image> (kitti-s: OUT/<style>/<image>) as PNG, where <image> is
    the source's path (KITTI: kitti_data/<date>/<drive>/image_02/data/<frame>.png), plus
    OUT/manifest.csv (one row and sha256 per file) and OUT/build.json (config, versions).
    Settings come from configs/DATASET.yaml, then --config FILE, then the flags.

    The ground truth comes with the images (--no-gt: not): KITTI's OUT/gt_depths.npz from
    ROOT/<date>/<drive>/velodyne_points (if a scan is missing, a note says so and
    'robodepth gt kitti' makes it later), NYU's OUT/gt/<scene>/sync_depth_N.png. For
    nyudepth2-c, ROOT may be the official nyu_depth_v2_labeled.mat instead of a BTS folder.
    A custom build with --depth DIR and the zero-shot sets write each image's depth map as
    OUT/gt/<image>.npy (float32 metres, NaN where invalid, at the map's own size).

    Rerunning the same command redoes only missing or changed outputs. Exit status: 0 all
    done, 1 some images failed (the rest is built; see the summary), 2 refused before any
    work (bad config, root, split or OUT; another build running there) or stopped by a
    write error such as a full disk (finished images kept), 130 interrupted (resumable).

    \b
    Examples:
      robodepth build kitti-c --root KITTI_RAW --out KITTI_C
      robodepth build nyudepth2-c --root NYU_TEST --out NYU_C --jobs 2
      robodepth build nyudepth2-c --root nyu_depth_v2_labeled.mat --out NYU_C
      robodepth build kitti-c --root KITTI_RAW --out /tmp/look --limit 2 --levels 3
      robodepth build kitti-c --root KITTI_RAW --out KITTI_CC --corruptions none \\
          --compose fog:3+gaussian_noise:2.5,dark:2+motion_blur:1.5
      robodepth build kitti-s --root KITTI_RAW --styles STYLES --vgg vgg_normalised.pth \\
          --decoder decoder.pth --out KITTI_S
      robodepth build kitti-c --root /shared/kitti_raw --out /shared/KITTI_C \\
          --scheduler tcp://head:8786
      robodepth build custom --root cityscapes/leftImg8bit/val --out CITYSCAPES_C \\
          --pattern '**/*_leftImg8bit.png' --levels 3
      robodepth build custom --root MINE/rgb --depth MINE/depth --depth-scale 1000 --out MINE_C
      robodepth build diode-c --root DIODE/val --out DIODE_C
      robodepth build drivingstereo-c --root DS --split foggy --corruptions none --out DS_FOGGY
    """
    from ..building.pipeline import build
    from ..building.config import resolve

    interrupted = "robodepth: interrupted; rerun the same command to resume"
    # The group turns a scheduler's SIGTERM (end of a job's time) into KeyboardInterrupt.
    common.on_interrupt("rerun the same command to resume")
    try:
        if flags["scheduler"] and flags["scheduler_file"]:
            raise RobodepthError("--scheduler and --scheduler-file: give one of them, not both")
        cfg = resolve(dataset, config_file, flags)
        for note in cfg.notes:
            click.echo(f"note: {note}", err=True)
        with _executor(cfg) as executor:
            summary = build(cfg, root, out, progress=progress, command=common.typed_argv(),
                            executor=executor, gt=gt)
    except KeyboardInterrupt:  # before or after the images (the build itself handles its own)
        click.echo(interrupted, err=True)
        sys.exit(130)
    _exit(cfg, summary, interrupted)


def _exit(cfg, summary, interrupted: str) -> None:
    """The build's summary line, then its exit status: 130 interrupted, 2 stopped by a
    write error, 1 some images failed, 0 (returning) all done."""
    click.echo(f"{cfg.preset}: {summary.text()}", err=True)
    if summary.interrupted:
        click.echo(interrupted, err=True)
        sys.exit(130)
    if summary.fatal:
        raise RobodepthError(f"{summary.fatal}; finished images are kept, rerun to resume")
    if summary.failed:
        sys.exit(1)


def _executor(cfg):
    """A Dask cluster's executor if the configuration names a scheduler; otherwise
    nothing (the builder's local pool), and dask is never imported."""
    if not (cfg.scheduler or cfg.scheduler_file):
        return contextlib.nullcontext()
    from ..building.cluster import DaskExecutor

    return DaskExecutor(cfg.scheduler, cfg.scheduler_file)


@click.command("verify")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--against", metavar="OTHER", type=click.Path(path_type=Path),
              help="Also compare OUT with another build of the same dataset (its folder, its "
                   "export's folder or its manifest.csv): per variant, outputs identical, "
                   "differing or missing.")
@common.progress_option
def verify_command(out, against, progress):
    """Re-hash every file in OUT against OUT/manifest.csv and the build's plan.

    OUT may be an export (robodepth export): every image in its shards is hashed against
    the build's manifest it carries, and changed, missing or extra rows are named.

    Reports a build that did not finish (outputs its plan asks for that were never made),
    files that are missing, changed or extra (not in the manifest), and images the build
    recorded as failed, with the reason; and, in one line, the libraries that decide pixels
    which the build used at other versions than robodepth's lock.

    --against OTHER then compares the two builds output by output (OTHER: a build's folder,
    an export's folder, or a manifest.csv alone): for each variant, how many outputs are
    identical, differ, or are missing here (OTHER only) or there (OUT only), and the largest
    pixel difference of the differing ones where both files can be read. Where a side's
    files are at hand, what they hold is compared: a file deleted counts as missing on its
    side, and one that does not match its own manifest as differing.

    Exit status 0 when everything matches, 1 otherwise (--against: any output not
    identical); 2 if OUT cannot be verified (no manifest, a damaged one, or a build writing
    there right now).
    """
    from ..export.reader import is_export
    from ..building.checks import planned_outputs
    from ..output.verify import verify
    from ..progress import bar as progress_bar

    if against is not None:  # a wrong OTHER is refused before OUT is hashed
        _check_against(out, against)
    with progress_bar("file", progress=progress) as bar:
        if is_export(out):  # robodepth export's folder: its shards against the carried manifest
            from ..export.verify import verify_export

            report = verify_export(out, progress=bar.update)
        else:
            # The total is known once the manifest is read; reset() also restarts the clock.
            report = verify(out, planned_outputs=planned_outputs, progress=bar.update,
                            on_total=lambda n: bar.reset(total=n))
    if report.incomplete():
        click.echo(report.incomplete())
    if report.versions_note:
        click.echo(f"{out}: {report.versions_note}")
    for kind in ("missing", "changed", "extra"):
        paths = getattr(report, kind)
        if paths:
            click.echo(f"{kind}: {len(paths)}")
            _list(paths, "  ")
    if report.failed:
        _list_failed(report)
    if report.ok:
        click.echo(f"{out}: {report.checked} files match the manifest")
    else:
        click.echo(f"{out}: {report.checked} files checked; the tree does not match its manifest", err=True)
    same = _against(out, report, against, progress) if against is not None else True
    if not (report.ok and same):
        sys.exit(1)


def _list_failed(report) -> None:
    """The images the build recorded as failed, under their reasons."""
    click.echo(f"failed: {len(report.failed)}")
    by_reason: dict[str, list[str]] = {}
    for p in report.failed:
        by_reason.setdefault(report.reasons.get(p) or "no reason recorded", []).append(p)
    for reason, paths in list(by_reason.items())[:_LISTED]:
        click.echo(f"  {reason}")
        _list(paths, "    ")
    if len(by_reason) > _LISTED:
        click.echo(f"  ... and {len(by_reason) - _LISTED} more reasons")


def _against(out: Path, report, other: Path, progress) -> bool:
    """Print OUT's comparison with OTHER, variant by variant; whether every output is identical.
    ``report``: OUT's verify report (its deleted and changed files count)."""
    from ..output.compare import Side, compare, disk_files
    from ..output.folder import OutputFolder

    mine = Side({p: r for p, r in OutputFolder(out).recorded().items() if not r.error},
                set(report.missing), set(report.changed), disk_files(out))
    variants = compare(mine, _other_side(other, progress))
    total = sum(v.outputs for v in variants.values())
    bad = total - sum(v.identical for v in variants.values())
    for name, v in variants.items():
        click.echo(f"{name}: {v.text()}")
    if not bad:
        click.echo(f"{out}: all {total} outputs identical to {other}")
        return True
    click.echo(f"{out}: {bad} of {total} outputs differ from {other} or are missing on one side", err=True)
    return False


def _check_against(out: Path, other: Path) -> None:
    from ..export.layout import META
    from ..export.reader import is_export
    from ..output.compare import other_rows

    if is_export(out):
        raise RobodepthError("--against: OUT is an export; compare the builds it was made from")
    other_rows(other / META if is_export(other) else other)


def _other_side(other: Path, progress):
    """OTHER as a side of the comparison: a build's folder with its files re-hashed, an
    export's with its shards read, or a manifest file by its rows alone."""
    from ..export.layout import META
    from ..export.reader import export_files, is_export
    from ..output.compare import Side, disk_files, other_rows
    from ..output.manifest import ManifestError

    if Path(other).is_file():
        rows, base = other_rows(other)
        return Side(rows, files=disk_files(base))
    export = is_export(other)
    rows, base = other_rows(Path(other) / META if export else other)
    from ..progress import bar as progress_bar

    with progress_bar("file", progress=progress) as bar:
        if export:
            from ..export.verify import verify_export

            report = verify_export(other, progress=bar.update)
            files = lambda paths: export_files(other, paths)  # noqa: E731
        else:
            from ..output.verify import verify

            try:
                report = verify(other, planned_outputs=lambda record: None, progress=bar.update,
                                on_total=lambda n: bar.reset(total=n))
            except ManifestError as exc:
                raise ManifestError(f"--against: {exc}") from None
            files = disk_files(Path(other))
    return Side(rows, set(report.missing) & rows.keys(), set(report.changed) & rows.keys(), files)


def _list(paths: list[str], indent: str) -> None:
    for p in paths[:_LISTED]:
        click.echo(f"{indent}{p}")
    if len(paths) > _LISTED:
        click.echo(f"{indent}... and {len(paths) - _LISTED} more")
