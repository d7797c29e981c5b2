"""The rows of a results CSV: the header, the cells and the checks of every number in them.

:func:`data_rows` finds the header, the columns scoring needs (``corruption``, ``level`` and
``abs_rel`` with ``a1``, or ``dee``) and yields each data row's cells. Every number of a row
is checked as it is read, in any column, scored or not: a non-finite number (``nan``,
``inf``) is refused wherever it is, and the metrics ``robodepth evaluate`` writes must lie
in their range: ``a1``, ``a2``, ``a3`` and ``dee`` in [0, 1], the error metrics (``abs_rel``,
``sq_rel``, ``rmse``, ``rmse_log``, ``log10``, ``silog``) at least 0 and at most
:data:`ERROR_LIMIT`. Beyond that limit a value is not an evaluation's result (depths are
clamped to the protocol's range, so even a map that is wrong everywhere stays far below
it) and would overflow the scores to infinity. A refusal is a :class:`ScoreError` naming
the file, the line and the column.
"""

from __future__ import annotations

import csv
import io
import math
from typing import Iterator

from ..errors import RobodepthError
from .protocols import NYU_METRICS

ERROR_LIMIT = 1e6
DATASET_COLUMNS = ("dataset", "split")  # what results are on, as robodepth evaluate writes it
FRACTIONS = ("a1", "a2", "a3", "dee")  # fractions of pixels, or DEE
ERRORS = tuple(m for m in NYU_METRICS if m not in FRACTIONS)  # non-negative, at most ERROR_LIMIT


class ScoreError(RobodepthError):
    """A results or baseline file that cannot be scored; the message is one line."""


def normalise_name(text: str) -> str:
    """A corruption cell as a name: ``Motion-Blur `` -> ``motion_blur``."""
    return text.strip().lower().replace("-", "_").replace(" ", "_")


def dataset_of(text: str, source: str) -> tuple[str, str] | None:
    """The (dataset, split) a results CSV's ``dataset`` and ``split`` columns name (lower
    case; split "" when absent or empty), or None when it has no ``dataset`` column (results
    from elsewhere, or written before evaluate wrote it). ScoreError when its rows name
    more than one, or a row has more cells than the header (:func:`check_width`)."""
    reader = csv.reader(io.StringIO(text))
    header: list[str] | None = None
    found = set()
    try:
        for row in reader:
            if not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
                continue
            if header is None:
                header = [c.strip().lower() for c in row]
                if "dataset" not in header:
                    return None
                at = [header.index(c) if c in header else None for c in DATASET_COLUMNS]
                continue
            check_width(row, header, f"{source}:{reader.line_num}")
            found.add(tuple(row[i].strip().lower() if i is not None and i < len(row) else ""
                            for i in at))
    except csv.Error as exc:
        raise ScoreError(f"{source}:{reader.line_num}: malformed CSV: {exc}") from None
    if header is None:
        return None
    if len(found) > 1:
        names = sorted(f"{d}:{s}" if s else d for d, s in found)
        raise ScoreError(f"{source}: its rows are on different datasets ({', '.join(names)}); "
                         "one results file holds one dataset's results")
    key = found.pop() if found else ("", "")
    return key if key[0] else None


def check_width(row: list[str], header: list[str], where: str) -> None:
    """Refuse a row with more cells than the header names columns: its cells would be read
    under the wrong columns (a comma inside a cell, a value pasted twice)."""
    if len(row) > len(header):
        raise ScoreError(f"{where}: {len(row)} fields, but the header names {len(header)} "
                         f"columns (a comma too many?)")


def number(text: str, column: str, where: str) -> float:
    """The cell ``text`` of ``column`` as a finite float, checked against the column's range
    when it is a known metric; ScoreError naming ``where`` (``FILE:LINE``) otherwise."""
    text = text.strip()
    if not text:
        raise ScoreError(f"{where}: empty {column}")
    try:
        value = float(text)
    except ValueError:
        raise ScoreError(f"{where}: {column} {text!r} is not a number") from None
    return _checked(value, text, column, where)


def _checked(value: float, text: str, column: str, where: str) -> float:
    if not math.isfinite(value):
        raise ScoreError(f"{where}: {column} {text!r} is not a finite number")
    if column in ERRORS:
        if value < 0.0:
            raise ScoreError(f"{where}: {column} {value:g} is negative")
        if value > ERROR_LIMIT:
            raise ScoreError(f"{where}: {column} {value:g} is absurd (above {ERROR_LIMIT:g}; no "
                             "evaluation gives it)")
    elif column in ("a1", "a2", "a3") and not 0.0 <= value <= 1.0:
        hint = f" (a percentage? give {column} as a fraction)" if 1.0 < value <= 100.0 else ""
        raise ScoreError(f"{where}: {column} {value:g} is outside [0, 1]{hint}")
    return value


def _other_cells(row: list[str], header: list[str], used: set[int], where: str) -> None:
    """Check the cells scoring does not use: known metrics in range, no non-finite number
    in any column (it would reach scores.json and the report as NaN)."""
    for i, cell in enumerate(row):
        if i in used or i >= len(header) or not cell.strip():
            continue
        column = header[i]
        if column in ERRORS or column in FRACTIONS:
            number(cell, column, where)
            continue
        try:
            value = float(cell)
        except ValueError:
            continue  # a text column of the user's (a note, a date): not a number
        _checked(value, cell.strip(), column, where)


def level(text: str, where: str) -> int | float:
    value = number(text, "level", where)
    # Spreadsheets and pandas often write integers as 3.0: those are the integer levels.
    return int(value) if value.is_integer() else value


def _columns(header: list[str], source: str, line: int) -> tuple[dict[str, int], bool]:
    """Map the needed column names to their indices; return it and whether ``dee`` is used."""
    index: dict[str, int] = {}
    for i, name in enumerate(header):
        key = name.strip().lower()
        if key in index:
            raise ScoreError(f"{source}:{line}: column {key!r} appears twice in the header")
        index[key] = i
    missing = [c for c in ("corruption", "level") if c not in index]
    has_metrics = "abs_rel" in index or "a1" in index
    if "dee" in index and has_metrics:
        raise ScoreError(f"{source}:{line}: header has both dee and abs_rel/a1; keep one")
    use_dee = "dee" in index
    if not use_dee:
        missing += [c for c in ("abs_rel", "a1") if c not in index]
    if missing:
        need = "corruption, level, abs_rel, a1 (or dee instead of abs_rel, a1)"
        if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
            raise ScoreError(f"{source}:{line}: columns must be separated by commas, "
                             f"not semicolons or tabs; need {need}")
        raise ScoreError(f"{source}:{line}: header lacks {', '.join(missing)}; "
                         f"the first row must name the columns: {need}")
    wanted = ("corruption", "level") + (("dee",) if use_dee else ("abs_rel", "a1"))
    return {c: index[c] for c in wanted}, use_dee


def data_rows(text: str, source: str) -> Iterator[tuple[int, str, dict[str, str], bool]]:
    """The data rows of a results CSV as ``(line, "source:line", {column: cell}, use_dee)``:
    blank and ``#`` lines skipped, the header found and checked, every number of the row
    checked (module docstring); short rows, a malformed file and a file with no header
    refused (ScoreError)."""
    reader = csv.reader(io.StringIO(text))
    columns: dict[str, int] | None = None
    header: list[str] = []
    use_dee = False
    try:
        for row in reader:
            line = reader.line_num
            if not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
                continue
            if columns is None:
                columns, use_dee = _columns(row, source, line)
                header = [c.strip().lower() for c in row]
                continue
            where = f"{source}:{line}"
            if any(i >= len(row) for i in columns.values()):
                raise ScoreError(f"{where}: only {len(row)} cells; the header names more columns")
            check_width(row, header, where)
            _other_cells(row, header, set(columns.values()), where)
            yield line, where, {c: row[i] for c, i in columns.items()}, use_dee
    except csv.Error as exc:
        raise ScoreError(f"{source}:{reader.line_num}: malformed CSV: {exc}") from None
    if columns is None:
        raise ScoreError(f"{source}: no header row; the file is empty")
