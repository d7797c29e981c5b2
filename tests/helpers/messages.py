"""What a command said: its one-line refusals."""

from __future__ import annotations

import re


def one_line_error(res, *parts: str, start: str = "", pattern: str | None = None,
                   stderr: bool = False) -> str:
    """A refusal as the house rules want it: exit status 2, one line ``robodepth: error:
    START...`` (on stderr alone with ``stderr``) holding each of ``parts`` and matching the
    regular expression ``pattern``, and no traceback. Returns the line."""
    text = res.stderr if stderr else res.output
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output, res.output
    assert text.count("\n") == 1 and text.startswith("robodepth: error: " + start), text
    line = text.strip()
    for part in parts:
        assert part in line, (part, line)
    if pattern is not None:
        assert re.search(pattern, line), (pattern, line)
    return line
