"""``robodepth stats``: what each corruption of a build does to its pixels."""

from __future__ import annotations

from pathlib import Path

import click

from . import common


@click.command("stats")
@click.argument("build", metavar="BUILD", type=click.Path(file_okay=False, path_type=Path))
@click.option("--out", "-o", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory to write stats.json and histograms.svg, .pdf, .png into "
                   "(created if needed; those files replaced).")
@click.option("--level", default=3, show_default=True, type=click.IntRange(min=1),
              help="The level the histogram figure shows, one panel per corruption (a build "
                   "of styles: every style).")
@click.option("--images", "most", type=click.IntRange(min=1), metavar="N",
              help="Use N images, evenly spaced over the split (default: all).")
@common.progress_option
def stats_command(build, out, level, most, progress):
    """Pixel statistics of BUILD (made by robodepth build): per variant, the histogram of
    the pixel values per channel, the mean and spread against the clean images', and PSNR
    and SSIM against the clean image, in OUT/stats.json; the histograms of every corruption
    at --level in OUT/histograms.svg, .pdf and .png.

    The build is read image by image (memory does not grow with its size); every variant
    of an image is compared with its clean image.

    \b
    Examples:
      robodepth stats KITTI_C --out stats/
      robodepth stats KITTI_C --out stats/ --level 5 --images 100
    """
    import json

    from ..api import open_dataset
    from ..files import check_writable, write_atomic
    from ..progress import bar as progress_bar
    from ..report import pixels
    from ..report.plot import close, load_matplotlib, save

    load_matplotlib()  # refuse before the work when matplotlib is missing
    check_writable(out / "stats.json" if out.is_dir() else out, "--out")
    dataset = open_dataset(build, warn=False)
    pixels.check_level([v.level for v in dataset.variants()], level)
    n = len(pixels.chosen(len(dataset.keys), most))
    with progress_bar("img", n, progress=progress) as bar:
        clean, sums = pixels.collect(dataset, most, bar.update)
    doc = pixels.to_json(dataset, clean, sums, most)
    fig = pixels.figure(doc, level)
    common.will_write(out / "stats.json")
    save(fig, out / "histograms")
    close(fig)
    write_atomic(out / "stats.json", (json.dumps(doc, allow_nan=False) + "\n").encode("utf-8"))
    click.echo(f"wrote {out / 'stats.json'} and {out / 'histograms.png'} ({len(sums)} variants x "
               f"{doc['images']} images of {dataset.path})", err=True)
