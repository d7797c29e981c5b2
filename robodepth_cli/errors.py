"""The one base class of every refusal the package makes.

Anything the user can cause (a bad flag, file, image, checkpoint, split or output
directory) is raised as a :class:`RobodepthError` subclass whose message is one line
naming the file or flag and the problem. The command line translates these, and only
these, into ``robodepth: error: <message>`` with exit status 2, in one place
(:mod:`robodepth_cli.cli`); any other exception is a bug and keeps its traceback.

It derives from ``ValueError`` so that library callers catching ``ValueError`` keep working.
"""

from __future__ import annotations

import errno
import os


class RobodepthError(ValueError):
    """A problem with the user's input or environment; the message is one line.

    ``where`` is the file, ``FILE:LINE`` or flag the problem is about, once it is known:
    a check that does not know it raises the problem alone, and the caller that does says
    it once, ``raise exc.at("--flag") from None``, instead of a new error of its own."""

    where: str = ""

    def at(self, where) -> "RobodepthError":
        """This refusal, about ``where``: its message becomes ``WHERE: MESSAGE``; unchanged
        when it already names its place. (The place goes into ``args`` too, so that the
        message survives a worker process's pickling.)"""
        if not self.where:
            self.where = str(where)
            self.args = (f"{where}: {self.args[0]}" if self.args else self.where, *self.args[1:])
        return self


class InvalidValueError(RobodepthError):
    """A value refused by a check that does not know where the value was given (a flag, a
    configuration key, a line of a split or list file): the message says what is wrong
    with the value; a caller that knows the place catches this class and names it with
    :meth:`RobodepthError.at` (``--split: ...``, ``config.yaml: size: ...``,
    ``split.txt:3: ...``). Uncaught, it is still a complete refusal."""


def os_reason(exc: OSError) -> str:
    """The readable part of an ``OSError`` ("No space left on device"), without errno noise."""
    return exc.strerror or str(exc)


def refused_entry(directory, exc: OSError) -> str:
    """Why an entry could not be made in ``directory``: "No such file or directory" from a
    folder that exists (/proc, /sys refuse new entries so) would read as if it did not."""
    if exc.errno == errno.ENOENT and os.path.isdir(directory):
        return f"{directory} exists but takes no new files or folders: {os_reason(exc)}"
    return f"{directory}: {os_reason(exc)}"


def _file_above(path) -> str | None:
    """The nearest existing entry above ``path`` when it is not a directory (a file where a
    folder of the path should be: what EEXIST or ENOTDIR from making the path means), else
    None. The one wording of this refusal, as :func:`~robodepth_cli.files.check_writable`
    gives it."""
    above = os.path.dirname(str(path))
    while above and not os.path.lexists(above) and above != os.path.dirname(above):
        above = os.path.dirname(above)
    return above if above and os.path.lexists(above) and not os.path.isdir(above) else None


def _nearest_refusing(path) -> str | None:
    """The nearest existing folder above ``path`` when it refuses a new entry with ENOENT
    (tried: a temporary folder made and removed), else None."""
    import tempfile

    folder = os.path.dirname(os.path.abspath(path))
    while not os.path.exists(folder) and folder != os.path.dirname(folder):
        folder = os.path.dirname(folder)
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".robodepth-probe.", dir=folder))
    except FileNotFoundError:
        return folder
    except OSError:
        return None
    return None


def failure_reason(exc: BaseException) -> str:
    """An image's failure as its record and messages word it: a :class:`RobodepthError`'s
    own message (it names the problem; its class says nothing more to a user), anything
    else (a bug, a library's error) with its class name: ``ValueError: ...``."""
    return str(exc) if isinstance(exc, RobodepthError) else f"{type(exc).__name__}: {exc}"


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``"1 variant"``, ``"2 variants"``: ``n`` and ``noun``, in the plural unless n is 1."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def cannot_write(path, reason: OSError | str, flag: str | None = None, what: str = "") -> str:
    """The one message for an output that cannot be written:
    ``[FLAG ]PATH: cannot write[ WHAT] (REASON)``, ``what`` naming the thing when the path
    alone does not (``"the output directory"``)."""
    if isinstance(reason, OSError):
        blocking = _file_above(path) if reason.errno in (errno.EEXIST, errno.ENOTDIR) else None
        folder = _nearest_refusing(path) if reason.errno == errno.ENOENT else None
        reason = (f"{blocking} is not a directory" if blocking else
                  refused_entry(folder, reason) if folder else os_reason(reason))
    return f"{flag + ' ' if flag else ''}{path}: cannot write{' ' + what if what else ''} ({reason})"


# Set by the command line's SIGINT and SIGTERM handlers (cli.py) when they raise
# KeyboardInterrupt, cleared when a command starts: an interrupt is under way.
_INTERRUPT_PENDING: list[bool] = []


def note_interrupt(pending: bool = True) -> None:
    """Record (or, with ``pending=False``, forget) that Ctrl-C or SIGTERM is stopping the
    command."""
    _INTERRUPT_PENDING[:] = [True] if pending else []


def is_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` is Ctrl-C or SIGTERM stopping the command rather than a failure of
    the work at hand: a KeyboardInterrupt; an exception whose ``__cause__`` or
    ``__context__`` chain holds one (a KeyboardInterrupt raised by the signal handler just
    as a compiled kernel returns, numba's dispatcher among them, reaches the caller as
    ``SystemError: ... returned a result with an exception set``); or any exception while
    an interrupt is pending (:func:`note_interrupt`), whatever became of the
    KeyboardInterrupt on its way."""
    if _INTERRUPT_PENDING:
        return True
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def reraise_interrupt(exc: BaseException) -> None:
    """Raise KeyboardInterrupt (chained to ``exc``) when ``exc`` is an interrupt
    (:func:`is_interrupt`): what a handler that records an image's or a job's failure calls
    first, so that a stop is never recorded as a failure."""
    if is_interrupt(exc):
        raise KeyboardInterrupt from exc
