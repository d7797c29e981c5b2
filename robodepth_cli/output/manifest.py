"""The manifest format: ``OUT/manifest.csv`` and the journal files, whose rows it shares
(where they lie and who writes them: :mod:`.folder`).

The manifest holds one row per output file (:data:`FIELDS`). Rows are appended and flushed
as results arrive, so a killed build keeps the record of what it finished; the last row for
a path wins. A torn last line (a build killed mid-write) is ignored when reading and cut off
before appending. A finished build rewrites the file with one row per path, sorted, so the
same build gives the same manifest whatever the worker count. A row with an ``error`` is a
job that failed; its file does not exist. Its format version is the build record's
(``robodepth-build``, :mod:`robodepth_cli.formats`): the header must be :data:`HEADER`
exactly. A journal file holds the same rows without the header.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, fields
from pathlib import Path

from ..files import write_atomic
from ..errors import RobodepthError
from ..integers import int_from_text, is_int
from .layout import MANIFEST, NEIGHBOUR_OF

SEQUENCE = "sequence="  # a params part: a corruption over time's sequence
MAP = "map="  # the last params part of a depth-aware output: its depth stamp

_SHA = re.compile(r"[0-9a-f]{64}")


class ManifestError(RobodepthError):
    """An output directory whose bookkeeping cannot be used."""


@dataclass(frozen=True)
class Params:
    """A row's ``params`` cell as its parts, parsed once here (:meth:`parse`, :meth:`text`):
    ``[neighbour_of=KEY;][FINGERPRINT][;sequence=ID][;map=STAMP]``, each part only when
    set. ``fingerprint`` is what the renderer says decides the pixels besides the seed and
    size (KITTI-S: checkpoints, style, alpha; a corruption's engine and severity size:
    ``;``-separated itself); ``neighbour_of``: the test frame a neighbour frame (--frames)
    was rendered for; ``sequence``: a corruption over time's sequence; ``depth_stamp``: the
    sha256 of a depth-aware output's depth files."""

    fingerprint: str = ""
    neighbour_of: str = ""
    sequence: str = ""
    depth_stamp: str = ""

    @classmethod
    def parse(cls, text: str) -> "Params":
        neighbour = ""
        if text.startswith(NEIGHBOUR_OF):
            neighbour, _, text = text[len(NEIGHBOUR_OF):].partition(";")
        parts = {}
        for name, tag in (("depth_stamp", MAP), ("sequence", SEQUENCE)):  # from the end
            if text.startswith(tag):
                text, parts[name] = "", text[len(tag):]
            else:
                head, sep, value = text.rpartition(";" + tag)
                if sep:
                    text, parts[name] = head, value
        return cls(text, neighbour, **parts)

    def text(self) -> str:
        return ";".join(p for p in ((NEIGHBOUR_OF + self.neighbour_of) if self.neighbour_of else "",
                                    self.fingerprint,
                                    (SEQUENCE + self.sequence) if self.sequence else "",
                                    (MAP + self.depth_stamp) if self.depth_stamp else "") if p)

    def parts(self) -> list[str]:
        """The fingerprint's own ``;``-separated parts (``engine=torch``, ``severity_size=...``)."""
        return self.fingerprint.split(";") if self.fingerprint else []


@dataclass(frozen=True)
class Row:
    output: str  # path relative to OUT, posix
    source: str  # source path relative to the root ("" if it was not found)
    variant: str
    # None: the clean image, a chain (its levels are in its name) or a dataset without
    # levels; a decimal level is a float, written in its shortest form ("2.5")
    level: int | float | None
    seed: int
    height: int
    width: int
    sha256: str  # of the file's bytes; "" for a failed job
    error: str = ""  # why the job failed; "" when it succeeded
    # Fingerprint of whatever else decided the pixels (KITTI-S: checkpoints, style image,
    # alpha, style size); "" when seed and size say it all (the corruptions).
    params: str = ""
    # The source when this output was made: size in bytes, modification time (ns since the
    # epoch) and sha256 of its bytes. A source whose size or hash changed since redoes its
    # outputs.
    source_size: int | None = None
    source_mtime: int | None = None
    source_sha256: str = ""

    @property
    def parsed(self) -> Params:
        """The ``params`` cell's parts."""
        return Params.parse(self.params)


FIELDS = tuple(f.name for f in fields(Row))
HEADER = ",".join(FIELDS) + "\n"


def _to_fields(row: Row) -> list[str]:
    return ["" if v is None else str(v) for v in (getattr(row, f) for f in FIELDS)]


def _from_fields(values: list[str]) -> Row:
    """Parse one CSV record of the :data:`FIELDS`; ``ValueError`` if it is not a complete
    row."""
    if len(values) != len(FIELDS):
        raise ValueError(f"{len(values)} fields, expected {len(FIELDS)}")
    (output, source, variant, level, seed, height, width, sha256, error, params, size, mtime,
     source_sha256) = values
    fields = dict(output=output, source=source, variant=variant, level=_level(level), seed=int(seed),
                  height=int(height), width=int(width), sha256=sha256, error=error, params=params,
                  source_size=int(size) if size else None, source_mtime=int(mtime) if mtime else None,
                  source_sha256=source_sha256)
    if not output or bool(error) == bool(_SHA.fullmatch(sha256)):
        raise ValueError("needs either a sha256 or an error")
    # Made without the dataclass's __init__, whose frozen field-by-field setting costs
    # more than the parsing (a build's manifest: 63,427 rows); the same fields and values.
    row = object.__new__(Row)
    row.__dict__.update(fields)
    return row


_LEVELS: dict[str, int | float | None] = {}  # level texts read so far: a manifest has a few


def _level(text: str) -> int | float | None:
    """A level as written: ``3`` an int, ``2.5`` a float, empty None; ``ValueError`` else."""
    if text in _LEVELS:
        return _LEVELS[text]
    if not text:
        return None
    v = float(text)
    if v != v or v in (float("inf"), float("-inf")):
        raise ValueError(f"level {text!r}")
    whole = int_from_text(text)
    value = whole if is_int(whole) else v
    if len(_LEVELS) < 1000:
        _LEVELS[text] = value
    return value


def _records(lines: list[str]):
    """The CSV records of ``lines``: split at the commas when the text has no quote (no
    field is quoted then, and ``csv`` splits exactly so, several times slower), else read
    by ``csv``."""
    if any('"' in line for line in lines):
        return csv.reader(lines)
    return ([] if line in ("\n", "\r\n", "\r") else line.rstrip("\r\n").split(",") for line in lines)


assert FIELDS == ("output", "source", "variant", "level", "seed", "height", "width", "sha256", "error", "params",
                  "source_size", "source_mtime", "source_sha256"), "_from_fields unpacks the fields in this order"


def _check_header(line: str, path: Path) -> None:
    """:class:`ManifestError` unless ``line`` is this version's :data:`HEADER`."""
    if line.rstrip("\r\n") != HEADER.strip():
        raise ManifestError(f"{path}: not a manifest of this robodepth (first line should be "
                            f"{HEADER.strip()!r}); rebuild into a new folder")


def format_rows(rows) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(_to_fields(r) for r in rows)
    return buf.getvalue()


def read_manifest_file(path: Path) -> dict[str, Row]:
    """The latest row of every output path in the manifest file at ``path`` ({} if there is
    none). A last line without its newline is a torn write and ignored."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    except (OSError, UnicodeDecodeError) as exc:
        raise ManifestError(f"{path}: cannot read the manifest ({exc})") from None
    if not text:
        return {}
    lines = text.splitlines(keepends=True)
    _check_header(lines[0], path)
    if not lines[-1].endswith("\n"):
        lines.pop()
    rows: dict[str, Row] = {}
    for n, values in enumerate(_records(lines[1:]), 2):
        try:
            row = _from_fields(values)
        except (ValueError, TypeError) as exc:
            raise ManifestError(
                f"{path}:{n}: damaged row ({exc}); to recover, delete that line (or the whole "
                f"{MANIFEST}) and rerun the build command: it makes again whatever the manifest "
                f"no longer lists") from None
        rows[row.output] = row
    return rows


class ManifestWriter:
    """Appends rows to the manifest file at ``path``, flushing after every batch."""

    def __init__(self, path: Path):
        self.path = Path(path)
        read_manifest_file(self.path)  # refuse a foreign or damaged file before touching it
        self._fh = open(self.path, "a+b")
        self._fh.seek(0)
        data = self._fh.read()
        if not data:
            self._fh.write(HEADER.encode())
        elif not data.endswith(b"\n"):
            self._fh.truncate(data.rfind(b"\n") + 1)  # drop a torn last line
        self._fh.flush()

    def append(self, rows) -> None:
        if rows:
            self._fh.write(format_rows(rows).encode("utf-8"))
            self._fh.flush()

    def close(self) -> None:
        try:
            self._fh.close()
        except OSError:
            # Only bytes of an append that already failed (disk full) can be pending here; that
            # error was reported, and a torn last line is ignored when the manifest is read.
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read_journal_file(path: Path) -> list[Row]:
    """The complete rows of one journal file; a torn last line (a worker killed in the
    middle of a write) and anything unreadable are left out: their outputs are made again."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return []
    lines = text.splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines.pop()
    rows = []
    for values in _records(lines):
        try:
            rows.append(_from_fields(values))
        except (ValueError, TypeError):
            continue
    return rows


def write_manifest_file(path: Path, rows) -> None:
    """Write the manifest file at ``path`` atomically with ``rows``, in their order."""
    write_atomic(path, (HEADER + format_rows(rows)).encode("utf-8"))
