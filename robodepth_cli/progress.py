"""The one progress bar of long work (build, verify, gt, evaluate): on stderr, so stdout
stays the command's result, and only where someone watches: ``progress=False``
(``--no-progress``) hides it, and so does a stderr that is not a terminal (a log file, a
pipe, a test)."""

from __future__ import annotations

import sys


def bar(unit: str, total: int | None = None, *, progress: bool = True, **options):
    """A ``tqdm`` bar counting ``unit``; ``options`` go to tqdm (``desc``, ``smoothing``).
    tqdm is imported here, not at module level, so commands that draw no bar never load it."""
    from tqdm import tqdm

    return tqdm(total=total, unit=unit, disable=None if progress else True, file=sys.stderr,
                dynamic_ncols=True, **options)
