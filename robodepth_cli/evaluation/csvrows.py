"""The results CSV's one owner: :class:`ResultsTable` reads, writes and checks it.

A results CSV is what ``robodepth evaluate`` and ``robodepth run`` write and ``score`` and
``report`` read: ``#`` comment lines (read by :mod:`.owndepth`), a header row naming the
columns, one row per variant. Its format version is in a sidecar, ``RESULTS.csv.json``
(:mod:`robodepth_cli.formats`), so the rows stay plain CSV for spreadsheets; a CSV without
one (results from elsewhere, typed by hand) is read by its header alone.

:meth:`ResultsTable.data_rows` finds the header, the columns scoring needs (``corruption``, ``level`` and
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
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator

from ..errors import RobodepthError, cannot_write, os_reason
from .protocols import NYU_METRICS

ERROR_LIMIT = 1e6
DATASET_COLUMNS = ("dataset", "split")  # what results are on, as robodepth evaluate writes it
# The severity size of the build (a text column on every row); absent: made with none.
SEVERITY_COLUMN = "severity_size"
SCHEMA = "robodepth-results"
FRACTIONS = ("a1", "a2", "a3", "dee")  # fractions of pixels, or DEE
ERRORS = tuple(m for m in NYU_METRICS if m not in FRACTIONS)  # non-negative, at most ERROR_LIMIT


class ScoreError(RobodepthError):
    """A results or baseline file that cannot be scored; the message is one line."""


def normalise_name(text: str) -> str:
    """A corruption cell as a name: ``Motion-Blur `` -> ``motion_blur``."""
    return text.strip().lower().replace("-", "_").replace(" ", "_")


def check_width(row, header, where: str) -> None:
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


def _rows(text: str) -> tuple[list[tuple[int, tuple[str, ...]]], tuple[int, str] | None]:
    """The CSV rows of ``text`` that are neither blank nor ``#`` comments, with their line
    numbers, and the first malformed line's (number, reason) if any (the rows stop there)."""
    reader = csv.reader(io.StringIO(text))
    rows: list[tuple[int, tuple[str, ...]]] = []
    try:
        for row in reader:
            if any(c.strip() for c in row) and not row[0].lstrip().startswith("#"):
                rows.append((reader.line_num, tuple(row)))
    except csv.Error as exc:
        return rows, (reader.line_num, str(exc))
    return rows, None


def sidecar(path: str | Path) -> Path:
    """Where the format version of the results CSV ``path`` is kept: ``path`` + ``.json``."""
    return Path(f"{path}.json")


@dataclass(frozen=True)
class ResultsTable:
    """A results CSV: its ``#`` comment lines above the header, its header and data rows
    (cells as written), each with its line number; ``source`` names it in every message.
    Made by :meth:`read` or :meth:`parse` from a file, or by :meth:`of` from values, and
    written by :meth:`write`: the text round-trips byte for byte."""

    source: str
    rows: tuple[tuple[int, tuple[str, ...]], ...]  # header first; (line, cells)
    comments: tuple[str, ...] = ()
    malformed: tuple[int, str] | None = None  # a line the CSV reader refused; rows stop there
    sha256: str = ""  # of the text read (its UTF-8 bytes, without a byte-order mark)

    # ----------------------------------------------------------------------- making

    @classmethod
    def parse(cls, text: str, source: str) -> "ResultsTable":
        from ..files import sha256_bytes

        rows, malformed = _rows(text)
        above = text.splitlines()[: rows[0][0] - 1] if rows else text.splitlines()
        return cls(source, tuple(rows), tuple(ln for ln in above if ln.startswith("#")), malformed,
                   sha256_bytes(text.encode()))

    @classmethod
    def read(cls, path: str | Path) -> "ResultsTable":
        """The results CSV at ``path``; I/O and decoding problems, and a sidecar of another
        format version, are a ScoreError naming the file."""
        from ..formats import check

        side = sidecar(path)
        if side.is_file():
            try:
                doc = json.loads(side.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, ValueError) as exc:
                raise ScoreError(f"{side}: not a results CSV's format record ({exc})") from None
            check(doc if isinstance(doc, dict) else {}, SCHEMA, str(path), "evaluate again")
        try:
            text = Path(path).read_bytes().decode("utf-8-sig")
        except UnicodeDecodeError:
            raise ScoreError(f"{path}: not a UTF-8 text file") from None
        except IsADirectoryError:
            raise ScoreError(f"{path}: is a directory, not a results CSV") from None
        except OSError as exc:
            raise ScoreError(f"{path}: cannot read: {os_reason(exc)}") from None
        return cls.parse(text, str(path))

    @classmethod
    def of(cls, header, rows, comments=(), source: str = "") -> "ResultsTable":
        """A table of ``header`` and ``rows`` (each a sequence of cells, as text)."""
        numbered = [(i + 1, tuple(map(str, r))) for i, r in enumerate([header, *rows])]
        return cls(source, tuple(numbered), tuple(comments))

    def with_column(self, name: str, value: str) -> "ResultsTable":
        """This table with the column ``name`` holding ``value`` on every row, last."""
        if not self.rows:
            return self
        (line, head), *data = self.rows
        return replace(self, rows=((line, (*head, name)), *((n, (*r, value)) for n, r in data)))

    # ----------------------------------------------------------------------- writing

    def text(self) -> str:
        """The CSV: the comment lines, then the rows as Python's csv writer writes them."""
        buf = io.StringIO()
        for line in self.comments:
            buf.write(line + "\n")
        csv.writer(buf, lineterminator="\n").writerows(r for _, r in self.rows)
        return buf.getvalue()

    def write(self, path: str | Path) -> None:
        """Write the CSV and its format sidecar, each atomically (the sidecar first, so a
        CSV is never read against an older one); EvaluationError if it cannot be written."""
        from ..files import write_atomic
        from ..formats import stamp
        from .protocols import EvaluationError

        try:
            write_atomic(sidecar(path), (json.dumps(stamp(SCHEMA), indent=2) + "\n").encode())
            write_atomic(path, self.text().encode("utf-8"))
        except OSError as exc:
            raise EvaluationError(cannot_write(path, exc)) from None

    # ----------------------------------------------------------------------- reading

    @property
    def header(self) -> tuple[str, ...]:
        """The header's column names, lower case, stripped; () without a header."""
        return tuple(c.strip().lower() for c in self.rows[0][1]) if self.rows else ()

    def column(self, name: str) -> list[str] | None:
        """Every data row's cell of column ``name`` ("" where a row is short), or None
        without that column."""
        if name not in self.header:
            return None
        i = self.header.index(name)
        return [r[i] if i < len(r) else "" for _, r in self.rows[1:]]

    def records(self) -> list[dict[str, str | None]]:
        """Each data row as ``{column: cell}`` (None where the row is short; cells beyond
        the header left out)."""
        head = self.header
        return [{k: (r[i] if i < len(r) else None) for i, k in enumerate(head)} for _, r in self.rows[1:]]

    def dataset(self) -> tuple[str, str] | None:
        """The (dataset, split) the ``dataset`` and ``split`` columns name (lower case;
        split "" when absent or empty), or None without a ``dataset`` column (results from
        elsewhere). ScoreError when its rows name more than one, or a row has more cells
        than the header (:func:`check_width`)."""
        if "dataset" not in self.header:
            return None
        for line, row in self.rows[1:]:
            check_width(row, self.header, f"{self.source}:{line}")
        cells = [self.column(c) or [""] * (len(self.rows) - 1) for c in DATASET_COLUMNS]
        found = {(d.strip().lower(), s.strip().lower()) for d, s in zip(*cells)}
        if len(found) > 1:
            names = sorted(f"{d}:{s}" if s else d for d, s in found)
            raise ScoreError(f"{self.source}: its rows are on different datasets ({', '.join(names)}); "
                             "one results file holds one dataset's results")
        key = found.pop() if found else ("", "")
        return key if key[0] else None

    def corruption_names(self) -> list[str]:
        """The normalised corruption cells; [] without a ``corruption`` column."""
        if "corruption" not in self.header:
            return []
        i = self.header.index("corruption")
        return [normalise_name(r[i]) for _, r in self.rows[1:] if i < len(r)]

    def severity_size(self) -> str:
        """The severity size the results were made at: the first row's
        :data:`SEVERITY_COLUMN`, else ``none``."""
        cells = self.column(SEVERITY_COLUMN)
        return cells[0].strip() if cells and cells[0].strip() else "none"

    def data_rows(self) -> Iterator[tuple[int, str, dict[str, str], bool]]:
        """The data rows as ``(line, "source:line", {column: cell}, use_dee)``: the header
        checked, every number of the row checked (module docstring); short rows, a malformed
        file and a file with no header refused (ScoreError)."""
        source = self.source
        if self.rows:
            (line, head), *data = self.rows
            columns, use_dee = _columns(list(head), source, line)
            header = self.header
            for line, row in data:
                where = f"{source}:{line}"
                if any(i >= len(row) for i in columns.values()):
                    raise ScoreError(f"{where}: only {len(row)} cells; the header names more columns")
                check_width(row, header, where)
                _other_cells(list(row), list(header), set(columns.values()), where)
                yield line, where, {c: row[i] for c, i in columns.items()}, use_dee
        if self.malformed:
            raise ScoreError(f"{source}:{self.malformed[0]}: malformed CSV: {self.malformed[1]}")
        if not self.rows:
            raise ScoreError(f"{source}: no header row; the file is empty")
