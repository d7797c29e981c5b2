"""The model's size in a results CSV: the ``params`` and ``flops`` columns.

``robodepth evaluate`` adds them to every row when ``PRED/predictions.json`` records the
model's size (``robodepth predict`` measures it for torch models, see
:mod:`robodepth_cli.models.size`): ``params`` the number of parameters, ``flops`` the FLOPs
per image (a multiply-add counts 2). Results without them (a model robodepth did not run)
are the same CSV as before.
"""

from __future__ import annotations

from .csvrows import ResultsTable

COLUMNS = ("params", "flops")


def with_size(table: ResultsTable, record: dict | None) -> ResultsTable:
    """``table`` with the :data:`COLUMNS` of ``record["size"]`` (a predictions.json) as its
    last columns on every row; unchanged without a recorded size."""
    size = (record or {}).get("size")
    if not isinstance(size, dict) or not all(isinstance(size.get(c), int) for c in COLUMNS):
        return table
    for c in COLUMNS:
        table = table.with_column(c, str(size[c]))
    return table
