"""Predictions and ground truth for the evaluation tests: KITTI-like maps made in memory, the
prediction folder's first form, and the results CSV read back."""

from __future__ import annotations

import csv

import numpy as np


KITTI_VARIANTS = ["clean", "brightness/1", "brightness/3", "contrast/1", "contrast/3"]



GT_SHAPES = [(375, 1242), (370, 1226)]  # two KITTI dates differ in image size



def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))



def smooth_depth(h, w, seed):
    """A dense, smooth depth field in metres (near at the bottom, far at the top)."""
    rng = np.random.default_rng(seed)
    y = np.linspace(1, 0, h)[:, None]
    x = np.linspace(0, 1, w)[None, :]
    return (8 + 70 * (1 - y) ** 2 + 5 * np.sin(6 * x + rng.uniform(0, 6))).astype(np.float32)



def lidar_gt(shape, seed):
    """KITTI-like ground truth: ~7% of the pixels, some beyond 80 m (invalid), zeros elsewhere."""
    rng = np.random.default_rng(seed)
    d = smooth_depth(*shape, seed) * rng.uniform(0.9, 1.25, shape).astype(np.float32)
    d[rng.random(shape) > 0.07] = 0
    return d



def fake_disp(shape, seed, noise, scale=0.03):
    """A mono model's disparity at the network size: 1 / depth up to scale, with noise."""
    rng = np.random.default_rng(seed)
    d = smooth_depth(*shape, seed % 2) * (1 + noise * rng.standard_normal(shape)).clip(0.3, None)
    return (scale / d).astype(np.float32)



def kitti_preds(variant_index, n=2, shape=(64, 96)):
    return np.stack([fake_disp(shape, i, 0.05 * (1 + variant_index)) for i in range(n)])



def write_form1(pred, preds_by_variant, ext=".npy"):
    for rel, arr in preds_by_variant.items():
        path = pred / f"{rel}{ext}"
        path.parent.mkdir(parents=True, exist_ok=True)
        if ext == ".npy":
            np.save(path, arr)
        else:
            np.savez(path, arr)
    return pred



KEY69 = "kitti_data/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


def ref_errors(g, d, nyu=False):
    """compute_errors of the reference scripts on the valid pixels (numpy, in the arrays'
    dtype as they compute it; silog's logarithms in float64, see below)."""
    t = np.maximum(g / d, d / g)
    out = [np.mean(np.abs(g - d) / g), np.mean((g - d) ** 2 / g), np.sqrt(np.mean((g - d) ** 2)),
           np.sqrt(np.mean((np.log(g) - np.log(d)) ** 2)),
           np.mean(t < 1.25), np.mean(t < 1.25 ** 2), np.mean(t < 1.25 ** 3)]
    if nyu:
        # float64: the difference of two means cancels most digits (the variance of e is
        # small beside its mean's square), and float32 keeps only ~1e-5 of silog then
        e = np.log(d.astype(np.float64)) - np.log(g.astype(np.float64))
        out += [np.mean(np.abs(np.log10(d) - np.log10(g))),
                np.sqrt(np.mean(e ** 2) - np.mean(e) ** 2) * 100]
    return out
