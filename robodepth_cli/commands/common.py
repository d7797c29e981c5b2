"""Option parsing and file helpers shared by several commands."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RobodepthError, os_reason


def corruption_names(value: str, flag: str = "--corruption") -> list[str]:
    """The corruptions ``value`` selects ('all', a name or a comma list), in order."""
    from ..benchmarks import CORRUPTIONS
    from ..config import choose_names

    return list(choose_names(flag, value, CORRUPTIONS, "corruption"))


def levels(value: str, flag: str = "--level") -> list[int]:
    """The levels ``value`` selects ('all', a level or a comma list), sorted, checked by
    the same rule as a build's ``--levels``: every corruption has levels 1..5."""
    from ..benchmarks import N_LEVELS
    from ..config import choose_levels

    return list(choose_levels(flag, value, tuple(range(1, N_LEVELS + 1))))


def load_input(image: str, size: str | None) -> np.ndarray:
    """The clean image of one input file, resized (Lanczos) to ``size`` ("HxW") if given."""
    from ..imageio import load_clean, parse_size

    try:
        size_hw = parse_size(size) if size else None
    except ValueError as exc:
        raise RobodepthError(str(exc)) from None
    return load_clean(image, size_hw)


def write_png(path: Path, img: np.ndarray) -> None:
    """Write ``img`` as a PNG at ``path`` (atomically); a write error is a refusal."""
    from ..imageio import write_png as write

    try:
        write(path, img)
    except OSError as exc:
        raise RobodepthError(f"{path}: cannot write ({os_reason(exc)})") from None
