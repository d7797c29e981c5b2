"""The challenge tests' and benchmark's shared pieces: the official evaluator's steps written
out from the RoboDepth toolkit's ``competition/evaluator_npy.py`` (independently of
robodepth's code), and a reference folder written by hand in the documented layout."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np


def official_errors(gt, pred):
    """evaluator_npy.py's compute_errors: the seven metrics, in its order."""
    thresh = np.maximum((gt / pred), (pred / gt))
    a1 = (thresh < 1.25).mean()
    a2 = (thresh < 1.25 ** 2).mean()
    a3 = (thresh < 1.25 ** 3).mean()
    rmse = np.sqrt(((gt - pred) ** 2).mean())
    rmse_log = np.sqrt(((np.log(gt) - np.log(pred)) ** 2).mean())
    abs_rel = np.mean(np.abs(gt - pred) / gt)
    sq_rel = np.mean(((gt - pred) ** 2) / gt)
    return abs_rel, sq_rel, rmse, rmse_log, a1, a2, a3


def official_evaluate(pred_disps, gt_depths) -> np.ndarray:
    """The official Track-1 evaluation (mono, eigen split, median scaling): per image,
    skimage's resize to the ground truth's size, 1 / disparity, the mask 1e-3 < gt < 80 inside
    the Garg crop (bounds as int32 of the float products), the median ratio, the clamp, the
    metrics; their mean over images."""
    from skimage.transform import resize

    min_depth, max_depth = 1e-3, 80
    errors = []
    for i in range(pred_disps.shape[0]):
        gt = gt_depths[i]
        h, w = gt.shape[:2]
        depth = 1 / resize(pred_disps[i], (h, w))
        mask = np.logical_and(gt > min_depth, gt < max_depth)
        box = np.array([0.40810811 * h, 0.99189189 * h, 0.03594771 * w, 0.96405229 * w]).astype(np.int32)
        inside = np.zeros(mask.shape)
        inside[box[0]:box[1], box[2]:box[3]] = 1
        mask = np.logical_and(mask, inside)
        depth, gt = depth[mask], gt[mask]
        depth *= np.median(gt) / np.median(depth)
        depth[depth < min_depth] = min_depth
        depth[depth > max_depth] = max_depth
        errors.append(official_errors(gt, depth))
    return np.array(errors).mean(0)


def write_reference(folder: Path, ids, gts, track: str = "kitti", corruptions=None, levels=None) -> Path:
    """A private reference folder as docs/challenge.md describes it: list.txt, key.csv,
    gt.npz (np.savez, one member per id), challenge.json."""
    folder.mkdir(parents=True, exist_ok=True)
    corruptions = corruptions or ["brightness"] * len(ids)
    levels = levels or [1] * len(ids)
    (folder / "list.txt").write_text("".join(i + "\n" for i in ids))
    np.savez(folder / "gt.npz", **dict(zip(ids, gts)))
    with open(folder / "key.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "position", "source", "corruption", "level", "seed", "sha256"])
        for k, (i, c, lv) in enumerate(zip(ids, corruptions, levels)):
            w.writerow([i, k, f"frame{k}.png", c, lv, 0, "0" * 64])
    (folder / "challenge.json").write_text(json.dumps({"format": 1, "track": track, "images": len(ids)}))
    return folder


def public_folder(folder: Path, ids, track: str = "kitti") -> Path:
    """A public folder's list.txt and challenge.json (no images: check needs only those)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "list.txt").write_text("".join(i + "\n" for i in ids))
    (folder / "challenge.json").write_text(json.dumps({"format": 1, "track": track, "images": len(ids)}))
    return folder
