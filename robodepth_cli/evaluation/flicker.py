"""Flicker: how steadily a model predicts along a sequence (``evaluate --flicker``).

Depth models flicker on video: the scale of their maps and their error jump between frames
that hardly differ. Over every pair of consecutive frames among the evaluated images (frame
``n`` and ``n + 1`` of the same folder: the keys' file names end in the frame number), two
measures, beside the per-frame metrics:

- ``flicker_scale``: ``exp(mean |log(s[n+1] / s[n])|) - 1``, where ``s`` is the per-frame
  median scale ``median(gt) / median(depth)`` over the valid pixels (the factor that aligns
  the prediction to the ground truth, before any alignment): the typical relative change of
  the model's scale from one frame to the next (0.05: 5% per frame);
- ``flicker_abs_rel``: ``mean |abs_rel[n+1] - abs_rel[n]|``, the change of the error (after
  the protocol's alignment) from one frame to the next.

A split of consecutive frames (a custom split of a drive's frames, or the Eigen split's
neighbouring test frames) gives the pairs; a split without any is refused.
"""

from __future__ import annotations

import re
from pathlib import PurePosixPath

import numpy as np

from .protocols import EvaluationError, disp_to_depth

COLUMNS = ("flicker_scale", "flicker_abs_rel")
_NUMBERED = re.compile(r"^(.*?)(\d+)$")


def consecutive_pairs(keys) -> list[tuple[int, int]]:
    """``(i, j)`` for every two keys that are frames ``n`` and ``n + 1`` of one folder."""
    where: dict[tuple[str, str, int], int] = {}
    for i, key in enumerate(keys):
        p = PurePosixPath(key)
        m = _NUMBERED.match(p.stem)
        if m:
            where[(str(p.parent), m.group(1), int(m.group(2)))] = i
    return sorted((i, where[(d, pre, n + 1)]) for (d, pre, n), i in where.items()
                  if (d, pre, n + 1) in where)


def frame_scale(pred: np.ndarray, kind: str, gt_shape, index: np.ndarray, gt: np.ndarray) -> float:
    """``median(gt) / median(depth)`` of one KITTI-protocol image: the prediction resized to
    the ground truth as the protocol does, a disparity inverted."""
    from .kernels import sample_linear

    if kind == "sigmoid":
        pred = disp_to_depth(pred)
    values = sample_linear(pred, gt_shape, index).astype(np.float64)
    with np.errstate(divide="ignore"):
        depth = values if kind == "depth" else 1 / values
    return float(np.median(gt) / np.median(depth))


def measure(scales, abs_rel, pairs) -> dict[str, float]:
    """The two flicker measures of one variant from its per-frame scales and abs_rel."""
    s = np.asarray(scales, dtype=np.float64)
    e = np.asarray(abs_rel, dtype=np.float64)
    i, j = np.array(pairs).T
    with np.errstate(divide="ignore", invalid="ignore"):
        change = np.abs(np.log(s[j] / s[i]))
    if not np.all(np.isfinite(change)):
        raise EvaluationError("a prediction's median depth is 0 or infinite: its scale, and so "
                              "the flicker, is not defined")
    return {"flicker_scale": float(np.expm1(change.mean())),
            "flicker_abs_rel": float(np.abs(e[j] - e[i]).mean())}


def check_pairs(keys, protocol: str, frames=None) -> list[tuple[int, int]]:
    """The consecutive pairs of ``keys``; :class:`EvaluationError` saying why flicker cannot
    be measured otherwise. ``frames``: the build's ``--frames`` offsets, if it has any."""
    if protocol != "kitti":
        raise EvaluationError("--flicker: flicker is measured under the kitti protocol (NYU's "
                              "test frames are no sequence)")
    pairs = consecutive_pairs(keys)
    if not pairs:
        # A build's neighbour frames have neither predictions nor ground truth of the split.
        extra = (f"; the build's neighbour frames (--frames {','.join(map(str, frames))}) are not "
                 "evaluated, only its test frames" if frames else "")
        raise EvaluationError("--flicker: the split has no consecutive frames (frame n and n + 1 "
                              f"of one drive){extra}; build a split that lists a sequence, such as "
                              "--split kitti_sequences, and evaluate that")
    return pairs


def read_flicker(table) -> list[dict]:
    """The flicker columns of a results table that has them (``evaluate --flicker``), one
    ``{corruption, level, flicker_scale, flicker_abs_rel}`` per row; [] when it has none.
    The table was already checked as a results CSV (``results.read_results``)."""
    if not set(COLUMNS) <= set(table.header):
        return []
    out = []
    for row in table.records():
        try:
            out.append({"corruption": row["corruption"].strip(), "level": row["level"].strip(),
                        **{c: float(row[c]) for c in COLUMNS}})
        except (AttributeError, TypeError, ValueError):
            raise EvaluationError(f"{table.source}: a row without numbers in {', '.join(COLUMNS)}") from None
    return out


def format_flicker(rows: list[dict]) -> str:
    """The flicker table ``score`` prints under the scores."""
    lines = ["", f"flicker (consecutive frames)  {'scale':>8}  {'abs_rel':>8}"]
    for r in rows:
        label = r["corruption"] if r["corruption"] == "clean" else f"{r['corruption']} {r['level']}"
        lines.append(f"{label:<29}  {r['flicker_scale']:>8.4f}  {r['flicker_abs_rel']:>8.4f}")
    return "\n".join(lines) + "\n"
