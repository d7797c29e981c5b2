"""Rank agreement of two sequences of scores (models' errors under two conditions):
Spearman's rho (the Pearson correlation of the ranks, ties given the mean of the ranks they
span), Kendall's tau-b (concordant minus discordant pairs over the geometric mean of the
pairs untied on each side) and their percentile bootstrap intervals. Pure numpy; no file,
no flag: the callers say what the values are.
"""

from __future__ import annotations

import math

import numpy as np

LEVEL = 0.95


def ranks(values) -> np.ndarray:
    """1-based ranks; tied values share the mean of the ranks they span."""
    x = np.asarray(values, dtype=np.float64)
    order = np.argsort(x, kind="stable")
    out = np.empty(len(x))
    out[order] = np.arange(1, len(x) + 1)
    for v in np.unique(x):
        tied = x == v
        out[tied] = out[tied].mean()
    return out


def spearman(x, y) -> float:
    """Spearman's rho; NaN when one side has every value tied (no ranking)."""
    rx, ry = ranks(x), ranks(y)
    dx, dy = rx - rx.mean(), ry - ry.mean()
    denom = math.sqrt(float(dx @ dx) * float(dy @ dy))
    return float(dx @ dy) / denom if denom > 0 else math.nan


def kendall(x, y) -> float:
    """Kendall's tau-b; NaN when one side has every value tied."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    i, j = np.triu_indices(len(x), k=1)
    sx, sy = np.sign(x[i] - x[j]), np.sign(y[i] - y[j])
    denom = math.sqrt(float(np.count_nonzero(sx)) * float(np.count_nonzero(sy)))
    return float(np.sum(sx * sy)) / denom if denom > 0 else math.nan


def bootstrap(x, y, n: int = 2000, seed: int = 0,
              level: float = LEVEL) -> dict[str, tuple[float, float] | None]:
    """Percentile intervals (``level``) of Spearman's rho and Kendall's tau from the same
    ``n`` resamples: each draws ``len(x)`` indices with replacement from a generator seeded
    by ``seed`` (the same inputs and seed give the same intervals); a resample in which one
    side has every value tied has no ranking and is drawn again. None for both when fewer
    than ``n`` such resamples turn up in ``50 n`` draws."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    rng = np.random.default_rng(seed)
    rhos, taus = [], []
    for _ in range(50 * n):
        pick = rng.integers(0, len(x), len(x))
        rho = spearman(x[pick], y[pick])
        if math.isnan(rho):
            continue
        rhos.append(rho)
        taus.append(kendall(x[pick], y[pick]))
        if len(rhos) == n:
            break
    if len(rhos) < n:
        return {"spearman": None, "kendall": None}
    q = [(1 - level) / 2, (1 + level) / 2]
    return {"spearman": tuple(float(v) for v in np.quantile(rhos, q)),
            "kendall": tuple(float(v) for v in np.quantile(taus, q))}
