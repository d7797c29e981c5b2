"""``robodepth list``, ``corrupt`` and ``preview``: the corruptions on single images."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from ..errors import RobodepthError
from . import common


@click.command("list")
@click.option("--format", "fmt", type=click.Choice(["text", "markdown", "json"]), default="text",
              show_default=True, help="Plain table, the README's Markdown table, or JSON.")
def list_command(fmt):
    """List the 18 corruptions with their category and per-level parameters."""
    from ..corruptions import REGISTRY
    from ..docs import corruption_table

    if fmt == "json":
        import json

        click.echo(json.dumps([
            {"name": c.name, "category": c.category, "deterministic": c.deterministic,
             "levels": [c.params(lv) for lv in range(1, c.n_levels + 1)],
             "between_levels": dict(zip(c.fields, c.rules)), "formula": c.doc}
            for c in REGISTRY.values()], indent=2))
    else:
        click.echo(corruption_table(markdown=(fmt == "markdown")))


@click.command("corrupt")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--corruption", "-c", "corruption", required=True, metavar="NAME|all",
              help="A corruption name (see `robodepth list`), a comma list, or 'all'.")
@click.option("--level", "-l", default="all", show_default=True, metavar="N|all",
              help="Level 1..5, a comma list, or 'all'.")
@click.option("--seed", "-s", default=0, show_default=True, type=int,
              help="Seed of the random corruptions (an integer >= 0).")
@click.option("--size", metavar="HxW", help="First resize the input as a build does (Lanczos), e.g. 192x640.")
@click.option("--out", "-o", required=True, type=click.Path(),
              help="Output .png for one corruption at one level; otherwise (or ending with /) "
                   "a directory receiving NAME/LEVEL.png.")
def corrupt_command(image, corruption, level, seed, size, out):
    """Corrupt one image (its EXIF orientation applied first).

    \b
    robodepth corrupt frame.png -c zoom_blur -l 3 --out zoom3.png
    robodepth corrupt frame.png -c all -l all --size 192x640 --out corrupted/
    """
    from ..corruptions import corrupt
    from ..seeding import job_rng

    seed = common.seed(seed)
    names = common.corruption_names(corruption)
    levels = common.levels(level)
    single = len(names) == 1 and len(levels) == 1 and corruption != "all" and level != "all"
    directory = Path(out)
    if single:
        target = common.png_output(out, f"{names[0]}/{levels[0]}.png")
    elif not common.means_directory(out):
        if directory.exists():
            raise RobodepthError(f"{out}: is a file; several outputs need a directory")
        if directory.suffix:
            raise RobodepthError(
                f"--out {out}: looks like a file name, but {_describe(names, levels)} make "
                f"{len(names) * len(levels)} images, which go into a directory; pick one "
                f"corruption and one level (-c NAME -l N) to write that file, or end the name "
                f"with / to make it a directory")
    clean = common.load_input(image, size)
    key = Path(image).name
    written = 0
    for name in names:
        for lv in levels:
            img = corrupt(clean, name, lv, job_rng(seed, "image", name, lv, key))
            common.write_png(target if single else directory / name / f"{lv}.png", img)
            written += 1
    if single:
        click.echo(f"wrote {target} ({img.shape[1]} x {img.shape[0]})")
    else:
        click.echo(f"wrote {written} images under {out}")


def _describe(names: list[str], levels: list[int]) -> str:
    """``"fog at levels 1,2,3,4,5"`` or ``"3 corruptions at level 2"``, for messages."""
    what = names[0] if len(names) == 1 else f"{len(names)} corruptions"
    at = f"level {levels[0]}" if len(levels) == 1 else f"levels {','.join(map(str, levels))}"
    return f"{what} at {at}"


@click.command("preview")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--out", "-o", required=True, type=click.Path(),
              help="The contact sheet (.png); a directory (or a name ending with /) receives "
                   "IMAGE_preview.png.")
@click.option("--corruption", "-c", "corruption", default="all", show_default=True, metavar="NAME|all",
              help="Rows: 'all' or a comma list of corruptions.")
@click.option("--size", metavar="HxW", help="First resize the input (Lanczos), e.g. 192x640.")
@click.option("--seed", "-s", default=0, show_default=True, type=int, help="An integer >= 0.")
@click.option("--thumb-width", default=320, show_default=True, type=click.IntRange(32, 2000),
              help="Width of each cell in pixels.")
def preview_command(image, out, corruption, size, seed, thumb_width):
    """A labelled contact sheet: the clean image, then one row per corruption and one column per level."""
    from ..benchmarks import N_LEVELS
    from ..preview import contact_sheet

    seed = common.seed(seed)
    target = common.png_output(out, f"{Path(image).stem}_preview.png")
    names = common.corruption_names(corruption)
    clean = common.load_input(image, size)
    sheet = contact_sheet(clean, names, range(1, N_LEVELS + 1), seed=seed, key=Path(image).name,
                          thumb_width=thumb_width)
    common.write_png(target, np.asarray(sheet))
    click.echo(f"wrote {target} ({sheet.width} x {sheet.height})")
