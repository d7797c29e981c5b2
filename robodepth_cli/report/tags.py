"""What the user says about the models of a report beyond their results: tags
(``--tag MODEL:KEY=VALUE``), sizes (``--params``, ``--flops``, ``--sizes FILE``).

Tags name the properties the group comparisons and the fine-tuning matrix read:
``base`` (the model the variants share), ``modality``, ``backbone``, ``resolution``,
``pretrain`` (as the published table's columns) and ``finetune`` (the corruption a model
was fine-tuned with, ``none`` for the baseline). Sizes are a count of parameters and FLOPs
per image, a number with an optional ``k``, ``M``, ``G`` or ``T`` suffix (``14.3M``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

from ..errors import RobodepthError


TAG_KEYS = ("base", "modality", "backbone", "resolution", "pretrain", "finetune")
SUFFIXES = {"": 1.0, "k": 1e3, "m": 1e6, "g": 1e9, "t": 1e12}
SIZES_LIMIT = 1 << 20  # bytes of a --sizes file: a table of model sizes is a few kB
SIZES_COLUMNS = ("model", "params", "flops")


def count(text: str, where: str) -> float:
    """``"14.3M"`` -> 14300000.0: a positive finite number with an optional k/M/G/T suffix
    (case-insensitive); :class:`RobodepthError` naming ``where`` otherwise."""
    t = text.strip()
    suffix = t[-1:].lower() if t[-1:].isalpha() else ""
    try:
        value = float(t[:len(t) - len(suffix)]) * SUFFIXES[suffix]
    except (ValueError, KeyError):
        raise RobodepthError(f"{where}: {text.strip()!r} is not a count (a number, optionally with "
                             "k, M, G or T: 14.3M)") from None
    if not math.isfinite(value) or value <= 0:
        raise RobodepthError(f"{where}: {text.strip()!r} must be a positive finite number")
    return value


def _split(text: str, flag: str, names: Sequence[str], at: int, form: str) -> tuple[str, str]:
    """``text`` split at ``at`` into a model of ``names`` and the rest."""
    if at <= 0 or "=" not in text:
        raise RobodepthError(f"{flag} {text!r}: expected {form}")
    model = text[:at].strip()
    if model not in names:
        raise RobodepthError(f"{flag} {text!r}: no model is named {model!r} (the names: "
                             f"{', '.join(names)})")
    return model, text[at + 1:]


def parse_tags(values: Sequence[str], names: Sequence[str]) -> dict[str, dict[str, str]]:
    """``--tag MODEL:KEY=VALUE[,KEY=VALUE...]`` (repeatable) -> model -> key -> value; a
    key given twice for one model keeps the last."""
    out: dict[str, dict[str, str]] = {}
    for text in values:
        model, rest = _split(text, "--tag", names, text.split("=", 1)[0].rfind(":"),
                             "MODEL:KEY=VALUE[,KEY=VALUE]")
        for item in rest.split(","):
            key, eq, value = item.partition("=")
            key = key.strip().lower()
            if not eq or not value.strip():
                raise RobodepthError(f"--tag {text!r}: expected KEY=VALUE, got {item.strip()!r}")
            if key not in TAG_KEYS:
                raise RobodepthError(f"--tag {text!r}: unknown key {key!r}; valid: {', '.join(TAG_KEYS)}")
            out.setdefault(model, {})[key] = value.strip()
    return out


def parse_counts(values: Sequence[str], flag: str, names: Sequence[str]) -> dict[str, float]:
    """``--params MODEL=COUNT`` or ``--flops MODEL=COUNT`` (repeatable) -> model -> count."""
    out = {}
    for text in values:
        model, rest = _split(text, flag, names, text.rfind("="), "MODEL=COUNT")
        out[model] = count(rest, f"{flag} {text!r}")
    return out


def read_sizes(path: Path, names: Sequence[str]) -> dict[str, dict[str, float]]:
    """A ``--sizes`` CSV: header ``model,params,flops`` (``#`` lines are comments), one row
    per model named as in the report (yours or the paper's), a cell empty where unknown ->
    model -> {"params": n, "flops": n} (the known ones)."""
    from .tablefile import table_rows

    out = {}
    for where, row in table_rows("--sizes", path, SIZES_COLUMNS, RobodepthError,
                                 (SIZES_LIMIT, "a table of model sizes is a few lines")):
        if len(row) != 3:
            raise RobodepthError(f"{where}: expected three cells: model,params,flops")
        model = row[0].strip()
        if model not in names:
            raise RobodepthError(f"{where}: no model of the report is named {model!r}")
        out[model] = {k: count(v, where) for k, v in zip(SIZES_COLUMNS[1:], row[1:]) if v.strip()}
    return out
