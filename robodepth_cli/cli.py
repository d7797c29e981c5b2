"""The ``robodepth`` command line.

Commands stay thin: they parse and validate options, then call the library modules.
Every expected failure is raised as :class:`UserError` (or a ``ValueError``/``OSError``
subclass caught here) and printed as one line, with a non-zero exit and no traceback.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import click
import numpy as np

from . import __version__


class UserError(click.ClickException):
    """A problem with the user's input: printed as ``robodepth: error: <message>``, exit 2."""

    exit_code = 2

    def show(self, file=None):
        click.echo(f"robodepth: error: {self.format_message()}", err=True)


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="robodepth")
def main():
    """Build the RoboDepth robustness benchmark datasets: KITTI-C, NYUDepth2-C and KITTI-S.

    \b
    Quick look at the corruptions:
      robodepth list
      robodepth preview frame.png --out sheet.png
    Build a dataset:
      robodepth build kitti-c --root KITTI_RAW --out KITTI_C
      robodepth verify KITTI_C
    Score a model on it:
      robodepth score results.csv --benchmark kitti-c
    """


# --- corruption commands (list, corrupt, preview) ---

def _corruption_names(value: str) -> list[str]:
    from .config import ConfigError, choose_names
    from .corruptions import NAMES

    try:
        return list(choose_names("--corruption", value, NAMES, "corruption"))
    except ConfigError as exc:
        raise UserError(str(exc)) from None


def _levels(value: str, names: list[str]) -> list[int]:
    from .corruptions import REGISTRY

    most = max(REGISTRY[n].n_levels for n in names)
    if value == "all":
        return list(range(1, most + 1))
    try:
        levels = [int(v) for v in value.split(",")]
    except ValueError:
        raise UserError(f"--level {value!r}: expected an integer 1..{most}, a comma list, or 'all'") from None
    for lv in levels:
        if not 1 <= lv <= most:
            raise UserError(f"--level {lv} out of range: levels are 1..{most}")
    return levels


def _load_input(image: str, size: str | None):
    from .imageio import ImageError, load_clean, parse_size

    try:
        size_hw = parse_size(size) if size else None
        return load_clean(image, size_hw)
    except (ImageError, ValueError) as exc:
        raise UserError(str(exc)) from None


def _write_png(path: Path, img) -> None:
    from .imageio import write_png

    try:
        write_png(path, img)
    except OSError as exc:
        raise UserError(f"{path}: cannot write ({exc.strerror or exc})") from None


@main.command("list")
@click.option("--format", "fmt", type=click.Choice(["text", "markdown", "json"]), default="text",
              show_default=True, help="Plain table, the README's Markdown table, or JSON.")
def list_command(fmt):
    """List the 18 corruptions with their category and per-level parameters."""
    from .corruptions import REGISTRY
    from .docs import corruption_table

    if fmt == "json":
        import json

        click.echo(json.dumps([
            {"name": c.name, "category": c.category, "deterministic": c.deterministic,
             "levels": [c.params(lv) for lv in range(1, c.n_levels + 1)], "formula": c.doc}
            for c in REGISTRY.values()], indent=2))
    else:
        click.echo(corruption_table(markdown=(fmt == "markdown")))


@main.command("corrupt")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--corruption", "-c", "corruption", required=True, metavar="NAME|all",
              help="A corruption name (see `robodepth list`), a comma list, or 'all'.")
@click.option("--level", "-l", default="all", show_default=True, metavar="N|all",
              help="Level 1..5, a comma list, or 'all'.")
@click.option("--seed", "-s", default=0, show_default=True, type=int, help="Seed of the random corruptions.")
@click.option("--size", metavar="HxW", help="First resize the input as SPEC section 1 does (Lanczos), e.g. 192x640.")
@click.option("--out", "-o", required=True, type=click.Path(),
              help="Output PNG for one corruption at one level; otherwise a directory receiving NAME/LEVEL.png.")
def corrupt_command(image, corruption, level, seed, size, out):
    """Corrupt one image.

    \b
    robodepth corrupt frame.png -c zoom_blur -l 3 --out zoom3.png
    robodepth corrupt frame.png -c all -l all --size 192x640 --out corrupted/
    """
    from .corruptions import REGISTRY, corrupt
    from .corruptions.frost import FrostTextureError
    from .seeding import job_rng

    names = _corruption_names(corruption)
    levels = _levels(level, names)
    clean = _load_input(image, size)
    single = len(names) == 1 and len(levels) == 1 and corruption != "all" and level != "all"
    out = Path(out)
    if single and out.is_dir():
        raise UserError(f"{out}: is a directory; give a .png file name for one corruption at one level")
    if not single and out.exists() and not out.is_dir():
        raise UserError(f"{out}: is a file; several outputs need a directory")
    key = Path(image).name
    for name in names:
        for lv in levels:
            if lv > REGISTRY[name].n_levels:
                continue
            try:
                img = corrupt(clean, name, lv, job_rng(seed, "image", name, lv, key))
            except FrostTextureError as exc:
                raise UserError(str(exc)) from None
            _write_png(out if single else out / name / f"{lv}.png", img)
    if not single:
        click.echo(f"wrote {len(names) * len(levels)} images under {out}")


@main.command("preview")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--out", "-o", required=True, type=click.Path(dir_okay=False), help="The contact sheet (PNG).")
@click.option("--corruption", "-c", "corruption", default="all", show_default=True, metavar="NAME|all",
              help="Rows: 'all' or a comma list of corruptions.")
@click.option("--size", metavar="HxW", help="First resize the input (Lanczos), e.g. 192x640.")
@click.option("--seed", "-s", default=0, show_default=True, type=int)
@click.option("--thumb-width", default=320, show_default=True, type=click.IntRange(32, 2000),
              help="Width of each cell in pixels.")
def preview_command(image, out, corruption, size, seed, thumb_width):
    """A labelled contact sheet: the clean image, then one row per corruption and one column per level."""
    from .corruptions.frost import FrostTextureError
    from .preview import contact_sheet

    names = _corruption_names(corruption)
    clean = _load_input(image, size)
    try:
        sheet = contact_sheet(clean, names, range(1, 6), seed=seed, key=Path(image).name,
                              thumb_width=thumb_width)
    except FrostTextureError as exc:
        raise UserError(str(exc)) from None
    _write_png(Path(out), np.asarray(sheet))
    click.echo(f"wrote {out} ({sheet.width} x {sheet.height})")

# --- build commands (build, verify) ---

_LISTED = 20  # paths shown per kind of problem by verify


@main.command("build")
@click.argument("dataset", metavar="DATASET")
@click.option("--root", required=True, type=click.Path(path_type=Path),
              help="KITTI raw root (holds 2011_09_26/...) or the NYU Depth V2 test root.")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="Output directory; rerunning into it resumes.")
@click.option("--config", "config_file", type=click.Path(dir_okay=False, path_type=Path),
              help="Your own YAML config, applied over the DATASET preset.")
@click.option("--split", metavar="NAME|FILE", help="Standard split name (eigen_test, nyu_test) or a split file.")
@click.option("--corruptions", metavar="A,B|all", help="Comma-separated corruption names, or 'all'.")
@click.option("--levels", metavar="1,3|all", help="Comma-separated levels (e.g. 1,3), or 'all'.")
@click.option("--size", metavar="HxW", help="Output size HxW (e.g. 320x1024).")
@click.option("--jobs", "-j", metavar="N", help="Worker processes (preset: 2).")
@click.option("--seed", metavar="S", help="Global seed (preset: 0).")
@click.option("--limit", metavar="N", help="Only the first N images of the split, for a quick look.")
@click.option("--styles", metavar="DIR", help="kitti-s: the style images, <style>.jpg/.jpeg/.png.")
@click.option("--only-styles", metavar="A,B|all", help="kitti-s: comma-separated style names, or 'all'.")
@click.option("--vgg", metavar="FILE", help="kitti-s: AdaIN encoder checkpoint (vgg_normalised.pth).")
@click.option("--decoder", metavar="FILE", help="kitti-s: AdaIN decoder checkpoint (decoder.pth).")
@click.option("--alpha", metavar="A", help="kitti-s: style strength 0..1 (preset: 1).")
@click.option("--style-size", metavar="N", help="kitti-s: shorter side of the style images (preset: 512).")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bar on stderr (only on a terminal).")
def build_command(dataset, root, out, config_file, progress, **flags):
    """Build DATASET (kitti-c, kitti-c-hr, nyudepth2-c, kitti-s) from ROOT into OUT.

    Writes OUT/clean/<image> and OUT/<corruption>/<level>/<image> (kitti-s:
    OUT/<style>/<image>) as PNG, where <image> is
    the source's path (KITTI: kitti_data/<date>/<drive>/image_02/data/<frame>.png), plus
    OUT/manifest.csv (one row and sha256 per file) and OUT/build.json (config, versions).
    Settings come from configs/DATASET.yaml, then --config FILE, then the flags.

    Rerunning the same command redoes only missing or changed outputs. Exit status: 0 all
    done, 1 some images failed (the rest is built; see the summary), 2 refused before any
    work (bad config, root, split or OUT; another build running there) or stopped by a
    write error such as a full disk (finished images kept), 130 interrupted (resumable).

    \b
    Examples:
      robodepth build kitti-c --root KITTI_RAW --out KITTI_C
      robodepth build nyudepth2-c --root NYU_TEST --out NYU_C --jobs 2
      robodepth build kitti-c --root KITTI_RAW --out /tmp/look --limit 2 --levels 3
      robodepth build kitti-s --root KITTI_RAW --styles STYLES --vgg vgg_normalised.pth \\
          --decoder decoder.pth --out KITTI_S
    """
    from .builder import BuildError, build
    from .config import ConfigError, resolve
    from .manifest import ManifestError
    from .splits import SplitError

    interrupted = "robodepth: interrupted; rerun the same command to resume"
    # A scheduler's SIGTERM (end of a job's time) stops the build as cleanly as Ctrl-C.
    previous = signal.signal(signal.SIGTERM, _raise_keyboard_interrupt)
    try:
        cfg = resolve(dataset, config_file, flags)
        summary = build(cfg, root, out, progress=progress, command=sys.argv)
    except (ConfigError, SplitError, BuildError, ManifestError) as exc:
        raise UserError(str(exc)) from None
    except KeyboardInterrupt:  # before or after the images (the build itself handles its own)
        click.echo(interrupted, err=True)
        sys.exit(130)
    finally:
        signal.signal(signal.SIGTERM, previous)
    click.echo(f"{cfg.preset}: {summary.text()}", err=True)
    if summary.interrupted:
        click.echo(interrupted, err=True)
        sys.exit(130)
    if summary.fatal:
        raise UserError(f"{summary.fatal}; finished images are kept, rerun to resume")
    if summary.failed:
        sys.exit(1)


def _raise_keyboard_interrupt(signum, frame):
    raise KeyboardInterrupt


@main.command("verify")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bar on stderr (only on a terminal).")
def verify_command(out, progress):
    """Re-hash every file in OUT against OUT/manifest.csv.

    Reports files that are missing, changed or extra (not in the manifest), and images the
    build recorded as failed. Exit status 0 when everything matches, 1 otherwise.
    """
    from tqdm import tqdm

    from .manifest import ManifestError, verify

    try:
        with tqdm(unit="file", disable=None if progress else True, file=sys.stderr) as bar:
            report = verify(out, progress=bar.update)
    except ManifestError as exc:
        raise UserError(str(exc)) from None
    for kind in ("missing", "changed", "extra", "failed"):
        paths = getattr(report, kind)
        if paths:
            click.echo(f"{kind}: {len(paths)}")
            for p in paths[:_LISTED]:
                click.echo(f"  {p}")
            if len(paths) > _LISTED:
                click.echo(f"  ... and {len(paths) - _LISTED} more")
    if report.ok:
        click.echo(f"{out}: {report.checked} files match the manifest")
    else:
        click.echo(f"{out}: {report.checked} files checked; the tree does not match its manifest", err=True)
        sys.exit(1)

# --- style commands (stylize) ---

@main.command("stylize")
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
@click.option("--out", "-o", required=True, type=click.Path(dir_okay=False), help="Output PNG.")
def stylize_command(image, style, vgg, decoder, alpha, style_size, size, out):
    """Stylise one image with AdaIN, as a KITTI-S build does (SPEC section 3).

    \b
    robodepth stylize frame.png --style styles/sketch.jpg --vgg vgg_normalised.pth \\
        --decoder decoder.pth --size 192x640 --out sketch.png
    """
    from .imageio import ImageError
    from .styles import StyleError, check_alpha, check_style_size, check_weights, load_style

    out = Path(out)
    if out.suffix.lower() != ".png":
        raise UserError(f"{out}: the output is written as PNG; give a .png file name")
    for flag, check, value in (("--alpha", check_alpha, alpha), ("--style-size", check_style_size, style_size)):
        try:
            check(value)
        except ValueError as exc:
            raise UserError(f"{flag}: {exc}") from None
    content = _load_input(image, size)
    try:
        check_weights(vgg, "--vgg")
        check_weights(decoder, "--decoder")
        style_img = load_style(style, style_size)
    except (StyleError, ImageError) as exc:
        raise UserError(str(exc)) from None
    from .adain import CheckpointError, Stylizer

    try:
        stylizer = Stylizer.from_files(vgg, decoder)
    except CheckpointError as exc:
        raise UserError(str(exc)) from None
    result = stylizer.stylize(content, [stylizer.style_features(style_img)], alpha)[0]
    _write_png(out, result)

# --- score command ---

@main.command("score")
@click.argument("results", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--benchmark", "-b", required=True, type=click.Choice(["kitti-c", "nyudepth2-c"]),
              help="Which benchmark the results are on (sets corruptions, levels, baseline).")
@click.option("--baseline", "baseline_file", type=click.Path(dir_okay=False, path_type=Path),
              help="Baseline results in the same CSV form (complete), instead of the published one.")
@click.option("--allow-partial", is_flag=True,
              help="Score the variants present; missing ones are a warning, not an error.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write a PNG bar chart of CE per corruption.")
def score_cmd(results, benchmark, baseline_file, allow_partial, as_json, plot_path):
    """Robustness scores of a model from its per-corruption results (SPEC section 5).

    RESULTS is a CSV with a header row naming the columns corruption, level, abs_rel, a1
    (or dee instead of abs_rel and a1), one row per corruption and level, plus a row
    `clean,0,...`. Prints DEE, CE and RR per corruption, category means, mCE, mRR, mDEE.

    \b
    Example:
      robodepth score monovit.csv --benchmark kitti-c --plot ce.png
    """
    import json

    from . import scores as S

    bench = S.get_benchmark(benchmark)
    try:
        res = S.read_results(results, bench)
        base = None
        if baseline_file is not None:
            base = S.baseline_from_results(S.read_results(baseline_file, bench), bench)
    except S.ScoreError as exc:
        raise UserError(str(exc)) from None
    missing = S.missing_message(res, bench)
    if missing and not allow_partial:
        raise UserError(f"{missing} (--allow-partial scores what is there)")
    if missing:
        click.echo(f"robodepth: warning: {missing}; scoring what is present", err=True)
    result = S.score(res, bench, base, allow_partial=True)
    if plot_path is not None:
        from .plot import ce_chart

        _write_png(plot_path, np.asarray(ce_chart(result)))
    if as_json:
        click.echo(json.dumps(result.to_json(), indent=2))
    else:
        click.echo(S.format_table(result), nl=False)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
