"""Option parsing and file helpers shared by several commands."""

from __future__ import annotations

import os
from pathlib import Path

import click
import numpy as np

from ..errors import InvalidValueError, RobodepthError, cannot_write, counted


ARGV = "robodepth.argv"  # ctx.meta: the arguments as typed (set by the group)
KEPT = "robodepth.kept"  # ctx.meta: what an interrupt leaves behind (see on_interrupt)
OUTPUTS = "robodepth.outputs"  # ctx.meta: {path: its state before the work} (see will_write)
NOTHING_KEPT = "nothing was written"


def typed_argv() -> list[str]:
    """The running command as the user typed it: ``["robodepth", "build", ...]``."""
    import sys

    return ["robodepth", *click.get_current_context().meta.get(ARGV, sys.argv[1:])]


def on_interrupt(kept: str) -> None:
    """What this command keeps if Ctrl-C or SIGTERM stops it now (the group prints
    ``robodepth: interrupted; <kept>``); by default, nothing was written."""
    click.get_current_context().meta[KEPT] = kept


def will_write(path) -> None:
    """Note that this command writes ``path`` (whole, atomically), so that an interrupt
    says whether it was written: the signal can come after the file is in place (see
    :func:`interrupt_note`)."""
    click.get_current_context().meta.setdefault(OUTPUTS, {})[Path(path)] = _state(Path(path))


def _state(path: Path):
    """What tells a file (or folder) written now from the one there before: an atomic write
    replaces it (a new inode) or creates it."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns, st.st_size


def interrupt_note(meta: dict) -> str:
    """What an interrupt kept, as ``robodepth: interrupted; <this>`` says it: the command's
    own words (:func:`on_interrupt`), else which of its outputs (:func:`will_write`) are
    already written, else that nothing was."""
    if KEPT in meta:
        return meta[KEPT]
    done = [str(p) for p, before in meta.get(OUTPUTS, {}).items()
            if _state(p) is not None and _state(p) != before]
    if not done:
        return NOTHING_KEPT
    if len(done) == 1:
        return f"{done[0]} was written (complete) before the interrupt"
    return f"{', '.join(done[:-1])} and {done[-1]} were written (complete) before the interrupt"


class Jobs(click.ParamType):
    """``--jobs N|auto``: worker processes, by the rule of every command
    (:func:`robodepth_cli.workers.parse_jobs`); 'auto' or -1: one per CPU."""

    name = "N|auto"

    def convert(self, value, param, ctx):
        from ..workers import parse_jobs

        try:
            return parse_jobs(value)
        except RobodepthError as exc:
            self.fail(str(exc), param, ctx)


def corruption_names(value: str, flag: str = "--corruption") -> list[str]:
    """The corruptions ``value`` selects ('all': the benchmarks' 18; a name or a comma list
    of any, the depth-aware ones included), in order."""
    from ..benchmark_facts import ALL_CORRUPTIONS, CORRUPTIONS
    from ..building.choices import ALL, choose_names

    if value == ALL:
        return list(CORRUPTIONS)
    return list(choose_names(flag, value, ALL_CORRUPTIONS, "corruption"))


def levels(value: str, flag: str = "--level") -> list:
    """The levels ``value`` selects ('all': 1..5, a level or a comma list; decimals such as
    2.5 allowed), sorted, each checked by the one level rule of every command."""
    from ..benchmark_facts import N_LEVELS
    from ..corruptions.severity import parse_levels

    return list(parse_levels(value, top=N_LEVELS, what=flag))


def items(corruption: str, level_list: list, flag: str = "--corruption") -> list[str]:
    """The corruptions and chains ``-c`` names, in order: 'all' and comma lists expanded,
    chains checked (against ``level_list`` for a step written without a level)."""
    from ..corruptions.chains import expand_chain, looks_like_chain

    parts = [p.strip() for p in corruption.split(",") if p.strip()]
    if not parts:
        corruption_names(corruption, flag)  # refuses, with the message every list gets
    out: list[str] = []
    for part in parts:
        if looks_like_chain(part):
            expand_chain(part, level_list, where=flag)
            out.append(part)
        else:
            out += corruption_names(part, flag)
    return list(dict.fromkeys(out))


def variants(corruption: str, level_list: list, flag: str = "--corruption") -> list[tuple[str, str, object]]:
    """What ``-c`` and ``-l`` ask for, in order: ``(file name, variant, level)`` for every
    corruption at every level (``NAME/LEVEL.png``) and every chain (``CHAIN.png``, its
    directory name; a step written without a level takes each level of ``level_list``)."""
    from ..corruptions.chains import expand_chain, looks_like_chain
    from ..corruptions.severity import level_text

    out: list[tuple[str, str, object]] = []
    for item in items(corruption, level_list, flag):
        if looks_like_chain(item):
            out += [(f"{c.dirname}.png", c.text, None) for c in expand_chain(item, level_list)]
        else:
            out += [(f"{item}/{level_text(lv)}.png", item, lv) for lv in level_list]
    return list(dict.fromkeys(out))


def load_input(image: str, size: str | None) -> np.ndarray:
    """The clean image of one input file, resized (Lanczos) to ``size`` ("HxW") if given.
    Its EXIF orientation is applied first: a photo is corrupted the way viewers show it."""
    from ..imageio import load_clean, parse_size

    try:
        hw = parse_size(size) if size else None
    except InvalidValueError as exc:
        raise RobodepthError(f"--size: {exc}") from None
    return load_clean(image, hw, orient=True)


def hxw(height: int, width: int) -> str:
    """``"48x64, HxW"``: a size in the one notation of ``--size``, the manifest and errors."""
    return f"{height}x{width}, HxW"


def seed(value: int, flag: str = "--seed") -> int:
    """``value`` if it is a valid seed (the same rule as a build's ``--seed``)."""
    from ..seeding import check_seed

    return check_seed(value, flag)


CONTENT_DATASET = "image"  # the dataset name corrupt and preview draw under without --as


def as_option(command):
    """``--as DATASET:KEY`` of ``corrupt`` and ``preview``, declared once."""
    return click.option("--as", "draw_as", metavar="DATASET:KEY",
                        help="Draw as a build of DATASET draws for its source KEY (manifest.csv's "
                             "source column, or the image's path under the build's clean/), to "
                             "remake a build's image from its clean one; default: drawn from the "
                             "image's pixels.")(command)


def draw_as(value: str | None, clean: np.ndarray) -> tuple[str, str]:
    """``(dataset, key)`` a single-image command draws under: ``--as DATASET:KEY`` as a
    build of DATASET draws for its source KEY (:func:`~robodepth_cli.sourcekeys.seed_key`: the
    manifest's ``source`` column or the image's path under ``clean/``), else (:data:`CONTENT_DATASET`, the image's
    :func:`~robodepth_cli.seeding.content_key`)."""
    from ..sourcekeys import seed_key
    from ..seeding import content_key
    from ..sources.datasets import DATASETS

    if value is None:
        return CONTENT_DATASET, content_key(clean)
    dataset, _, key = value.partition(":")
    if dataset not in DATASETS or not key:
        raise RobodepthError(f"--as {value}: expected DATASET:KEY, DATASET one of "
                             f"{', '.join(DATASETS)} and KEY a source as manifest.csv records it")
    return dataset, seed_key(dataset, key)


def means_directory(out: str) -> bool:
    """Whether ``--out`` as typed names a directory: it ends with a path separator, or it
    is an existing directory."""
    return out.endswith(("/", os.sep)) or Path(out).is_dir()


def png_output(out: str, default_name: str, flag: str = "--out") -> Path:
    """The PNG file that ``out`` (as typed) names: ``out`` itself, or ``out/default_name``
    when it means a directory (:func:`means_directory`). Any other name must end in
    ``.png``: writing PNG bytes under another extension would mislabel the file."""
    if means_directory(out):
        path = Path(out) / default_name
    else:
        path = Path(out)
        if path.suffix.lower() != ".png":
            raise RobodepthError(f"{flag} {out}: the output is written as PNG; give a .png file "
                                 f"name, or a directory (end it with /)")
    will_write(path)
    return path


def write_png(path: Path, img: np.ndarray) -> None:
    """Write ``img`` as a PNG at ``path`` (atomically); a write error is a refusal."""
    from ..imageio import write_png as write

    try:
        write(path, img)
    except OSError as exc:
        raise RobodepthError(cannot_write(path, exc)) from None


def wrote(what) -> None:
    """Say where output went: ``wrote WHAT``, on stderr as every command says it (stdout
    carries only results: tables, JSON)."""
    click.echo(f"wrote {what}", err=True)


FIGURE_SUFFIXES = (".png", ".svg", ".pdf")


def figure_output(out: str, default_name: str, flag: str) -> Path:
    """The figure file that ``out`` (as typed) names: ``out`` itself (.png, .svg or .pdf,
    the format its suffix says) or ``out/default_name`` when it means a directory; checked
    writable now, so no work is done for an output that would fail."""
    from ..files import check_writable

    path = Path(out) / default_name if means_directory(out) else Path(out)
    if path.suffix.lower() not in FIGURE_SUFFIXES:
        raise RobodepthError(f"{flag} {out}: give a .png, .svg or .pdf file name, or a "
                             "directory (end it with /)")
    if path.is_dir():
        raise RobodepthError(cannot_write(path, "it is a directory", flag))
    check_writable(path, flag)
    will_write(path)
    return path


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically; a write error is a refusal."""
    from ..files import write_atomic

    try:
        write_atomic(path, data)
    except OSError as exc:
        raise RobodepthError(cannot_write(path, exc)) from None


# Options several commands share, worded once.
progress_option = click.option("--progress/--no-progress", default=True, show_default=True,
                               help="Progress bar on stderr (only on a terminal).")
model_device_option = click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto",
                                   show_default=True, help="Where monodepth2 and hf models run (auto: "
                                   "cuda if torch sees a GPU).")
model_kind_option = click.option("--kind", type=click.Choice(["disp", "sigmoid", "depth"]),
                                 help="What the maps hold: required for python:, overrides an hf "
                                 "model's own.")


def selection_options(command):
    """Which images, variants and seed a build configuration takes (``building.config``'s
    flags): the options ``build`` and ``run`` share, declared once."""
    options = [
        click.option("--config", "config_file", type=click.Path(dir_okay=False, path_type=Path),
                     help="Your own YAML config, applied over the DATASET preset."),
        click.option("--corruptions", metavar="A,B|all|none",
                     help="Comma-separated corruption names, 'all', or 'none' (only --compose chains)."),
        click.option("--levels", metavar="1,3|all",
                     help="Comma-separated levels (e.g. 1,3 or 1,2.5,4: decimals allowed), or 'all'."),
        click.option("--seed", metavar="S", help="Global seed (preset: 0)."),
        click.option("--limit", metavar="N", help="Only the first N images of the split, for a quick look."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def severity_size_option(default_text: str):
    """``--severity-size HxW|none``: the image size at which the levels' spatial parameters
    are defined (:mod:`robodepth_cli.corruptions.scaling`); ``default_text`` says the
    command's default."""
    return click.option("--severity-size", metavar="HxW|none",
                        help="The image size at which the levels' blur radii, streaks, flakes and "
                             "warps are defined; another size scales them by the square root of the "
                             f"area ratio; none: pixels as tabulated at any size ({default_text}).")


def severity_size(value: str | None, flag: str = "--severity-size") -> tuple[int, int] | None:
    """``--severity-size`` checked: ``(H, W)``, or None for ``none`` or when not given."""
    from ..corruptions.scaling import parse_severity_size

    try:
        return parse_severity_size(value)
    except InvalidValueError as exc:
        raise exc.at(flag) from None


def evaluation_options(command):
    """How predictions are judged against the ground truth: the options ``evaluate`` and
    ``run`` share (declared once, so their choices and defaults cannot drift apart)."""
    options = [
        click.option("--stereo", is_flag=True,
                     help="kitti: a stereo-trained model: depth x 5.4, no median scaling."),
        click.option("--align", type=click.Choice(["none", "median", "scale", "scale-shift"]),
                     help="Per image, on the valid pixels: none; median (median(gt) / "
                          "median(pred), the kitti mono default); scale (least-squares s); "
                          "scale-shift (least-squares s and t). Default: PRED/predictions.json's, "
                          "else the protocol's."),
        click.option("--align-space", type=click.Choice(["depth", "disparity"]),
                     help="Align the depth, or the disparity against 1/gt (relative models' "
                          "default from predictions.json). Default: depth."),
        click.option("--crop", type=click.Choice(["garg", "eigen", "cityscapes", "none"]),
                     help="The evaluation crop (default: garg for kitti, eigen for nyu, the "
                          "dataset's own for a zero-shot set, none for custom)."),
        click.option("--min-depth", type=float, metavar="M",
                     help="Valid ground truth and clamp: above M metres (default 0.001)."),
        click.option("--max-depth", type=float, metavar="M",
                     help="Valid ground truth and clamp: below M metres (default 80 kitti, 10 nyu)."),
    ]
    for option in reversed(options):  # as if stacked in this order above the command
        command = option(command)
    return command


def show_results(result, table, out: Path, bench, as_json: bool, replacing: bool) -> None:
    """Print an evaluation written to ``out`` as the results ``table``: its table (or JSON), the warnings
    it calls for, and with ``bench`` the robustness scores, as ``robodepth score`` prints them."""
    import json

    from ..evaluation import results, scores
    from ..evaluation.protocols import STEREO_SCALE

    if result.setup.stereo and result.setup.kind == "depth":
        click.echo(f"robodepth: warning: --stereo multiplied every depth by {STEREO_SCALE}: right "
                   "for a stereo model's depths in monodepth2's units (1 / its disparity), wrong "
                   f"for depths in metres ({STEREO_SCALE} times too far; drop --stereo)", err=True)
    for note in result.warnings:
        click.echo(f"robodepth: warning: {note}", err=True)
    if result.missing:
        click.echo(f"robodepth: warning: no predictions for {counted(len(result.missing), 'variant')}; "
                   "evaluated the rest", err=True)
    if result.left_out:
        n, reasons = len(result.left_out), list(result.left_out.items())[:2]
        click.echo(f"robodepth: left out {n} of {result.images} images without usable ground truth ("
                   + "; ".join(f"{k}: {why}" for k, why in reasons) + ("; ..." if n > 2 else "")
                   + ")", err=True)
    implausible = _implausible_clean(result) if bench is not None else ""
    scored = None
    if bench is not None and not implausible:
        res = results.parse_results(table, bench)
        missing = results.missing_message(res, bench)
        if missing:
            click.echo(f"robodepth: warning: {missing}; scoring what is present", err=True)
        scored = scores.score(res, bench, allow_partial=True)
    if as_json:
        doc = {**result.to_json(), "csv": str(out)}
        if scored is not None:
            doc["scores"] = scored.to_json()
        click.echo(json.dumps(doc, indent=2, allow_nan=False))
    else:
        click.echo(result.summary(), nl=False)
    wrote(f"{out} (replaced)" if replacing else out)
    if implausible:  # the work is done and written: a warning, not a refusal
        click.echo(f"robodepth: warning: {implausible}", err=True)
    if scored is not None and not as_json:
        click.echo()
        click.echo(scores.format_table(scored), nl=False)


def _implausible_clean(result) -> str:
    """Why the clean DEE cannot be scored (at least 1: every rate divides by 1 - DEE), as
    a wrong --kind, --stereo or --png-scale gives it; "" when it is plausible."""
    from ..benchmark_facts import CLEAN
    from ..evaluation.results import implausible_dee

    for r in result.results:
        if r.variant.name == CLEAN:
            text = implausible_dee(r.metrics, result.setup)
            return f"{text}; the metrics above are written, not scored" if text else ""
    return ""
