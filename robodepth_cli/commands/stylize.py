"""``robodepth stylize``: one image in one AdaIN style, as a KITTI-S build renders it."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import InvalidValueError
from . import common

@click.command("stylize")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--style", required=True, type=click.Path(dir_okay=False), help="The style image.")
@click.option("--vgg", required=True, type=click.Path(dir_okay=False),
              help="AdaIN encoder checkpoint (vgg_normalised.pth).")
@click.option("--decoder", required=True, type=click.Path(dir_okay=False),
              help="AdaIN decoder checkpoint (decoder.pth).")
@click.option("--alpha", default=1.0, show_default=True, type=float,
              help="Style strength, 0..1: 0 decodes the content's own features.")
@click.option("--style-size", default=512, show_default=True, type=int,
              help="Resize the style image so its shorter side is N (bilinear); 0 keeps it.")
@click.option("--size", metavar="HxW", help="First resize the input (Lanczos) as a build does, "
              "e.g. 192x640; default: keep its size.")
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True,
              help="Where AdaIN runs: auto is a CUDA GPU when there is one, else the CPU.")
@click.option("--out", "-o", required=True, type=click.Path(),
              help="Output .png; a directory (or a name ending with /) receives IMAGE_STYLE.png.")
def stylize_command(image, style, vgg, decoder, alpha, style_size, size, device, out):
    """Stylise one image with AdaIN, as a KITTI-S build does.

    \b
    robodepth stylize frame.png --style styles/sketch.jpg --vgg vgg_normalised.pth \\
        --decoder decoder.pth --size 192x640 --out sketch.png
    """
    from ..styles.inputs import check_option, load_style

    out = common.png_output(out, f"{Path(image).stem}_{Path(style).stem}.png")
    # The same checks as a KITTI-S build's options, with the same messages.
    opts = {}
    for key, value in (("alpha", alpha), ("style_size", style_size), ("vgg", vgg), ("decoder", decoder)):
        try:
            opts[key] = check_option(key, value, Path())  # paths kept as typed
        except InvalidValueError as exc:
            raise exc.at(f"--{key.replace('_', '-')}") from None
    content = common.load_input(image, size)
    style_img = load_style(style, opts["style_size"])
    from ..styles.adain import Stylizer, choose_device, describe_device

    where = choose_device(device)
    stylizer = Stylizer.from_files(opts["vgg"], opts["decoder"], device=where)
    result = stylizer.stylize(content, [stylizer.style_features(style_img)], opts["alpha"])[0]
    common.write_png(out, result)
    common.wrote(f"{out} ({common.hxw(*result.shape[:2])}; AdaIN on {describe_device(where)})")
