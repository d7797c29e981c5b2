"""A small CSV table a ``report`` flag names (``--sizes``, ``--pairs``): read once, its
fixed header checked, its data rows handed out with the place messages name."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Iterator, Sequence

from ..errors import RobodepthError, os_reason


def table_rows(flag: str, path: Path, columns: Sequence[str], error: type[RobodepthError],
               limit: tuple[int, str] | None = None) -> Iterator[tuple[str, list[str]]]:
    """The data rows of the table at ``path`` as ``("FLAG PATH:LINE", cells)``: ``#`` and
    blank lines skipped, the first row the header, which must be ``columns`` (lower case);
    ``limit``: (bytes, why a larger file is refused). Every refusal is ``error``, one line
    naming the flag and the file."""
    try:
        if limit is not None and path.stat().st_size > limit[0]:
            raise error(f"{flag} {path}: larger than {limit[0] >> 10} kB; {limit[1]}")
        text = Path(path).read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise error(f"{flag} {path}: not a UTF-8 text file") from None
    except OSError as exc:
        raise error(f"{flag} {path}: cannot read: {os_reason(exc)}") from None
    reader = csv.reader(io.StringIO(text))
    header = None
    for row in reader:
        if not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
            continue
        where = f"{flag} {path}:{reader.line_num}"
        if header is None:
            header = [c.strip().lower() for c in row]
            if header != list(columns):
                raise error(f"{where}: the header must be {','.join(columns)}")
            continue
        yield where, row
    if header is None:
        raise error(f"{flag} {path}: no header row ({','.join(columns)})")
