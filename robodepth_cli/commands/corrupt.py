"""``robodepth list``, ``corrupt`` and ``preview``: the corruptions on single images."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from ..benchmark_facts import DEPTH_AWARE
from ..errors import RobodepthError
from ..files import check_writable
from . import common


def _depth_options(command):
    """``--depth`` and ``--depth-scale`` of ``corrupt`` and ``preview``, declared once; the
    help names the depth-aware corruptions from the registry's list."""
    command = click.option("--depth-scale", type=float, metavar="S",
                           help="A 16-bit depth PNG's value per metre: 256 for KITTI, 1000 for "
                                "millimetres (NYU).")(command)
    return click.option("--depth", "depth_file", type=click.Path(dir_okay=False), metavar="FILE",
                        help=f"The scene's depth, which {', '.join(DEPTH_AWARE)} need: a .npy of "
                             f"metres or a 16-bit PNG (with --depth-scale).")(command)


@click.command("list")
@click.option("--format", "fmt", type=click.Choice(["text", "markdown", "json"]), default="text",
              show_default=True, help="Plain table, the Markdown table of docs/corruptions.md, or JSON.")
def list_command(fmt):
    """List the corruptions (the benchmarks' 18, then those that also need the scene's
    depth) with their category and per-level parameters."""
    from ..corruptions import REGISTRY
    from ..listing import corruption_table

    if fmt == "json":
        import json

        click.echo(json.dumps([
            {"name": c.name, "category": c.category, "deterministic": c.deterministic,
             "needs_depth": c.needs_depth, "scaled": c.scaled,
             "levels": [c.params(lv) for lv in range(1, c.n_levels + 1)],
             "between_levels": dict(zip(c.fields, c.rules)), "formula": c.doc}
            for c in REGISTRY.values()], indent=2))
    else:
        click.echo(corruption_table(markdown=(fmt == "markdown")))


@click.command("corrupt")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--corruption", "-c", "corruption", required=True, metavar="NAME|CHAIN|all",
              help="A corruption name (see `robodepth list`), a chain such as "
                   "fog:3+gaussian_noise:2.5 (a step without :LEVEL takes each -l level), a "
                   "comma list of these, or 'all'.")
@click.option("--level", "-l", default="all", show_default=True, metavar="S|all",
              help="Level 1..5, decimals allowed (2.5), a comma list, or 'all' (1,2,3,4,5).")
@click.option("--seed", "-s", default=0, show_default=True, type=int,
              help="Seed of the random corruptions (an integer >= 0).")
@click.option("--size", metavar="HxW", help="First resize the input as a build does (Lanczos), e.g. 192x640.")
@click.option("--out", "-o", required=True, type=click.Path(),
              help="Output .png for one image; otherwise (or ending with /) a directory "
                   "receiving NAME/LEVEL.png and CHAIN.png (e.g. fog-3+gaussian_noise-2.5.png).")
@_depth_options
@common.severity_size_option("default: none")
@common.as_option
def corrupt_command(image, corruption, level, seed, size, out, depth_file, depth_scale, severity_size,
                    draw_as):
    """Corrupt one image (its EXIF orientation applied first).

    \b
    robodepth corrupt frame.png -c zoom_blur -l 3 --out zoom3.png
    robodepth corrupt frame.png -c fog -l 1,1.5,2 --out out/      # out/fog/1.png ...
    robodepth corrupt frame.png -c fog:3+gaussian_noise:2.5 --out fog_noise.png
    robodepth corrupt frame.png -c all -l all --size 192x640 --out corrupted/
    robodepth corrupt frame.png -c fog_3d -l 3 --depth depth.png --depth-scale 256 --out f.png
    robodepth corrupt big.png -c defocus_blur -l 3 --severity-size 192x640 --out d.png
    robodepth corrupt OUT/clean/a.png -c fog -l 3 --as custom:a.png --severity-size 192x640 --out f.png

    The random draws are keyed by the seed, the corruption, the level and the image's
    pixels (after --size): byte-identical copies give the same output. --as DATASET:KEY
    draws as a build of DATASET does for its source KEY (manifest.csv's source column, or
    the image's path under OUT/clean/): from
    the build's clean image, with the build's --seed and severity size, it remakes the
    build's pixels.
    """
    from ..corruptions import render

    seed = common.seed(seed)
    severity_size = common.severity_size(severity_size)
    level_list = common.levels(level)
    jobs = common.variants(corruption, level_list)
    single = len(jobs) == 1 and "all" not in corruption.replace(" ", "").split(",")
    directory = Path(out)
    if single:
        target = common.png_output(out, jobs[0][0])
    elif not common.means_directory(out):
        if directory.exists():
            raise RobodepthError(f"{out}: is a file; several outputs need a directory")
        if directory.suffix:
            what = _describe(common.items(corruption, level_list), level_list)
            raise RobodepthError(
                f"--out {out}: looks like a file name, but {what} make "
                f"{len(jobs)} images, which go into a directory; pick one corruption and one "
                f"level (-c NAME -l N), or one chain, to write that file, or end the name with / "
                f"to make it a directory")
    check_writable(target if single else directory / jobs[0][0], "--out")  # before any work
    clean = common.load_input(image, size)
    depth = _depth(depth_file, depth_scale, [v for _, v, _ in jobs], clean)
    dataset, key = common.draw_as(draw_as, clean)
    if not single:
        common.on_interrupt(f"the images written so far are kept under {out}, each complete")
    for name, variant, lv in jobs:
        img = render(clean, variant, lv, seed=seed, dataset=dataset, key=key, depth=depth,
                     severity_size=severity_size)
        common.write_png(target if single else directory / name, img)
    if single:
        common.wrote(f"{target} ({common.hxw(*img.shape[:2])})")
    else:
        common.wrote(f"{len(jobs)} images under {out}")


def _depth(path: str | None, scale: float | None, variants: list[str], clean: np.ndarray):
    """The depth map of ``--depth`` (None without it), checked against the image; a
    depth-aware corruption without one is refused before any work."""
    from ..corruptions import needs_depth
    from ..corruptions.depth import DepthError, scene_depth
    from ..sources.depthfile import read_depth

    if path is None:
        if scale is not None:
            raise RobodepthError("--depth-scale: is for a 16-bit --depth PNG, and no --depth was given")
        aware = next((v for v in variants if needs_depth(v)), None)
        if aware:
            raise RobodepthError(f"--corruption {aware}: needs the scene's depth; give --depth FILE "
                                 f"(.npy in metres, or a 16-bit PNG with --depth-scale)")
        return None
    depth = read_depth(path, scale)
    try:
        scene_depth(depth, clean.shape[:2])
    except DepthError as exc:
        raise RobodepthError(f"--depth {path}: {str(exc).removeprefix('depth: ')}") from None
    return depth


def _describe(items: list[str], level_list: list) -> str:
    """``"fog at levels 1,2,3,4,5"``, ``"fog+snow at levels 1,2"`` or ``"3 corruptions and
    chains at level 2"``, for messages: what ``-c`` names, and the ``-l`` levels when a
    corruption or a chain template takes them."""
    from ..corruptions import level_text
    from ..corruptions.chains import looks_like_chain, parse_chain

    def takes_levels(item: str) -> bool:
        if not looks_like_chain(item):
            return True
        try:
            parse_chain(item)
        except RobodepthError:  # a step without a level: a template
            return True
        return False

    what = items[0] if len(items) == 1 else f"{len(items)} corruptions and chains"
    if not any(takes_levels(i) for i in items):
        return what
    levels = ",".join(map(level_text, level_list))
    return f"{what} at level{'s' if len(level_list) > 1 else ''} {levels}"


@click.command("preview")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--out", "-o", required=True, type=click.Path(),
              help="The contact sheet (.png); a directory (or a name ending with /) receives "
                   "IMAGE_preview.png.")
@click.option("--corruption", "-c", "corruption", default="all", show_default=True, metavar="NAME|CHAIN|all",
              help="Rows: 'all' or a comma list of corruptions and chains (a chain step without "
                   ":LEVEL takes each column's level, e.g. fog+gaussian_noise; a chain whose "
                   "steps all have a level is drawn once, in the first column).")
@click.option("--levels", "-l", "level", default="all", show_default=True, metavar="S|all",
              help="Columns: levels 1..5, decimals allowed, as a comma list (1,1.5,2), or 'all' (1..5).")
@click.option("--size", metavar="HxW", help="First resize the input (Lanczos), e.g. 192x640.")
@click.option("--seed", "-s", default=0, show_default=True, type=int, help="An integer >= 0.")
@click.option("--thumb-width", default=320, show_default=True, type=click.IntRange(32, 2000),
              help="Width of each cell in pixels.")
@_depth_options
@common.severity_size_option("default: none")
@common.as_option
def preview_command(image, out, corruption, level, size, seed, thumb_width, depth_file, depth_scale,
                    severity_size, draw_as):
    """A labelled contact sheet: the clean image, then one row per corruption or chain and
    one column per level.

    \b
    robodepth preview frame.png -c fog,contrast --out sheet.png
    robodepth preview frame.png -c fog,fog+gaussian_noise -l 1,1.5,2,2.5,3 --out sheet.png

    Each cell is drawn as robodepth corrupt draws it (from the image's pixels, or --as).
    """
    from ..preview import contact_sheet

    seed = common.seed(seed)
    severity_size = common.severity_size(severity_size)
    target = common.png_output(out, f"{Path(image).stem}_preview.png")
    level_list = common.levels(level, "--levels")
    rows = common.items(corruption, level_list)
    check_writable(target, "--out")  # before any work
    clean = common.load_input(image, size)
    depth = _depth(depth_file, depth_scale, rows, clean)
    dataset, key = common.draw_as(draw_as, clean)
    sheet = contact_sheet(clean, rows, level_list, seed=seed, dataset=dataset, key=key,
                          thumb_width=thumb_width, depth=depth, severity_size=severity_size)
    common.write_png(target, np.asarray(sheet))
    common.wrote(f"{target} ({common.hxw(sheet.height, sheet.width)})")
