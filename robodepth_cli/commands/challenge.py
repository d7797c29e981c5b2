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
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bar on stderr (only on a terminal).")
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
    meta = build_challenge(cfg, root, out, images=images, track=track, progress=progress,
                           command=common.typed_argv())
    click.echo(f"{out}: {meta['images']} images (track {meta['track']}) in {out / 'public'}; "
               f"ground truth and key in {out / 'private'}", err=True)
