"""The text of a bundle's pages and of its starting kit."""

from __future__ import annotations

MAKE_SUBMISSION = '''"""Write a valid challenge submission from per-image predictions.

    python make_submission.py PUBLIC PRED_DIR submission.zip [--half]

PUBLIC is the challenge's public folder (its list.txt gives the ids); PRED_DIR holds one
<id>.npy per image: an H x W float map (track kitti: a disparity; track nyu: depth in
metres). The result is a zip holding disp.npz, one map per id (the keyed form, which no
ordering mistake can spoil). --half stores float16 (half the upload). Needs numpy only.
"""
import io
import os
import sys
import zipfile

import numpy as np


def main(public, pred, out, half=False):
    with open(os.path.join(public, "list.txt")) as fh:
        ids = [line.strip() for line in fh if line.strip()]
    npz = io.BytesIO()
    with zipfile.ZipFile(npz, "w", zipfile.ZIP_DEFLATED) as zf:
        for image_id in ids:  # one map in memory at a time
            m = np.load(os.path.join(pred, image_id + ".npy"), allow_pickle=False)
            m = np.squeeze(m).astype(np.float16 if half else np.float32)
            if m.ndim != 2 or not np.isfinite(m).all() or not (m > 0).all():
                sys.exit(f"{image_id}.npy: need one H x W map of finite values above zero")
            with zf.open(image_id + ".npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.ascontiguousarray(m), allow_pickle=False)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_STORED) as zf:
        zf.writestr("disp.npz", npz.getvalue())
    print(f"{out}: {len(ids)} maps")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--half"]
    if len(args) != 3:
        sys.exit(__doc__)
    main(*args, half="--half" in sys.argv[1:])
'''


def _what(meta: dict) -> str:
    return ("a disparity map per image (any scale: each is median-scaled to the ground truth)"
            if meta["track"] == "kitti" else "a depth map in metres per image (no scaling)")


def pages(meta: dict, title: str, dev: int, max_bytes: int) -> dict[str, str]:
    n, track = meta["images"], meta["track"]
    rank = "Abs Rel (lower is better)" if track == "kitti" else "a1 (higher is better)"
    return {
        "overview": f"# {title}\n\nMonocular depth estimation under corruptions (the RoboDepth "
                    f"benchmark). The test set holds {n} images, each under one corruption at one "
                    f"level; which one is hidden. Submit {_what(meta)}.\n\nTwo phases: "
                    f"development (scores on {dev} of the images, shown at once) and final (every "
                    "image).\n",
        "data": "# Data\n\nThe public folder holds `images/<id>.png`, `list.txt` (the order of "
                "predictions) and a README. Predict every image; the starting kit's "
                "`make_submission.py` (or `robodepth predict PUBLIC --model ... --out "
                "submission.zip`) writes a valid submission.\n",
        "evaluation": f"# Evaluation\n\nTrack {track}, ranked by {rank}. "
                      + ("Each disparity is resized to its ground truth with scikit-image's "
                         "`resize`, inverted, median-scaled, clamped to 1e-3..80 m and compared "
                         "inside the Garg crop: the official evaluator of the RoboDepth Challenge. "
                         if track == "kitti" else
                         "Each depth map is compared in metres inside the Eigen crop, "
                         "clamped to 1e-3..10 m (the NYU protocol). ")
                      + "The seven depth metrics are averaged over images; DEE = (Abs Rel - a1 + "
                      "1) / 2. The detailed results show them per corruption and per level.\n\n"
                      "Accepted: a zip holding `disp.npz` (one map per id: recommended), or one "
                      "`disp.npy` of shape (N, H, W) in the order of `list.txt`, or `disp.npz` "
                      "saved with `data=`; float16/32/64, values finite and above zero, at most "
                      f"{max_bytes / 1e6:.0f} MB. A refusal says why in the scoring log.\n",
        "terms": "# Terms\n\nThe test images derive from the source dataset and keep its license. "
                 "Do not label or hand-tune on the test images.\n",
    }


def starting_kit_readme(meta: dict) -> str:
    return ("# Starting kit\n\n`make_submission.py PUBLIC PRED_DIR submission.zip` writes a valid "
            f"submission from one `<id>.npy` per image ({_what(meta)}). Upload the zip.\n")
