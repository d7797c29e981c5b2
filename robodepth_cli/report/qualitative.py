"""The qualitative figure: one frame of a dataset build, clean and under a few corruptions
(or styles), with each model's prediction under each image."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .. import open_dataset
from ..benchmark_facts import CLEAN
from ..errors import RobodepthError, counted
from .inputs import KITTI_S

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
        raise RobodepthError(f"--dataset {dataset.path}: the build has no clean images")
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


DRAWN = {"disp": "disparity", "sigmoid": "sigmoid output", "depth": "depth, drawn inverted"}


def check_kinds(kinds: Sequence[str], preds: Sequence[Path]) -> None:
    """``--kind`` is given once per ``--pred``, once for all, or not at all."""
    if kinds and not preds:
        raise RobodepthError("--kind needs --pred (it says what the predictions hold)")
    if kinds and len(kinds) not in (1, len(preds)):
        raise RobodepthError(f"--kind given {counted(len(kinds), 'time')} for "
                             f"{counted(len(preds), '--pred folder')}; give "
                             "it once per --pred in the same order, once for all, or not at all "
                             "(each folder's predictions.json says it)")


def pred_kinds(preds: Sequence[Path], kinds: Sequence[str], dataset_name: str) -> list[tuple[str, str]]:
    """What each ``--pred`` holds and where that was read: ``(kind, source)`` with source
    ``--kind``, ``predictions.json`` (what robodepth predict recorded) or ``default`` (the
    dataset's evaluation default: disp for KITTI, depth for NYU). ``kinds`` is ``--kind``
    as given: not at all, once for every ``--pred``, or once per ``--pred`` in order."""
    from ..predictions import RECORD, read_record

    check_kinds(kinds, preds)
    default = "depth" if dataset_name == "nyudepth2-c" else "disp"
    out = []
    for i, pred in enumerate(preds):
        if kinds:
            out.append((kinds[i if len(kinds) > 1 else 0], "--kind"))
            continue
        record = read_record(Path(pred)) if Path(pred).is_dir() else None
        kind = (record or {}).get("evaluate", {}).get("kind")
        out.append((kind, RECORD) if kind in DRAWN else (default, "default"))
    return out


def qualitative(report, dataset_dir: Path, preds: Sequence[Path], frame: int, kinds: Sequence[str] = ()):
    """The figure entry (stem, title, caption, Figure) for ``report``'s page, and the
    ``(pred, kind)`` of each ``--pred`` drawn with the dataset's default kind because
    neither ``--kind`` nor a ``predictions.json`` said what it holds."""
    from ..predictions import RECORD, find_predictions
    from .figures import qualitative_figure

    dataset = open_dataset(dataset_dir)
    if frame >= len(dataset.keys):
        raise RobodepthError(f"--frame {frame}: {dataset_dir} has {len(dataset.keys)} images "
                             f"(0..{len(dataset.keys) - 1})")
    held = pred_kinds(preds, kinds, dataset.name)
    variants = choose_variants(dataset)
    models = report.models[:len(preds)]
    images, rows = [], []
    for v in variants:
        images.append(v.read(frame))  # a build's file or an export's shard
    for model, pred, (kind, _) in zip(models, preds, held):
        row = []
        for v in variants:
            found = find_predictions(Path(pred), v, 256.0)
            if found is None:
                raise RobodepthError(f"--pred {pred}: no predictions for {v.label} (expected "
                                     f"{v.prediction_file(pred)})")
            try:
                m, _, _ = found.read(frame)
            finally:
                found.close()
            if m.ndim != 2:
                raise RobodepthError(f"--pred {pred}: prediction {frame} of {v.label} is not a 2-D map")
            row.append(inverse_depth(m, kind))
        rows.append((f"{model.name}  ({DRAWN[kind]})", row))
    key = dataset.keys[frame]
    fig = qualitative_figure([v.label for v in variants], images, rows, dataset.name, key)
    said = {"--kind": "as --kind says", RECORD: f"as its {RECORD} records",
            "default": f"the {dataset.name} default"}
    names = ", ".join(f"{m.name} ({DRAWN[k]}, {said[s]})" for m, (k, s) in zip(models, held))
    entry = ("qualitative", "One frame", f"Frame {frame} ({key}) of {dataset_dir}: the clean "
             f"image and {len(variants) - 1} variants, with the predictions of {names} under "
             "each (inverse depth, one colour scale per model, set by its clean prediction).", fig)
    return entry, [(pred, k) for pred, (k, s) in zip(preds, held) if s == "default"]
