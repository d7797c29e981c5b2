"""A model judged on corruptions made from its own depth predictions.

A build with ``--scene-depth PRED`` records the model whose predictions gave the
depth-aware corruptions their depth (``build.json``'s ``depth.identity``). ``robodepth
evaluate`` on such a build writes two comment lines at the top of its results CSV (which
every reader skips): the identity of the scene depth's model and that of the model being
evaluated (from ``PRED/predictions.json``; ``unknown`` without one). ``score`` and
``report`` warn when the two are the same model: its depth errors shaped the corruptions it
is judged on, so its scores on the depth-aware corruptions are not comparable with other
models'. Builds with any other depth source write no such line (their CSVs are as before).
"""

from __future__ import annotations

SCENE = "# scene depth: predictions of "
EVALUATED = "# evaluated: predictions of "


def csv_lines(depth: dict | None, pred_record: dict | None) -> tuple[str, ...]:
    """The comment lines for a build whose record's ``depth`` entry is ``depth``, evaluated
    with the predictions whose ``predictions.json`` is ``pred_record``; none unless the
    build's depth came from predictions."""
    from ..predictions import model_identity

    if not isinstance(depth, dict) or depth.get("kind") != "predictions":
        return ()
    evaluated = model_identity(pred_record) if pred_record else "unknown"
    name = f" ({pred_record.get('model')})" if pred_record else ""
    return (f"{SCENE}{depth.get('identity')} ({depth.get('model')})", f"{EVALUATED}{evaluated}{name}")


def _identity(line: str, prefix: str) -> str:
    return line[len(prefix):].split(" (")[0].strip()


def warning(table) -> str:
    """One line when the results ``table`` (a :class:`.csvrows.ResultsTable`) are of the
    model whose predictions made the build's scene depth; "" otherwise."""
    scene = evaluated = ""
    for line in table.comments:
        if line.startswith(SCENE):
            scene = _identity(line, SCENE)
        elif line.startswith(EVALUATED):
            evaluated = _identity(line, EVALUATED)
    source = table.source
    if not scene or scene != evaluated:
        return ""
    return (f"{source}: this model was evaluated on depth-aware corruptions made from its own "
            f"depth predictions ({scene}); its errors there are not comparable with other models'")
