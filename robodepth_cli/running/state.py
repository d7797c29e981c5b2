"""The sidecar state of ``robodepth run``: the metric rows of the variants finished so far,
beside the results CSV (``results.csv`` -> ``results.csv.state.json``), rewritten
atomically after each variant. A run started again with the same settings takes those rows
instead of running the variants again; the state is removed once the CSV is written.

The settings are everything that decides a variant's numbers besides the variant itself:
the dataset, root, split and size, the seed, the engine, the model and its batches, the
evaluation setup. A state made under other settings is set aside (the run says so) and
the run starts afresh; its rows would be another model's, or another evaluation's.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import RobodepthError, cannot_write

SUFFIX = ".state.json"


def state_path(out: Path) -> Path:
    return Path(out).with_name(Path(out).name + SUFFIX)


class RunState:
    """The finished variants' rows of one run: ``{variant relpath: {"metrics": {...},
    "ratios": [...] or None}}``, floats kept exactly (JSON writes their shortest repr)."""

    def __init__(self, path: Path, settings: dict):
        self.path = Path(path)
        self.settings = settings
        self.rows: dict[str, dict] = {}
        self.note = ""  # why an existing state was not taken, for the user

    @classmethod
    def open(cls, out: Path, settings: dict) -> "RunState":
        """The state beside ``out``: its rows when it was made under ``settings``."""
        state = cls(state_path(out), json.loads(json.dumps(settings)))
        try:
            doc = json.loads(state.path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return state
        except (OSError, ValueError) as exc:
            state.note = f"{state.path}: unreadable ({exc}); starting afresh"
            return state
        if not isinstance(doc, dict) or not isinstance(doc.get("variants"), dict):
            state.note = f"{state.path}: not a run state; starting afresh"
        elif doc.get("settings") != state.settings:
            theirs = doc.get("settings") if isinstance(doc.get("settings"), dict) else {}
            differ = sorted(k for k in set(theirs) | set(state.settings)
                            if theirs.get(k) != state.settings.get(k))
            state.note = (f"{state.path}: from a run with other settings ({', '.join(differ)} "
                          f"{'differs' if len(differ) == 1 else 'differ'}); starting afresh")
        else:
            state.rows = doc["variants"]
        return state

    def check_writable(self) -> None:
        from ..files import check_writable

        check_writable(self.path, "--out")

    def get(self, relpath: str):
        """``(metrics, ratios or None)`` of a finished variant, else None."""
        row = self.rows.get(relpath)
        if row is None:
            return None
        ratios = row.get("ratios")
        return row["metrics"], None if ratios is None else np.array(ratios, dtype=np.float64)

    def add(self, relpath: str, metrics: dict, ratios) -> None:
        """Record a finished variant, atomically (a kill leaves the previous state whole)."""
        from ..files import write_atomic

        self.rows[relpath] = {"metrics": metrics,
                              "ratios": None if ratios is None else [float(r) for r in ratios]}
        doc = {"robodepth_version": __version__, "settings": self.settings, "variants": self.rows}
        try:
            write_atomic(self.path, (json.dumps(doc, indent=1) + "\n").encode("utf-8"))
        except OSError as exc:
            raise RobodepthError(cannot_write(self.path, exc)) from None

    def remove(self) -> None:
        self.path.unlink(missing_ok=True)
