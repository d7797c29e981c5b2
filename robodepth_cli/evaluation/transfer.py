"""Synthetic against real: does a synthetic corruption rank models as the real condition does?

For each pair of a synthetic corruption and a real condition (:data:`PAIRS_FILE`, a table
users extend with their own file), every model that has results on both gives two numbers:
its DEE on the corruption (the mean over the levels its results have, as ``score``
averages them) and its DEE on the real condition (the clean row of its results on a build
of that condition's images, e.g. ``drivingstereo-c --split foggy --corruptions none``).
The agreement of the two rankings is Spearman's rank correlation ``rho`` (the Pearson
correlation of the ranks, ties given their average rank), with a percentile bootstrap
interval: models resampled with replacement, ``rho`` of each resample (resamples whose
ranks are all tied are drawn again), the ``(1 - level) / 2`` and ``(1 + level) / 2``
quantiles. The generator is seeded, so the interval is the same on every run.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..benchmarks import CLEAN, CORRUPTIONS
from ..errors import RobodepthError, os_reason
from ..files import data_dir
from .results import dee

PAIRS_FILE = data_dir("configs") / "transfer" / "synthetic-real.yaml"
MIN_MODELS = 3  # fewer models give no ranking to speak of


class TransferError(RobodepthError):
    """Results or a pairs table that cannot be compared; the message names the file."""


@dataclass(frozen=True)
class Pair:
    synthetic: str  # a corruption
    real: str  # a real condition's name, as the results are labelled


@dataclass(frozen=True)
class Transfer:
    """One pair's comparison over the models with results on both sides."""

    pair: Pair
    models: tuple[str, ...]
    synthetic: tuple[float, ...]  # DEE per model
    real: tuple[float, ...]
    rho: float
    low: float
    high: float

    def to_json(self) -> dict:
        return {"synthetic": self.pair.synthetic, "real": self.pair.real, "rho": self.rho,
                "interval": [self.low, self.high],
                "models": {m: {"synthetic_dee": s, "real_dee": r}
                           for m, s, r in zip(self.models, self.synthetic, self.real)}}


def read_pairs(path: Path = PAIRS_FILE) -> list[Pair]:
    """The pairs of a table: YAML ``pairs:``, a list of ``{synthetic: CORRUPTION, real:
    CONDITION}``."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise TransferError(f"{path}: cannot read the pairs ({os_reason(exc)})") from None
    except (UnicodeDecodeError, yaml.YAMLError):
        raise TransferError(f"{path}: not a YAML file") from None
    items = data.get("pairs") if isinstance(data, dict) else None
    if not isinstance(items, list) or not items:
        raise TransferError(f"{path}: expected 'pairs:', a list of {{synthetic: CORRUPTION, "
                            "real: CONDITION}}")
    pairs = []
    for i, item in enumerate(items, 1):
        if (not isinstance(item, dict) or set(item) != {"synthetic", "real"}
                or not all(isinstance(v, str) and v for v in item.values())):
            raise TransferError(f"{path}: pair {i}: expected {{synthetic: CORRUPTION, real: "
                                f"CONDITION}}, got {item!r}")
        if item["synthetic"] not in CORRUPTIONS:
            raise TransferError(f"{path}: pair {i}: unknown corruption {item['synthetic']!r}; "
                                f"valid: {', '.join(CORRUPTIONS)}")
        pairs.append(Pair(item["synthetic"], item["real"]))
    return pairs


def _rows(path: Path) -> list[dict]:
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        reason = os_reason(exc) if isinstance(exc, OSError) else "not a text file"
        raise TransferError(f"{path}: cannot read the results ({reason})") from None
    rows = list(csv.DictReader(io.StringIO(text)))
    if not rows or not {"corruption", "level"} <= set(rows[0]) or not (
            {"abs_rel", "a1"} <= set(rows[0]) or "dee" in rows[0]):
        raise TransferError(f"{path}: not a results CSV (columns corruption, level, abs_rel, a1 "
                            "or dee)")
    return rows


def _dee(row: dict, path: Path) -> float:
    try:
        value = float(row["dee"]) if row.get("dee") else dee(float(row["abs_rel"]), float(row["a1"]))
    except (TypeError, ValueError):
        raise TransferError(f"{path}: row {row.get('corruption')},{row.get('level')}: not a "
                            "number") from None
    if not math.isfinite(value):
        raise TransferError(f"{path}: row {row['corruption']},{row['level']}: not a finite DEE")
    return value


def synthetic_dees(path: Path) -> dict[str, float]:
    """Per corruption of a results CSV, its DEE averaged over the integer levels present."""
    levels: dict[str, list[float]] = {}
    for row in _rows(path):
        name = row["corruption"].strip()
        if name in CORRUPTIONS and float(row["level"]) == int(float(row["level"])):
            levels.setdefault(name, []).append(_dee(row, path))
    if not levels:
        raise TransferError(f"{path}: no corruption rows")
    return {n: float(np.mean(v)) for n, v in levels.items()}


def real_dee(path: Path) -> float:
    """The DEE of the clean row of results on a real condition's build."""
    for row in _rows(path):
        if row["corruption"].strip() == CLEAN:
            return _dee(row, path)
    raise TransferError(f"{path}: no clean row (the real condition's own images)")


def _ranks(x: np.ndarray) -> np.ndarray:
    """1-based ranks, ties given the average of the ranks they share."""
    order = np.argsort(x, kind="stable")
    ranks = np.empty(len(x))
    ranks[order] = np.arange(1, len(x) + 1)
    for value in np.unique(x):
        tied = x == value
        ranks[tied] = ranks[tied].mean()
    return ranks


def spearman(x, y) -> float:
    """Spearman's rank correlation of two equally long sequences; NaN when one of them
    has a single rank (every value tied)."""
    rx, ry = _ranks(np.asarray(x, float)), _ranks(np.asarray(y, float))
    dx, dy = rx - rx.mean(), ry - ry.mean()
    denom = math.sqrt(float(dx @ dx) * float(dy @ dy))
    return float(dx @ dy) / denom if denom > 0 else math.nan


def bootstrap(x, y, n: int = 2000, seed: int = 0, level: float = 0.95) -> tuple[float, float]:
    """The percentile bootstrap interval of :func:`spearman` (see the module docstring)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    rng = np.random.default_rng(seed)
    rhos = []
    for _ in range(100 * n):  # a bound: all-tied resamples are drawn again
        pick = rng.integers(0, len(x), len(x))
        rho = spearman(x[pick], y[pick])
        if not math.isnan(rho):
            rhos.append(rho)
            if len(rhos) == n:
                break
    if len(rhos) < n:
        raise TransferError("the bootstrap found too few resamples whose models differ")
    low, high = np.quantile(rhos, [(1 - level) / 2, (1 + level) / 2])
    return float(low), float(high)


def compare(synthetic: dict[str, dict[str, float]], real: dict[str, dict[str, float]],
            pairs: list[Pair], n: int = 2000, seed: int = 0) -> list[Transfer]:
    """Each pair with at least :data:`MIN_MODELS` models on both sides (``synthetic``:
    model -> corruption -> DEE; ``real``: model -> condition -> DEE), models in name order."""
    out = []
    for pair in pairs:
        models = tuple(sorted(m for m in synthetic if pair.synthetic in synthetic[m]
                              and pair.real in real.get(m, {})))
        if len(models) < MIN_MODELS:
            continue
        s = tuple(synthetic[m][pair.synthetic] for m in models)
        r = tuple(real[m][pair.real] for m in models)
        rho = spearman(s, r)
        if math.isnan(rho):
            raise TransferError(f"{pair.synthetic} against {pair.real}: every model has the same "
                                "DEE on one side; there is no ranking to compare")
        low, high = bootstrap(s, r, n, seed)
        out.append(Transfer(pair, models, s, r, rho, low, high))
    return out


def table(transfers: list[Transfer]) -> str:
    lines = [f"{'synthetic':<18}{'real':<14}{'models':>7}{'rho':>8}  95% interval"]
    for t in transfers:
        lines.append(f"{t.pair.synthetic:<18}{t.pair.real:<14}{len(t.models):>7}{t.rho:>8.3f}  "
                     f"[{t.low:.3f}, {t.high:.3f}]")
    return "\n".join(lines) + "\n"


def figure(transfers: list[Transfer]):
    """One scatter per pair: each model's DEE on the corruption against its DEE on the real
    condition, labelled, with rho and its interval in the panel's title."""
    from .plot import _figure, _freeze_layout, place_labels, pretty, style

    fig = _figure(3.4 * len(transfers), 3.4)
    axes = fig.subplots(1, len(transfers), squeeze=False)[0]
    for ax, t in zip(axes, transfers):
        for i, (s, r) in enumerate(zip(t.synthetic, t.real)):
            st = style(i)
            ax.plot([s], [r], linestyle="none", marker=st["marker"], color=st["color"])
        ax.set_xlabel(f"DEE, synthetic {pretty(t.pair.synthetic)}")
        ax.set_ylabel(f"DEE, real {pretty(t.pair.real)}")
        ax.set_title(f"Spearman rho {t.rho:.2f}, 95% [{t.low:.2f}, {t.high:.2f}]")
        ax.grid(alpha=0.3)
        ax.margins(0.25)
    renderer = _freeze_layout(fig)  # labels are placed in the final axes
    for ax, t in zip(axes, transfers):
        place_labels(ax, [(s, r, m, {"fontsize": 8, "color": style(i)["color"]}, True)
                          for i, (m, s, r) in enumerate(zip(t.models, t.synthetic, t.real))],
                     renderer=renderer)
    return fig
