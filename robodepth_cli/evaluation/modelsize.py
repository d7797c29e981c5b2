"""The model's size in a results CSV: the ``params`` and ``flops`` columns.

``robodepth evaluate`` adds them to every row when ``PRED/predictions.json`` records the
model's size (``robodepth predict`` measures it for torch models, see
:mod:`robodepth_cli.models.size`): ``params`` the number of parameters, ``flops`` the FLOPs
per image (a multiply-add counts 2). Results without them (a model robodepth did not run)
are the same CSV as before.
"""

from __future__ import annotations

COLUMNS = ("params", "flops")


def with_size(text: str, record: dict | None) -> str:
    """The results CSV ``text`` with the :data:`COLUMNS` of ``record["size"]`` (a
    predictions.json) added to every row; unchanged without a recorded size."""
    size = (record or {}).get("size")
    if not isinstance(size, dict) or not all(isinstance(size.get(c), int) for c in COLUMNS):
        return text
    lines = text.splitlines()
    cells = ",".join(str(size[c]) for c in COLUMNS)
    out = [f"{lines[0]},{','.join(COLUMNS)}"] + [f"{line},{cells}" for line in lines[1:] if line]
    return "\n".join(out) + "\n"

