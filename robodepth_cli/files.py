"""Writing files atomically and hashing them: the file helpers every module shares.

:func:`write_atomic` names its temporary files ``.<name>.<random>.part`` in the target's
directory; :func:`is_temporary` recognises them, so a build can delete what a killed
process left behind without knowing how the name is made.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, Iterator

_TEMP_PREFIX = "."
_TEMP_SUFFIX = ".part"


def _umask() -> int:
    # mkstemp/mkdtemp create 0600/0700 entries; outputs should get the usual 0666/0777 & ~umask.
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _umask()
_FILE_MODE = 0o666 & ~_UMASK


def data_dir(name: str) -> Path:
    """The ``configs`` or ``splits`` directory: inside the package when installed from a
    wheel, at the top of the repository in a checkout (and an editable install)."""
    here = Path(__file__).resolve().parent
    installed = here / name
    return installed if installed.is_dir() else here.parent / name


def cache_dir() -> Path:
    """The user's cache of robodepth (generated splits, ground truth kept for evaluations):
    ``$ROBODEPTH_CACHE_DIR``, else ``$XDG_CACHE_HOME/robodepth``, else ``~/.cache/robodepth``."""
    if os.environ.get("ROBODEPTH_CACHE_DIR"):
        return Path(os.environ["ROBODEPTH_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "robodepth"


def write_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same directory and a
    rename, so a reader never sees a partial file. The temporary file is removed on error;
    parent directories are created as needed."""
    with atomic_output(path) as fh:
        fh.write(data)


@contextmanager
def atomic_output(path: str | os.PathLike, buffering: int = -1) -> Iterator[BinaryIO]:
    """A binary file (opened ``w+b``, so it can be read back; ``buffering`` as
    :func:`open`'s) to write ``path``'s contents into, for output too large to hold as one
    ``bytes``: it replaces ``path`` when the ``with`` block ends without error and is
    removed otherwise (:func:`is_temporary` recognises the temporary file a killed process
    leaves)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f"{_TEMP_PREFIX}{path.name}.", suffix=_TEMP_SUFFIX, dir=path.parent)
    try:
        with os.fdopen(fd, "w+b", buffering=buffering) as fh:
            os.fchmod(fh.fileno(), _FILE_MODE)
            yield fh
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


@contextmanager
def atomic_directory(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary folder beside ``path`` (named as :func:`is_temporary` recognises) to fill
    with a whole output folder: it becomes ``path`` when the ``with`` block ends without
    error, and is removed otherwise (Ctrl-C included), so ``path`` is never half-written.
    ``path`` must not exist, or be an empty folder (replaced)."""
    import shutil

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f"{_TEMP_PREFIX}{path.name}.", suffix=_TEMP_SUFFIX, dir=path.parent))
    try:
        os.chmod(tmp, 0o777 & ~_UMASK)  # mkdtemp makes it 0700
        yield tmp
        if path.is_dir():
            path.rmdir()  # empty, or this raises: nothing of the user's is lost
        os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def check_writable(path: str | os.PathLike, flag: str | None = None) -> None:
    """Refuse, before any work, an output that could not be created at ``path`` (a file, or
    a folder written under a temporary name and renamed): :class:`~.errors.RobodepthError` with
    :func:`~robodepth_cli.errors.cannot_write`'s message when a parent is not a directory
    or the nearest existing parent does not let us create an entry. Leaves nothing behind.
    """
    from .errors import RobodepthError, cannot_write, refused_entry

    path = Path(path)
    parent = path.parent
    existing = parent
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise RobodepthError(cannot_write(path, f"{existing} is not a directory", flag))
    if existing != parent:  # missing folders are made at the end: can the first be?
        # Tried, not os.access: that says nothing of a read-only file system's reason
        # (EROFS) and, for root, passes where the mkdir later fails.
        try:
            made = tempfile.mkdtemp(prefix=f"{_TEMP_PREFIX}{path.name}.", suffix=_TEMP_SUFFIX, dir=existing)
        except OSError as exc:
            raise RobodepthError(cannot_write(path, refused_entry(existing, exc), flag)) from None
        os.rmdir(made)
        return
    try:
        fd, tmp = tempfile.mkstemp(prefix=f"{_TEMP_PREFIX}{path.name}.", suffix=_TEMP_SUFFIX, dir=parent)
    except OSError as exc:
        raise RobodepthError(cannot_write(path, exc, flag)) from None
    os.close(fd)
    os.unlink(tmp)


def probe_writable(directory: str | os.PathLike) -> None:
    """Create ``directory`` (and its parents) if needed and prove that a file can be made
    in it, so that a refusal comes before long work rather than after; ``OSError``
    otherwise (word it with :func:`robodepth_cli.errors.cannot_write`)."""
    Path(directory).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryFile(dir=directory):
        pass


def is_temporary(name: str) -> bool:
    """Whether the file name ``name`` is one of :func:`write_atomic`'s temporary files."""
    return (name.startswith(_TEMP_PREFIX) and name.endswith(_TEMP_SUFFIX)
            and len(name) > len(_TEMP_PREFIX) + len(_TEMP_SUFFIX))


def sha256_bytes(data: bytes) -> str:
    """The hex sha256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike) -> str:
    """The hex sha256 of the file at ``path``, read in 1 MB chunks; ``OSError`` if it
    cannot be read."""
    with open(path, "rb") as fh:
        return sha256_stream(fh)


def sha256_stream(fh: BinaryIO) -> str:
    """The hex sha256 of what is left to read in the binary file ``fh``, in 1 MB chunks."""
    h = hashlib.sha256()
    for chunk in iter(lambda: fh.read(1 << 20), b""):
        h.update(chunk)
    return h.hexdigest()


def read_npy_header(fh) -> tuple[tuple[int, ...], bool, object]:
    """Shape, Fortran order and dtype (a ``numpy.dtype``) of the ``.npy`` stream ``fh``,
    which is left at the first byte of the data."""
    import numpy as np

    fmt = np.lib.format
    version = fmt.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = fmt.read_array_header_1_0(fh)
    else:
        shape, fortran, dtype = fmt.read_array_header_2_0(fh)
    return tuple(shape), fortran, dtype
