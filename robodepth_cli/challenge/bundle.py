"""``robodepth challenge bundle``: a Codabench competition bundle (``competition.yaml``
version 2) for a challenge built by ``challenge build``; docs/challenge.md lists what it
holds. The scoring program is :data:`PROGRAM_FILES`, copied as they are."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from ..errors import RobodepthError
from . import layout
from .scoring import RANK
from .npzfile import write_npz

DOCKER_IMAGE = "codalab/codalab-legacy:py39"  # Codabench's documented default (Python 3.9, numpy)
PROGRAM_FILES = ("errors.py", "benchmark_facts.py", "evaluation/protocols.py", "evaluation/resample.py",
                 "challenge/__init__.py", "challenge/layout.py", "challenge/submission.py",
                 "challenge/resize.py", "challenge/scoring.py", "challenge/page.py",
                 "challenge/server.py")
_EPOCH = (1980, 1, 1, 0, 0, 0)
SCORE_PY = '''"""The challenge's scoring program (robodepth challenge bundle): python3 score.py INPUT OUTPUT [MAX_BYTES]."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from robodepth_cli.challenge import server  # noqa: E402

if len(sys.argv) > 3:
    os.environ["ROBODEPTH_MAX_BYTES"] = sys.argv[3]
sys.exit(server.main(sys.argv[1:3]))
'''


def leaderboard_columns(track: str, corruptions) -> list[dict]:
    """The leaderboard's columns: the ranking metric first (the leaderboard's
    ``primary_index``), then the other metrics, DEE, and DEE per corruption (keys of
    ``scores.json``; Codabench stores a column's key and title in 36 characters)."""
    from ..evaluation.protocols import KITTI_METRICS, NYU_METRICS

    rank, sorting = RANK[track]
    metrics = KITTI_METRICS if track == "kitti" else NYU_METRICS
    cols = [(rank, sorting)] + [(m, "desc" if m.startswith("a") and m[1:].isdigit() else "asc")
                                for m in metrics if m != rank]
    cols += [("dee", "asc"), ("mdee", "asc")] + [(f"dee_{c}", "asc") for c in corruptions]
    return [{"title": k.replace("_", " "), "key": k, "index": i, "sorting": s, "precision": 4}
            for i, (k, s) in enumerate(cols)]


def dev_rows(rows: list[dict], k: int) -> list[dict]:
    """The development set: for each corruption its first image in list order, then the
    next images of the list, ``k`` in all (at least one per corruption), in list order; so
    every per-corruption column of the leaderboard has a value in both phases."""
    chosen: dict[str, dict] = {}
    for r in rows:
        chosen.setdefault(r["corruption"], r)
    picked = {r["id"] for r in chosen.values()}
    for r in rows:
        if len(picked) >= k:
            break
        picked.add(r["id"])
    return [r for r in rows if r["id"] in picked]


def present(rows: list[dict]) -> list[str]:
    """The corruptions of ``rows``, in benchmark order."""
    from ..benchmark_facts import ALL_CORRUPTIONS

    have = {r["corruption"] for r in rows}
    return [c for c in ALL_CORRUPTIONS if c in have] + sorted(have - set(ALL_CORRUPTIONS))


def competition_yaml(meta: dict, title: str, dev_images: int, dates: dict, per_day: int,
                     total: int, final_total: int, docker_image: str) -> str:
    """The text of ``competition.yaml``."""
    import yaml

    track = meta["track"]
    doc = {
        "version": 2, "title": title,
        "description": f"Monocular depth under corruptions, track {track}: {meta['images']} "
                       "hidden test images.",
        "image": "logo.png", "registration_auto_approve": True, "docker_image": docker_image,
        "enable_detailed_results": True, "terms": "pages/terms.md",
        "pages": [{"title": t, "file": f"pages/{f}.md"} for t, f in
                  (("Overview", "overview"), ("Data", "data"), ("Evaluation", "evaluation"),
                   ("Terms", "terms"))],
        "tasks": [{"index": 0, "name": "Development set",
                   "description": f"{dev_images} of the images, every corruption among them.",
                   "scoring_program": "scoring_program/", "reference_data": "reference_dev/"},
                  {"index": 1, "name": "Final set", "description": f"All {meta['images']} images.",
                   "scoring_program": "scoring_program/", "reference_data": "reference_final/"}],
        "solutions": [{"index": 0, "tasks": [0, 1], "path": "solutions/sample/"}],
        "phases": [{"index": 0, "name": "Development", "description":
                    f"Scores on {dev_images} of the images, shown at once.",
                    "start": dates["dev_start"], "end": dates["dev_end"],
                    "max_submissions_per_day": per_day, "max_submissions": total, "tasks": [0],
                    "starting_kit": "starting_kit/"},
                   {"index": 1, "name": "Final", "description": "Scores on every image.",
                    "start": dates["final_start"], "end": dates["final_end"],
                    "max_submissions_per_day": per_day, "max_submissions": final_total,
                    "tasks": [1]}],
        "leaderboards": [{"index": 0, "title": "Results", "key": "main", "primary_index": 0,
                          "submission_rule": "Force_Last",
                          "columns": leaderboard_columns(track, meta["corruptions"])}],
    }
    return yaml.safe_dump(doc, sort_keys=False, allow_unicode=True)


def _add(zf: zipfile.ZipFile, name: str, data: bytes) -> None:
    info = zipfile.ZipInfo(name, date_time=_EPOCH)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    zf.writestr(info, data)


def _npz_bytes(members) -> bytes:
    buf = io.BytesIO()
    write_npz(buf, members)
    return buf.getvalue()


def reference_files(private: Path, ids: list[str], rows: list[dict], meta: dict) -> dict[str, bytes]:
    """A phase's reference data: the whole list, the key rows and maps of the images scored."""
    with np.load(private / layout.GT, allow_pickle=False) as gt:
        maps = _npz_bytes(m for r in rows for m in layout.gt_members(r["id"], layout.read_gt(gt, r["id"])))
    return {layout.LIST: "".join(i + "\n" for i in ids).encode(),
            layout.KEY: layout.key_text(rows).encode(), layout.GT: maps,
            layout.META: layout.meta_text({**meta, "scored": len(rows)}).encode()}


def sample_submission(ids: list[str]) -> bytes:
    """A keyed npz of 8 x 8 maps of ones: valid, and scored as a constant prediction."""
    return _npz_bytes((i, np.ones((8, 8), np.float16)) for i in ids)


def _logo() -> bytes:
    from ..imageio import encode_png

    y, x = np.mgrid[0:96, 0:96]
    img = np.stack([(x * 2.6).astype(np.uint8), (y * 2.6).astype(np.uint8),
                    np.full((96, 96), 160, np.uint8)], -1)
    return encode_png(img, method="compact")


def make_bundle(challenge: Path, out: Path, *, title: str, dev_images: int | None, dates: dict,
                per_day: int, total: int, final_total: int, max_bytes: int,
                docker_image: str = DOCKER_IMAGE) -> dict:
    """Write the bundle of the challenge in ``challenge`` (its public and private folders)
    to ``out``; returns a summary (images per phase)."""
    from ..files import atomic_output
    from . import pages

    public, private = Path(challenge) / "public", Path(challenge) / "private"
    for folder in (public, private):
        if not folder.is_dir():
            raise RobodepthError(f"{folder}: missing; CHALLENGE is the --out of robodepth challenge build")
    meta = layout.read_meta(str(private))
    ids = layout.read_list(str(public))
    rows = layout.read_key(str(private))
    n, corruptions = len(ids), present(rows)
    meta = {**meta, "corruptions": corruptions}
    dev = dev_images if dev_images is not None else max(len(corruptions), min(50, n // 10))
    if not len(corruptions) <= dev <= n:
        raise RobodepthError(f"--dev-images {dev}: must be {len(corruptions)}..{n} (at least one "
                             "image per corruption, so that every leaderboard column has a value)")
    package = Path(__file__).resolve().parent.parent
    with atomic_output(out) as fh, zipfile.ZipFile(fh, "w") as zf:
        _add(zf, "competition.yaml", competition_yaml(meta, title, dev, dates, per_day, total,
                                                      final_total, docker_image).encode())
        _add(zf, "logo.png", _logo())
        for name, text in pages.pages(meta, title, dev, max_bytes).items():
            _add(zf, f"pages/{name}.md", text.encode())
        _add(zf, "scoring_program/metadata.yaml",
             f"command: python3 /app/program/score.py /app/input /app/output {max_bytes}\n".encode())
        _add(zf, "scoring_program/score.py", SCORE_PY.encode())
        for pkg in ("", "evaluation/"):
            _add(zf, f"scoring_program/robodepth_cli/{pkg}__init__.py", b"")
        for rel in PROGRAM_FILES:
            _add(zf, f"scoring_program/robodepth_cli/{rel}", (package / rel).read_bytes())
        for folder, part in (("reference_dev", dev_rows(rows, dev)), ("reference_final", rows)):
            for name, data in reference_files(private, ids, part, meta).items():
                _add(zf, f"{folder}/{name}", data)
        _add(zf, "solutions/sample/disp.npz", sample_submission(ids))
        _add(zf, "starting_kit/README.md", pages.starting_kit_readme(meta).encode())
        _add(zf, "starting_kit/make_submission.py", pages.MAKE_SUBMISSION.encode())
    return {"dev": dev, "final": n}
