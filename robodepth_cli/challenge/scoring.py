"""Scoring a challenge submission against the private reference, per image by the track's
protocol (kitti: the official evaluator, the disparity resized by :func:`.resize.resize_at`;
nyu: :func:`~robodepth_cli.evaluation.protocols.nyu_image`), then the mean of each metric
over images and, since the scorer holds the key, per corruption, category and level, with
DEE = (abs_rel - a1 + 1) / 2 of each group's means (a category's: its corruptions' mean)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..benchmark_facts import ALL_CATEGORY, CATEGORIES
from ..errors import RobodepthError
from ..evaluation import protocols
from . import layout
from .resize import resize_at

RANK = {"kitti": ("abs_rel", "asc"), "nyu": ("a1", "desc")}  # as the ICRA 2023 tracks ranked


def slug(name: str) -> str:
    """A score key part: ``weather & lighting`` -> ``weather_lighting``."""
    return "_".join(w for w in name.replace("&", " ").split() if w)


@dataclass
class Reference:
    """The private side: the list order, the key rows scored and the ground truth."""

    folder: str
    track: str
    ids: list[str]  # every image, list order (a submission has a map for each)
    rows: dict[str, dict]  # id -> key row, the images scored
    meta: dict = field(default_factory=dict)

    def ground_truth(self):
        """An opened ``gt.npz`` (read lazily, member by member, never pickled)."""
        path = os.path.join(self.folder, layout.GT)
        try:
            return np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise RobodepthError(f"{path}: {exc}") from None


def open_reference(folder: str) -> Reference:
    """The reference in ``folder`` (``challenge build``'s private folder, or a phase's
    reference data in a bundle)."""
    meta = layout.read_meta(folder)
    ids = layout.read_list(folder)
    rows = {r["id"]: r for r in layout.read_key(folder)}
    unknown = [i for i in rows if i not in set(ids)]
    if unknown:
        raise RobodepthError(f"{folder}: key.csv names ids list.txt lacks ({unknown[0]})")
    return Reference(folder, meta["track"], ids, rows, meta)


def image_errors(track: str, pred: np.ndarray, gt: np.ndarray) -> tuple:
    """The metrics of one image under ``track`` (see the module docstring)."""
    if track == "kitti":
        index = protocols.kitti_valid(gt)
        if not index.size:
            raise RobodepthError("a ground-truth map has no valid pixel")
        gt_values = gt.reshape(-1)[index]
        disp = resize_at(pred, gt.shape, index)
        depth, _ = protocols.align_prediction(disp, True, gt_values, "median", "depth",
                                      protocols.MIN_DEPTH, protocols.KITTI_MAX_DEPTH)
        return protocols.depth_errors(gt_values, depth)
    index = protocols.nyu_valid(gt)
    return protocols.nyu_image(pred.astype(np.float32), gt.shape, index, gt.reshape(-1)[index])


@dataclass
class Scores:
    """Per-image metrics of the scored images and what they add up to."""

    track: str
    metrics: tuple[str, ...]
    rows: list[dict]  # key rows of the scored images, in list order
    values: np.ndarray  # len(rows) x len(metrics), float64

    def mean(self, mask=None) -> dict[str, float]:
        v = self.values if mask is None else self.values[mask]
        return dict(zip(self.metrics, v.mean(0).tolist()))

    def groups(self) -> dict[str, dict]:
        """Per corruption (benchmark order), its images' count, metric means and DEE."""
        corr = np.array([r["corruption"] for r in self.rows])
        names = [c for c in ALL_CATEGORY if c in set(corr)] + sorted(set(corr) - set(ALL_CATEGORY))
        out = {}
        for c in names:
            mask = corr == c
            m = self.mean(mask)
            out[c] = {"images": int(mask.sum()), **m, "dee": dee(m)}
        return out

    def levels(self) -> dict[int, dict]:
        lv = np.array([r["level"] for r in self.rows])
        out = {}
        for level in sorted(set(lv.tolist())):
            m = self.mean(lv == level)
            out[level] = {"images": int((lv == level).sum()), **m, "dee": dee(m)}
        return out

    def flat(self) -> dict[str, float]:
        """``scores.json``: flat keys a leaderboard column can name (see docs/challenge.md)."""
        overall = self.mean()
        out: dict[str, float] = {**overall, "dee": dee(overall), "images": len(self.rows)}
        groups = self.groups()
        for c, g in groups.items():
            for k in ("abs_rel", "a1", "dee"):
                out[f"{k}_{c}"] = g[k]
        by_cat: dict[str, list[float]] = {}
        for c, g in groups.items():
            by_cat.setdefault(ALL_CATEGORY.get(c, "other"), []).append(g["dee"])
        for cat in [*CATEGORIES, "other"]:
            if cat in by_cat:
                out[f"dee_{slug(cat)}"] = float(np.mean(by_cat[cat]))
        if groups:
            out["mdee"] = float(np.mean([g["dee"] for g in groups.values()]))
        for level, g in self.levels().items():
            out[f"dee_level{level}"] = g["dee"]
        return out


def dee(m: dict) -> float:
    """``(abs_rel - a1 + 1) / 2``."""
    return (m["abs_rel"] - m["a1"] + 1) / 2


def score(submission, ref: Reference) -> Scores:
    """Score every map of ``submission`` (a :class:`.submission.Submission` opened for
    ``ref.ids``) whose image ``ref`` holds; the others are read and checked, not scored."""
    metrics = protocols.KITTI_METRICS if ref.track == "kitti" else protocols.NYU_METRICS
    rows, values = [], []
    with ref.ground_truth() as gt_file:
        for image_id, pred in submission.maps():
            row = ref.rows.get(image_id)
            if row is None:
                continue
            try:
                gt = layout.read_gt(gt_file, image_id)
            except KeyError:
                raise RobodepthError(f"{ref.folder}: gt.npz has no map for {image_id}") from None
            try:
                values.append(image_errors(ref.track, pred, gt))
            except protocols.EvaluationError as exc:
                raise protocols.EvaluationError(f"{submission.where}: image {image_id}: {exc}") from None
            rows.append(row)
    if len(rows) != len(ref.rows):
        raise RobodepthError(f"{ref.folder}: {len(ref.rows) - len(rows)} images of the key are "
                              "not in list.txt")
    return Scores(ref.track, metrics, rows, np.array(values, dtype=np.float64).reshape(len(rows), len(metrics)))
