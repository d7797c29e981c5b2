"""Integers as options arrive: a flag's value is text ("8"), a configuration file's is
already a YAML number. One reading for every check (``--seed``, ``--jobs``, ``--limit``,
``--levels``, ``--style-size``), so that ``8``, ``"8"`` and ``" 8 "`` mean the same
everywhere and ``True`` never passes for 1."""

from __future__ import annotations


def is_int(value) -> bool:
    """Whether ``value`` is an integer (a ``bool`` is not)."""
    return isinstance(value, int) and not isinstance(value, bool)


def int_from_text(value, *, negative: bool = True):
    """``value`` as an ``int`` when it is the text of one (surrounding blanks allowed; a
    leading ``-`` only with ``negative``), else ``value`` unchanged for the caller's check
    to refuse with the value as given."""
    if isinstance(value, str):
        digits = value.strip()
        if negative and digits.startswith("-"):
            digits = digits[1:]
        # isdecimal, not isdigit: int() refuses "²", which isdigit accepts.
        if digits.isdecimal():
            return int(value)
    return value
