"""The manifest and the lock of an output directory (their names: :mod:`.layout`).

- ``OUT/manifest.csv``: one row per output file (:data:`FIELDS`). Rows are appended and
  flushed as results arrive, so a killed build keeps the record of what it finished; the
  last row for a path wins. A torn last line (a build killed mid-write) is ignored when
  reading and cut off before appending. A finished build rewrites the file with one row per
  path, sorted, so the same build gives the same manifest whatever the worker count.
  A row with an ``error`` is a job that failed; its file does not exist. Its format
  version is the build record's (``robodepth-build``, :mod:`robodepth_cli.formats`): the
  header must be :data:`HEADER` exactly.
- ``OUT/build.json``: the build record, :mod:`.record`.
- ``OUT/.robodepth.journal/``: while a build runs, each worker appends the row of every
  output to a file of its own here right after writing the output (:class:`Journal`), so a
  build stopped in the middle of an image (one image has up to 91 outputs) keeps the record
  of what it wrote. The builder moves those rows into the manifest (and removes the files)
  when it ends, even interrupted, and when the next build starts; ``verify`` reads them too.
- ``OUT/.robodepth.lock``: held (``flock``) by the running build, and removed by it when
  it ends; if the process dies, the kernel releases the lock and the next build reuses the
  file.
"""

from __future__ import annotations

import csv
import io
import os
import re
from dataclasses import dataclass, fields
from pathlib import Path

from ..files import is_temporary, write_atomic
from ..errors import RobodepthError
from ..values import int_from_text, is_int
from .layout import JOURNAL, LOCK, MANIFEST, NEIGHBOUR_OF

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
_INTS = ("seed", "height", "width")
_OPTIONAL_INTS = ("source_size", "source_mtime")


def _to_fields(row: Row) -> list[str]:
    return ["" if v is None else str(v) for v in (getattr(row, f) for f in FIELDS)]


def _from_fields(values: list[str]) -> Row:
    """Parse one CSV record of the :data:`FIELDS`; ``ValueError`` if it is not a complete
    row."""
    if len(values) != len(FIELDS):
        raise ValueError(f"{len(values)} fields, expected {len(FIELDS)}")
    d: dict = dict(zip(FIELDS, values))
    for k in _INTS:
        d[k] = int(d[k])
    for k in _OPTIONAL_INTS:
        d[k] = int(d[k]) if d[k] else None
    d["level"] = _level(d["level"])
    row = Row(**d)
    if not row.output or bool(row.error) == bool(_SHA.fullmatch(row.sha256)):
        raise ValueError("needs either a sha256 or an error")
    return row


def _level(text: str) -> int | float | None:
    """A level as written: ``3`` an int, ``2.5`` a float, empty None; ``ValueError`` else."""
    if not text:
        return None
    v = float(text)
    if v != v or v in (float("inf"), float("-inf")):
        raise ValueError(f"level {text!r}")
    whole = int_from_text(text)
    return whole if is_int(whole) else v


def _check_header(line: str, path: Path) -> None:
    """:class:`ManifestError` unless ``line`` is this version's :data:`HEADER`."""
    if line.rstrip("\r\n") != HEADER.strip():
        raise ManifestError(f"{path}: not a manifest of this robodepth (first line should be "
                            f"{HEADER.strip()!r}); rebuild into a new folder")


def format_rows(rows) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(_to_fields(r) for r in rows)
    return buf.getvalue()


def read_manifest(out: Path) -> dict[str, Row]:
    """The latest row of every output path in ``out``'s manifest ({} if there is none).
    A last line without its newline is a torn write and ignored."""
    return read_manifest_file(Path(out) / MANIFEST)


def read_manifest_file(path: Path) -> dict[str, Row]:
    """:func:`read_manifest` of the manifest file at ``path``, wherever it lies."""
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
    for n, values in enumerate(csv.reader(lines[1:]), 2):
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
    """Appends rows to ``out``'s manifest, flushing after every batch."""

    def __init__(self, out: Path):
        self.path = Path(out) / MANIFEST
        read_manifest(out)  # refuse a foreign or damaged file before touching it
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


class Journal:
    """A worker's record of the outputs it writes, one row appended right after each file is
    written, in ``OUT/.robodepth.journal/<host>-<pid>-<thread>.csv`` (no file is shared, so no
    two writers interleave, on any file system). Use as a context manager around one task;
    the file is created on the first row."""

    def __init__(self, out: Path):
        import socket
        import threading

        self.path = (Path(out) / JOURNAL /
                     f"{socket.gethostname()}-{os.getpid()}-{threading.get_ident()}.csv")
        self._fd: int | None = None

    def append(self, row: Row) -> None:
        if self._fd is None:
            self.path.parent.mkdir(exist_ok=True)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        os.write(self._fd, format_rows([row]).encode("utf-8"))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def _journal_files(out: Path) -> list[Path]:
    try:
        return sorted(p for p in (Path(out) / JOURNAL).iterdir() if p.suffix == ".csv")
    except (FileNotFoundError, NotADirectoryError):
        return []


def _journal_rows(path: Path) -> list[Row]:
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
    for values in csv.reader(lines):
        try:
            rows.append(_from_fields(values))
        except (ValueError, TypeError):
            continue
    return rows


def read_recorded(out: Path) -> dict[str, Row]:
    """:func:`read_manifest` with the rows of a journal a killed build left laid over them:
    every output recorded so far, changing nothing."""
    rows = read_manifest(out)
    for path in _journal_files(out):
        for row in _journal_rows(path):
            rows[row.output] = row
    return rows


def merge_journal(out: Path) -> list[Row]:
    """Move the journal's rows into the manifest (call with the lock held) and delete the
    journal; return the rows the manifest did not already hold."""
    files = _journal_files(out)
    if not files:
        return []
    current = read_manifest(out)
    new: dict[str, Row] = {}
    for path in files:
        for row in _journal_rows(path):
            if current.get(row.output) != row:
                new[row.output] = row
    if new:
        with ManifestWriter(out) as writer:
            writer.append(list(new.values()))
    for path in files:
        path.unlink(missing_ok=True)
    try:
        (Path(out) / JOURNAL).rmdir()
    except OSError:
        pass  # a straggling worker wrote again: the next build merges it
    return list(new.values())


def compact_manifest(out: Path, drop=frozenset()) -> None:
    """Rewrite the manifest atomically with the latest row of each path, sorted by path,
    leaving out the rows of the paths in ``drop``."""
    rows = read_manifest(out)
    write_atomic(Path(out) / MANIFEST, (HEADER + format_rows(rows[k] for k in sorted(rows)
                                                             if k not in drop)).encode("utf-8"))


class BuildLock:
    """An exclusive lock on ``OUT/.robodepth.lock`` for the duration of a ``with`` block.
    A second build into the same OUT gets :class:`ManifestError` instead of waiting.

    The file is removed when the block ends (a refused or finished build leaves none). A
    process that opened the file just before it was removed would lock an orphan inode, so
    after locking, the inode is compared with the path's and the lock taken again if they
    differ."""

    def __init__(self, out: Path):
        self.path = Path(out) / LOCK
        self._fd: int | None = None

    def __enter__(self):
        import fcntl

        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 64).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise ManifestError(f"{self.path.parent}: another build (pid {holder}) is writing here; "
                                    f"wait for it to finish or choose another --out") from None
            try:
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # the file was removed by the build that held it: lock the new one
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd
        return self

    def __exit__(self, *exc):
        try:
            os.unlink(self.path)  # while still locked: see the class docstring
        except FileNotFoundError:
            pass
        os.close(self._fd)
        self._fd = None


def lock_holder(out: Path) -> str | None:
    """The pid (as written) of the build holding ``out``'s lock, or None if none does."""
    import fcntl

    try:
        fd = os.open(Path(out) / LOCK, os.O_RDONLY)
    except FileNotFoundError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return os.read(fd, 64).decode(errors="replace").strip() or "unknown"
    finally:
        os.close(fd)
    return None


def remove_temporaries(out: Path) -> int:
    """Delete temporary files a killed build left behind (call with the lock held)."""
    n = 0
    for dirpath, _, files in os.walk(out):
        for name in files:
            if is_temporary(name):
                try:
                    os.unlink(os.path.join(dirpath, name))
                except FileNotFoundError:
                    # A cluster worker still finishing a cancelled task renamed it meanwhile.
                    continue
                n += 1
    return n


def links_leaving(out: Path) -> list[tuple[str, str]]:
    """Symlinks under ``out`` whose target lies outside it, as (path relative to ``out``,
    resolved target). A build refuses to start over any: a write or deletion through one
    would land outside OUT. Links are not followed while searching."""
    top = os.path.realpath(out)
    found, stack = [], [top]
    while stack:
        with os.scandir(stack.pop()) as entries:
            for e in entries:
                if e.is_symlink():
                    real = os.path.realpath(e.path)
                    if os.path.commonpath([top, real]) != top:
                        found.append((os.path.relpath(e.path, top), real))
                elif e.is_dir():
                    stack.append(e.path)
    return sorted(found)
