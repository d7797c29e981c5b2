"""A build's output directory, OUT, as one object (:class:`OutputFolder`): its lock,
journal, manifest and record. The names are :mod:`.layout`'s, the formats those of
:mod:`.manifest` and :mod:`.record`.

- ``OUT/manifest.csv``: one row per output file, appended as results arrive and rewritten
  sorted when the build ends (:meth:`OutputFolder.compact`).
- ``OUT/build.json``: the build record, written when the build starts and when it ends.
- ``OUT/.robodepth.journal/``: while a build runs, each worker appends the row of every
  output to a file of its own here right after writing the output (:class:`Journal`), so a
  build stopped in the middle of an image (one image has up to 91 outputs) keeps the record
  of what it wrote. The builder moves those rows into the manifest (and removes the files)
  when it ends, even interrupted, and when the next build starts; ``verify`` reads them too.
- ``OUT/.robodepth.lock``: held (``flock``) by the running build, and removed by it when
  it ends; if the process dies, the kernel releases the lock and the next build reuses the
  file.

Reading (:meth:`~OutputFolder.rows`, :meth:`~OutputFolder.recorded`,
:meth:`~OutputFolder.record`, :meth:`~OutputFolder.lock_holder`) needs no lock; every
other method is for the build that holds it (:meth:`~OutputFolder.lock`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from ..errors import RobodepthError, cannot_write
from ..files import is_temporary, probe_writable
from .layout import JOURNAL, LOCK, MANIFEST, RECORD
from .manifest import (ManifestError, ManifestWriter, Row, format_rows, read_journal_file,
                       read_manifest_file, write_manifest_file)
from .record import BuildRecord, read_record_file, write_record_file


class OutputDirError(RobodepthError):
    """An output directory this build must not write into."""


@dataclass(frozen=True)
class OutputFolder:
    """OUT, named as the user typed it (messages name it so). Small and picklable: a
    worker receives it with its task."""

    path: Path

    def __post_init__(self):
        object.__setattr__(self, "path", Path(self.path))

    @property
    def manifest(self) -> Path:
        return self.path / MANIFEST

    @property
    def record_file(self) -> Path:
        return self.path / RECORD

    # --------------------------------------------------------------------- reading

    def rows(self) -> dict[str, Row]:
        """The latest manifest row of every output path ({} without a manifest)."""
        return read_manifest_file(self.manifest)

    def recorded(self) -> dict[str, Row]:
        """:meth:`rows` with the rows of a journal a killed build left laid over them:
        every output recorded so far, changing nothing."""
        rows = self.rows()
        for path in self._journal_files():
            for row in read_journal_file(path):
                rows[row.output] = row
        return rows

    def record(self) -> BuildRecord | None:
        """The build record (None when there is none)."""
        return read_record_file(self.record_file)

    def lock_holder(self) -> str | None:
        """The pid (as written) of the build holding the lock, or None if none does."""
        import fcntl

        try:
            fd = os.open(self.path / LOCK, os.O_RDONLY)
        except FileNotFoundError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return os.read(fd, 64).decode(errors="replace").strip() or "unknown"
        finally:
            os.close(fd)
        return None

    # --------------------------------------------------------------------- the build's

    def prepare(self) -> None:
        """Create the folder if needed and prove it writable; :class:`OutputDirError`
        otherwise."""
        if self.path.exists() and not self.path.is_dir():
            raise OutputDirError(f"{self.path}: exists and is not a directory")
        try:
            probe_writable(self.path)
        except OSError as exc:
            raise OutputDirError(cannot_write(self.path, exc, what="the output directory")) from None

    def lock(self) -> "BuildLock":
        """The build's lock, for a ``with`` block; a second build gets :class:`ManifestError`."""
        return BuildLock(self.path / LOCK)

    def claim(self) -> None:
        """Make the locked folder safe to write into: refuse symlinks that lead outside it
        (a write or deletion through one would land elsewhere), delete the temporary files a
        killed build left behind and record what it wrote (:meth:`merge_journal`)."""
        leaving = self.links_leaving()
        if leaving:
            link, target = leaving[0]
            raise OutputDirError(f"{self.path / link}: a symlink to {target}, outside {self.path}; "
                                 f"refused (a build writes only inside its output directory)")
        self.remove_temporaries()
        try:
            self.merge_journal()  # what a killed build wrote is recorded, so kept
        except OSError as exc:
            raise OutputDirError(cannot_write(self.manifest, exc)) from None

    def writer(self) -> ManifestWriter:
        """Appends rows to the manifest."""
        return ManifestWriter(self.manifest)

    def journal(self) -> "Journal":
        """A worker's journal, for a ``with`` block around one task."""
        return Journal(self.path / JOURNAL)

    def write_record(self, record: BuildRecord) -> None:
        write_record_file(self.record_file, record)

    def merge_journal(self) -> list[Row]:
        """Move the journal's rows into the manifest and delete the journal; return the rows
        the manifest did not already hold."""
        files = self._journal_files()
        if not files:
            return []
        current = self.rows()
        new: dict[str, Row] = {}
        for path in files:
            for row in read_journal_file(path):
                if current.get(row.output) != row:
                    new[row.output] = row
        if new:
            with self.writer() as writer:
                writer.append(list(new.values()))
        for path in files:
            path.unlink(missing_ok=True)
        try:
            (self.path / JOURNAL).rmdir()
        except OSError:
            pass  # a straggling worker wrote again: the next build merges it
        return list(new.values())

    def compact(self, drop=frozenset()) -> None:
        """Rewrite the manifest atomically with the latest row of each path, sorted by path,
        leaving out the rows of the paths in ``drop``."""
        rows = self.rows()
        write_manifest_file(self.manifest, [rows[k] for k in sorted(rows) if k not in drop])

    def remove_temporaries(self) -> int:
        """Delete temporary files a killed build left behind."""
        n = 0
        for dirpath, _, files in os.walk(self.path):
            for name in files:
                if is_temporary(name):
                    try:
                        os.unlink(os.path.join(dirpath, name))
                    except FileNotFoundError:
                        # A cluster worker still finishing a cancelled task renamed it meanwhile.
                        continue
                    n += 1
        return n

    def links_leaving(self) -> list[tuple[str, str]]:
        """Symlinks in the folder whose target lies outside it, as (path relative to it,
        resolved target). Links are not followed while searching."""
        top = os.path.realpath(self.path)
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

    def _journal_files(self) -> list[Path]:
        try:
            return sorted(p for p in (self.path / JOURNAL).iterdir() if p.suffix == ".csv")
        except (FileNotFoundError, NotADirectoryError):
            return []


class Journal:
    """A worker's record of the outputs it writes, one row appended right after each file is
    written, in ``<journal dir>/<host>-<pid>-<thread>.csv`` (no file is shared, so no two
    writers interleave, on any file system). Use as a context manager around one task; the
    file is created on the first row."""

    def __init__(self, directory: Path):
        import socket
        import threading

        self.path = Path(directory) / f"{socket.gethostname()}-{os.getpid()}-{threading.get_ident()}.csv"
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


class BuildLock:
    """An exclusive lock on the lock file ``path`` for the duration of a ``with`` block.
    A second build into the same OUT gets :class:`ManifestError` instead of waiting.

    The file is removed when the block ends (a refused or finished build leaves none). A
    process that opened the file just before it was removed would lock an orphan inode, so
    after locking, the inode is compared with the path's and the lock taken again if they
    differ."""

    def __init__(self, path: Path):
        self.path = Path(path)
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
