"""``robodepth report`` on challenge ``scores.json`` files (``robodepth challenge score``,
or a Codabench scoring run): the leaderboard, one table per track, ranked as the track
ranks (kitti: Abs Rel ascending, nyu: a1 descending), with the metrics, DEE, mean DEE and
DEE per corruption as columns. Written as ``OUT/index.html`` (self-contained) and
``OUT/leaderboard.md``."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Sequence

from ..benchmark_facts import ALL_CORRUPTIONS
from ..errors import RobodepthError
from .inputs import model_names

RANK = {"kitti": ("abs_rel", False), "nyu": ("a1", True)}  # metric, higher is better
METRICS = {"kitti": ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3"),
           "nyu": ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3", "log10", "silog")}


def is_challenge_scores(path: Path) -> bool:
    """Whether ``path`` looks like a challenge ``scores.json`` (a JSON object with abs_rel,
    a1 and dee), not a results CSV."""
    if Path(path).suffix.lower() != ".json":
        return False
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and {"abs_rel", "a1", "dee"} <= set(doc)


def read_scores(path: Path) -> tuple[str, dict[str, float]]:
    """(track, scores) of one ``scores.json``: track nyu when it has the NYU metrics."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise RobodepthError(f"{path}: not a readable scores.json ({exc})") from None
    if not isinstance(doc, dict):
        raise RobodepthError(f"{path}: not a challenge scores.json (a JSON object)")
    track = "nyu" if "silog" in doc else "kitti"
    bad = [m for m in METRICS[track] + ("dee",)
           if not isinstance(doc.get(m), (int, float)) or not math.isfinite(doc[m])]
    if bad:
        raise RobodepthError(f"{path}: {bad[0]}: missing or not a number; not a challenge scores.json")
    return track, {k: float(v) for k, v in doc.items() if isinstance(v, (int, float))}


def _name(path: Path) -> str:
    """A scores.json is usually called so: the folder it is in names the model."""
    path = Path(path)
    return path.parent.name if path.stem == "scores" and path.parent.name else path.stem


def tables(paths: Sequence[Path], names: Sequence[str]) -> dict[str, list[list[str]]]:
    """Per track, the leaderboard as rows of cells (header first), ranked."""
    chosen = model_names(paths, names) if names else model_names(paths, [_name(p) for p in paths])
    by_track: dict[str, list[tuple[str, dict]]] = {}
    for name, path in zip(chosen, paths):
        track, scores = read_scores(path)
        by_track.setdefault(track, []).append((name, scores))
    out = {}
    for track in ("kitti", "nyu"):
        entries = by_track.get(track)
        if not entries:
            continue
        metric, higher = RANK[track]
        entries.sort(key=lambda e: -e[1][metric] if higher else e[1][metric])
        corruptions = [c for c in ALL_CORRUPTIONS if any(f"dee_{c}" in s for _, s in entries)]
        cols = list(METRICS[track]) + ["dee", "mdee"] + [f"dee_{c}" for c in corruptions]
        rows = [["rank", "model", *[c.replace("dee_", "DEE ") if c.startswith("dee_") else c for c in cols]]]
        for i, (name, s) in enumerate(entries, 1):
            rows.append([str(i), name, *[f"{s[c]:.4f}" if c in s else "-" for c in cols]])
        out[track] = rows
    return out


def write_leaderboard(paths: Sequence[Path], names: Sequence[str], out: Path) -> list[Path]:
    """Write ``OUT/index.html`` and ``OUT/leaderboard.md``; return them."""
    from ..files import write_atomic

    per_track = tables(paths, names)
    title = {"kitti": "Track kitti (ranked by Abs Rel, lower is better)",
             "nyu": "Track nyu (ranked by a1, higher is better)"}
    md, body = ["# Challenge leaderboard", ""], []
    for track, rows in per_track.items():
        md += [f"## {title[track]}", "", "| " + " | ".join(rows[0]) + " |",
               "|" + "---|" * len(rows[0])] + ["| " + " | ".join(r) + " |" for r in rows[1:]] + [""]
        head = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
        cells = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows[1:])
        body.append(f"<h2>{html.escape(title[track])}</h2><table><thead><tr>{head}</tr></thead>"
                    f"<tbody>{cells}</tbody></table>")
    style = ("body{font-family:sans-serif;margin:1.5em;color:#1e1e1e}table{border-collapse:collapse}"
             "th,td{border:1px solid #ccc;padding:3px 6px;text-align:right}td:nth-child(2){text-align:left}")
    page = ("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>Challenge leaderboard</title>"
            f"<style>{style}</style></head><body><h1>Challenge leaderboard</h1>{''.join(body)}</body></html>\n")
    written = [Path(out) / "index.html", Path(out) / "leaderboard.md"]
    write_atomic(written[0], page.encode())
    write_atomic(written[1], "\n".join(md).encode())
    return written
