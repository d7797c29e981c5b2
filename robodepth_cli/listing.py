"""Text rendered from the registry: the `robodepth list` table and the table of docs/corruptions.md."""

from __future__ import annotations

import numpy as np

from .corruptions import REGISTRY


def _param_text(v) -> str:
    if isinstance(v, (tuple, list)) and len(v) > 3:
        # A long factor set, e.g. zoom_blur's: first..last, step, count.
        step = v[1] - v[0]
        return f"{_param_text(v[0])}..{_param_text(v[-1])} step {_param_text(step)} ({len(v)})"
    if isinstance(v, (tuple, list)):
        return "(" + ", ".join(_param_text(u) for u in v) + ")"
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.4g}"
    return str(v)


def _level_text(c, level: int) -> str:
    return ", ".join(_param_text(v) for v in c.params(level).values())


def corruption_table(markdown: bool = False, names=None) -> str:
    """Every corruption (or those ``names``) with its category and the parameters of each
    level."""
    head = ["#", "name", "category", "parameters", "level 1", "level 2", "level 3", "level 4", "level 5"]
    rows = [[str(i), c.name, c.category + (", needs depth" if c.needs_depth else ""), ", ".join(c.fields)]
            + [_level_text(c, lv) if lv <= c.n_levels else "" for lv in range(1, 6)]
            for i, c in enumerate(REGISTRY.values(), 1) if names is None or c.name in names]
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines)
    widths = [max(len(r[i]) for r in [head] + rows) for i in range(len(head))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(r, widths)).rstrip()
                     for r in [head] + rows)
