"""Option parsing and file helpers shared by several commands."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RobodepthError, os_reason


def corruption_names(value: str, flag: str = "--corruption") -> list[str]:
    """The corruptions ``value`` selects ('all', a name or a comma list), in order."""
    from ..config import choose_names
    from ..corruptions import NAMES

    return list(choose_names(flag, value, NAMES, "corruption"))


def levels(value: str, names: list[str], flag: str = "--level") -> list[int]:
    """The levels ``value`` selects ('all' or a comma list) for the corruptions ``names``."""
    from ..corruptions import REGISTRY

    most = max(REGISTRY[n].n_levels for n in names)
    if value == "all":
        return list(range(1, most + 1))
    try:
        chosen = [int(v) for v in value.split(",")]
    except ValueError:
        raise RobodepthError(f"{flag} {value!r}: expected an integer 1..{most}, a comma list, or 'all'") from None
    for lv in chosen:
        if not 1 <= lv <= most:
            raise RobodepthError(f"{flag} {lv} out of range: levels are 1..{most}")
    return chosen


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
