"""The scene depth of a build from a model's predictions (``build --scene-depth PRED``).

PRED is what ``robodepth predict`` wrote for the clean images of a build: ``clean.npy``
(``N x h x w`` in that build's split order, or ``clean.npz``) or one ``clean/<image>.npy``
per image, and ``predictions.json``, which names the build (its ``build.json`` lists the
split's keys, so each source of this build finds its map by key) and says what the maps
hold. They become metres by this rule:

- metric depth (``output: depth``, ``scale: metric``): as they are;
- metric disparity: ``1 / disparity`` metres;
- relative maps that ``robodepth evaluate`` judges by a scale alone (``align`` ``median`` or
  ``scale``, as monodepth2's): the depth (``1 / disparity`` for a disparity) times
  ``s = median(own) / median(pred)`` over the pixels where the dataset's own depth (its
  ground truth, or a custom build's ``--depth``, at the output size) is valid, per image:
  monodepth2's median scaling; refused for a build without depth of its own;
- relative maps up to a scale *and a shift* (``align scale-shift``: MiDaS, Depth Anything),
  and raw sigmoid outputs, are refused: no rule turns them into metres.

Then a depth of 0 or less is missing (the corruptions fill it from the nearest valid
pixel), a disparity of 0 or less is infinitely far (:data:`~..corruptions.depth.FAR`), and
the map is brought to the output size as a depth folder's (:func:`robodepth_cli.building.scenedepth.at_size`);
:class:`~robodepth_cli.building.scenedepth.PredictedDepth` reads the maps.
The build record keeps the model and its identity (:func:`~..predictions.model_identity`), each depth-aware
output's manifest row ``depth=predictions:<identity>``.
"""

from __future__ import annotations

from pathlib import Path

from .. import predictions
from ..errors import InvalidValueError


def read_record(pred: Path) -> dict:
    """``PRED/predictions.json``; :class:`InvalidValueError` saying why it cannot be used."""
    if not Path(pred).is_dir():
        raise InvalidValueError(f"{pred}: not a folder of robodepth predict's output")
    try:
        record = predictions.read_record(pred)
    except predictions.PredictionsError as exc:
        raise InvalidValueError(str(exc)) from None
    if record is None:
        raise InvalidValueError(f"{pred}: no {predictions.RECORD} (not written by robodepth predict), so "
                                "what its maps hold (depth or disparity, metres or relative) is unknown")
    return record


def conversion(record: dict, pred: Path) -> str:
    """How the maps become metres: ``metric``, ``median`` (scaled to the dataset's own
    depth); :class:`InvalidValueError` for maps that cannot."""
    kind, align = record["evaluate"].get("kind"), record["evaluate"].get("align")
    what = f"{pred}: the maps of {record.get('model')} are"
    if kind not in ("disp", "depth"):
        raise InvalidValueError(f"{what} {kind} outputs; depth in metres needs a depth or a disparity")
    if record.get("scale") == "metric" or align == "none":
        return "metric"
    if align in ("median", "scale"):
        return "median"
    raise InvalidValueError(f"{what} relative {record.get('output')} up to a scale and a shift "
                            f"(align {align}); no rule turns them into metres: give a metric "
                            "model's predictions")


def check_option(value, base: Path) -> str:
    """The checked ``scene_depth`` (a folder of robodepth predict's output) as an absolute path."""
    if not isinstance(value, str) or not value.strip():
        raise InvalidValueError(f"expected the folder of robodepth predict's output, got {value!r}")
    pred = (base / Path(value).expanduser()).resolve()
    conversion(read_record(pred), pred)
    return str(pred)
