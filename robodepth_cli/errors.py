"""The one base class of every refusal the package makes.

Anything the user can cause (a bad flag, file, image, checkpoint, split or output
directory) is raised as a :class:`RobodepthError` subclass whose message is one line
naming the file or flag and the problem. The command line translates these, and only
these, into ``robodepth: error: <message>`` with exit status 2, in one place
(:mod:`robodepth_cli.cli`); any other exception is a bug and keeps its traceback.

It derives from ``ValueError`` so that library callers catching ``ValueError`` keep working.
"""

from __future__ import annotations


class RobodepthError(ValueError):
    """A problem with the user's input or environment; the message is one line."""


class InvalidValueError(RobodepthError):
    """A value refused by a check that does not know where the value was given (a flag, a
    configuration key, a line of a split or list file): the message says what is wrong
    with the value; a caller that knows the place catches this class and raises its own
    error naming it (``--split: ...``, ``config.yaml: size: ...``, ``split.txt:3: ...``).
    Uncaught, it is still a complete refusal."""


def os_reason(exc: OSError) -> str:
    """The readable part of an ``OSError`` ("No space left on device"), without errno noise."""
    return exc.strerror or str(exc)


def cannot_write(path, reason: OSError | str, flag: str | None = None, what: str = "") -> str:
    """The one message for an output that cannot be written:
    ``[FLAG ]PATH: cannot write[ WHAT] (REASON)``, ``what`` naming the thing when the path
    alone does not (``"the output directory"``)."""
    if isinstance(reason, OSError):
        reason = os_reason(reason)
    return f"{flag + ' ' if flag else ''}{path}: cannot write{' ' + what if what else ''} ({reason})"
