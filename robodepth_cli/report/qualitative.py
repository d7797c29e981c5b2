"""The qualitative figure: one frame of a dataset build, clean and under a few corruptions
(or styles), with each model's prediction under each image."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..api import open_dataset
from ..benchmarks import CLEAN
from .inputs import KITTI_S, ReportError

# Shown when the build has them: one corruption of each category and one more, at level 3
# (visible yet not extreme); for KITTI-S, three styles.
PREFERRED = (("fog", 3), ("motion_blur", 3), ("gaussian_noise", 3), ("snow", 3),
             ("dark", 3), ("contrast", 3), ("defocus_blur", 3), ("pixelate", 3))
PREFERRED_STYLES = ("cartoon", "sketch", "water_color", "oil_painting")
COLUMNS = 4  # clean + three variants


def choose_variants(dataset) -> list:
    """Clean and up to three other variants of ``dataset`` that exist, by preference."""
    built = {(v.name, v.level): v for v in dataset.variants()}
    if (CLEAN, None) not in built:
        raise ReportError(f"--dataset {dataset.path}: the build has no clean images")
    chosen = [built[CLEAN, None]]
    wanted = ([(s, None) for s in PREFERRED_STYLES] if dataset.name == KITTI_S else list(PREFERRED))
    wanted += sorted(k for k in built if k[0] != CLEAN)
    for key in wanted:
        if len(chosen) == COLUMNS:
            break
        if key in built and built[key] not in chosen:
            chosen.append(built[key])
    return chosen


def inverse_depth(pred: np.ndarray, kind: str) -> np.ndarray:
    """What to colour: disparity and sigmoid outputs as they are (near is large), depth
    inverted; non-finite or non-positive depths become 0 (drawn as farthest)."""
    m = np.asarray(pred, dtype=np.float64)
    if kind == "depth":
        with np.errstate(divide="ignore", invalid="ignore"):
            m = np.where(m > 0, 1.0 / m, 0.0)
    return np.where(np.isfinite(m), m, 0.0)


def qualitative(report, dataset_dir: Path, preds: Sequence[Path], frame: int, kind: str | None):
    """The figure entry (stem, title, caption, Figure) for ``report``'s page."""
    from ..evaluation.predictions import find_predictions
    from ..imageio import read_rgb
    from .figures import qualitative_figure

    dataset = open_dataset(dataset_dir)
    if frame >= len(dataset.keys):
        raise ReportError(f"--frame {frame}: {dataset_dir} has {len(dataset.keys)} images "
                          f"(0..{len(dataset.keys) - 1})")
    kind = kind or ("depth" if dataset.name == "nyudepth2-c" else "disp")
    variants = choose_variants(dataset)
    models = report.models[:len(preds)]
    images, rows = [], []
    for v in variants:
        images.append(np.asarray(read_rgb(v.images()[frame])))
    for model, pred in zip(models, preds):
        row = []
        for v in variants:
            found = find_predictions(Path(pred), v, 256.0)
            if found is None:
                raise ReportError(f"--pred {pred}: no predictions for {v.label} (expected "
                                  f"{v.prediction_file(pred)})")
            try:
                m, _, _ = found.read(frame)
            finally:
                found.close()
            if m.ndim != 2:
                raise ReportError(f"--pred {pred}: prediction {frame} of {v.label} is not a 2-D map")
            row.append(inverse_depth(m, kind))
        rows.append((model.name, row))
    key = dataset.keys[frame]
    fig = qualitative_figure([v.label for v in variants], images, rows, dataset.name, key)
    names = ", ".join(m.name for m in models)
    return ("qualitative", "One frame", f"Frame {frame} ({key}) of {dataset_dir}: the clean "
            f"image and {len(variants) - 1} variants, with the predictions of {names} under "
            "each (inverse depth, one colour scale per model, set by its clean prediction).", fig)
