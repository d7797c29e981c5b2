"""``robodepth challenge``: build a hidden test set, score, bundle for Codabench, check."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import RobodepthError
from . import common

DEFAULT_MAX_MB = 512  # see docs/challenge.md: uploads of a few hundred MB troubled CodaLab


@click.group("challenge")
def challenge_command():
    """Run the benchmark as a challenge: a hidden mixed test set, its scoring, a Codabench bundle.

    \b
    Organisers:
      robodepth challenge build kitti-c --root KITTI_RAW --seed 12345 --out CHALLENGE
      robodepth challenge bundle CHALLENGE --out competition.zip
      robodepth challenge score submission.zip --reference CHALLENGE/private
    Participants:
      robodepth predict CHALLENGE/public --model MODEL --out submission.zip
      robodepth challenge check submission.zip --public CHALLENGE/public
    """


@challenge_command.command("build")
@click.argument("dataset", metavar="DATASET")
@click.option("--root", required=True, type=click.Path(path_type=Path),
              help="The source frames, as robodepth build takes them (KITTI raw root, NYU test root, ...).")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="Output directory: OUT/public (for participants) and OUT/private (ground truth, key).")
@click.option("--seed", required=True, metavar="S",
              help="The draw's and the corruptions' seed; keep it private until the challenge ends.")
@click.option("--images", "-n", metavar="N", type=int,
              help="Number of test images (default: 500 on track kitti, 200 on track nyu).")
@click.option("--corruptions", metavar="A,B|all", help="The corruptions drawn from (default: the dataset's).")
@click.option("--levels", metavar="1,3|all", help="The levels drawn from (default: the dataset's).")
@click.option("--track", type=click.Choice(["kitti", "nyu"]),
              help="How submissions are scored: kitti (disparities, median scaling, the official "
                   "evaluator) or nyu (metric depth, NYU protocol); default: the dataset's protocol.")
@click.option("--config", "config_file", type=click.Path(dir_okay=False, path_type=Path),
              help="A YAML config over the DATASET preset, as robodepth build takes it.")
@click.option("--split", metavar="NAME|FILE", help="The split whose frames are drawn from (default: the preset's).")
@click.option("--size", metavar="HxW", help="Image size (default: the preset's).")
@click.option("--jobs", "-j", metavar="N|auto", help="Worker processes of the source frames' build.")
@common.progress_option
def challenge_build_command(dataset, root, out, seed, images, corruptions, levels, track,
                            config_file, split, size, jobs, progress):
    """Draw a challenge set of N images from DATASET's frames into OUT.

    Each image is one seeded draw of (source frame, corruption, level): corruptions balanced
    to within one image, levels within one image per corruption, each frame used at most
    once while N allows. OUT/public holds the images under anonymous ids in a shuffled
    order, list.txt (the order predictions follow), challenge.json and a README saying what
    to submit; OUT/private the ground truth (gt.npz, metres), the key (key.csv: id, source,
    corruption, level, seed, sha256) and the build of the source frames. The same command
    and seed give the same bytes.
    """
    from ..building.config import resolve
    from ..challenge.build import build_challenge

    if images is not None and images < 1:
        raise RobodepthError(f"--images {images}: need at least 1")
    cfg = resolve(dataset, config_file, {"corruptions": corruptions, "levels": levels,
                                         "seed": seed, "split": split, "size": size, "jobs": jobs})
    common.on_interrupt(f"no challenge was written; the source frames' build in {out / 'private' / 'build'} "
                        "is kept and a rerun resumes it")
    meta = build_challenge(cfg, root, out, images=images, track=track, progress=progress,
                           command=common.typed_argv())
    click.echo(f"{out}: {meta['images']} images (track {meta['track']}) in {out / 'public'}; "
               f"ground truth and key in {out / 'private'}", err=True)


def _max_bytes(max_size: int) -> int:
    if max_size < 1:
        raise RobodepthError(f"--max-size {max_size}: must be at least 1 (MB)")
    return max_size * 10 ** 6


_MAX_SIZE = click.option("--max-size", metavar="MB", type=int, default=DEFAULT_MAX_MB, show_default=True,
                         help="Refuse submissions larger than this, as uploaded or as they declare "
                              "uncompressed (float16 halves a submission).")


@challenge_command.command("score")
@click.argument("submission", type=click.Path(path_type=Path))
@click.option("--reference", required=True, type=click.Path(path_type=Path),
              help="The private folder of challenge build (or a phase's reference data).")
@click.option("--out", "-o", type=click.Path(path_type=Path),
              help="Write scores.json and detailed_results.html into this folder.")
@_MAX_SIZE
@click.option("--json", "as_json", is_flag=True, help="Print the scores as JSON.")
def challenge_score_command(submission, reference, out, max_size, as_json):
    """Score SUBMISSION (a zip, npz, npy or folder) against the hidden ground truth.

    Prints the track's metrics over all images (the official numbers), then DEE per
    corruption; --out writes scores.json (flat keys) and detailed_results.html. A refused
    submission is one line and exit status 2.
    """
    import json

    from ..challenge.server import score_folder

    scores = score_folder(str(submission), str(reference), str(out) if out else None,
                          _max_bytes(max_size))
    flat = scores.flat()
    if as_json:
        click.echo(json.dumps(flat, indent=1, sort_keys=True))
        return
    click.echo(f"{flat['images']} images, track {scores.track}")
    click.echo("  ".join(f"{m} {flat[m]:.4f}" for m in scores.metrics))
    click.echo(f"DEE {flat['dee']:.4f}   mean DEE over corruptions {flat['mdee']:.4f}")
    for c, g in scores.groups().items():
        click.echo(f"  {c:<18} {g['images']:>4} images  abs_rel {g['abs_rel']:.4f}  "
                   f"a1 {g['a1']:.4f}  DEE {g['dee']:.4f}")


@challenge_command.command("check")
@click.argument("submission", type=click.Path(path_type=Path))
@click.option("--public", required=True, type=click.Path(path_type=Path),
              help="The challenge's public folder (its list.txt).")
@_MAX_SIZE
def challenge_check_command(submission, public, max_size):
    """Check SUBMISSION offline as the server would: every refusal but the scores.

    Reads every map (form, count, shape, dtype, values) against PUBLIC's list. Exit status
    0 when the server would score it, 2 (one line saying why) when it would refuse it.
    """
    from ..challenge.server import check_folder

    form, n = check_folder(str(submission), str(public), _max_bytes(max_size))
    click.echo(f"{submission}: valid ({n} maps, {'keyed by image id' if form == 'keyed' else 'in list order'})")


@challenge_command.command("bundle")
@click.argument("challenge", type=click.Path(path_type=Path))
@click.option("--out", "-o", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The competition bundle to write (a .zip to upload to Codabench).")
@click.option("--title", default="RoboDepth Challenge", show_default=True, help="The competition's title.")
@click.option("--dev-images", type=int, metavar="K",
              help="Images of the development phase: each corruption's first in the list, then the "
                   "list's next ones, K in all (default: a tenth, at most 50, at least one per corruption).")
@click.option("--dev-start", default="2026-01-01", show_default=True, help="Development phase start (YYYY-MM-DD).")
@click.option("--final-start", default="2026-03-01", show_default=True,
              help="Final phase start, the development phase's end (YYYY-MM-DD).")
@click.option("--final-end", default="2026-03-15", show_default=True, help="Final phase end (YYYY-MM-DD).")
@click.option("--per-day", type=int, default=5, show_default=True, help="Submissions per day, each phase.")
@click.option("--total", type=int, default=100, show_default=True, help="Submissions in total, development phase.")
@click.option("--final-total", type=int, default=3, show_default=True, help="Submissions in total, final phase.")
@click.option("--docker-image", default="codalab/codalab-legacy:py39", show_default=True,
              help="The image the scoring program runs in (it needs Python 3 and numpy only).")
@_MAX_SIZE
def challenge_bundle_command(challenge, out, title, dev_images, dev_start, final_start, final_end,
                             per_day, total, final_total, docker_image, max_size):
    """Write a Codabench competition bundle for the challenge built in CHALLENGE.

    competition.yaml (version 2), pages, the scoring program (Python 3 and numpy only),
    the development and final reference data, a sample submission and a starting kit.
    Upload OUT on Codabench (Benchmarks > Management > Upload).
    """
    import datetime

    from ..challenge.bundle import make_bundle

    dates = {}
    for flag, value in (("--dev-start", dev_start), ("--final-start", final_start),
                        ("--final-end", final_end)):
        try:
            dates[flag] = datetime.date.fromisoformat(value)
        except ValueError:
            raise RobodepthError(f"{flag} {value!r}: expected a date YYYY-MM-DD") from None
    if not dates["--dev-start"] < dates["--final-start"] < dates["--final-end"]:
        raise RobodepthError("--dev-start, --final-start, --final-end: must be in that order")
    for flag, v in (("--per-day", per_day), ("--total", total), ("--final-total", final_total)):
        if v < 1:
            raise RobodepthError(f"{flag} {v}: must be at least 1")
    info = make_bundle(challenge, out, title=title, dev_images=dev_images, dates={
        "dev_start": dates["--dev-start"], "dev_end": dates["--final-start"],
        "final_start": dates["--final-start"], "final_end": dates["--final-end"]},
        per_day=per_day, total=total, final_total=final_total, max_bytes=_max_bytes(max_size),
        docker_image=docker_image)
    click.echo(f"{out}: Codabench bundle, development phase {info['dev']} images, final "
               f"{info['final']}", err=True)
