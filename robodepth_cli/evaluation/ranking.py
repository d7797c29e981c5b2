"""Rank agreement of two sequences of scores (models' errors under two conditions):
Spearman's rho (the Pearson correlation of the ranks, ties given the mean of the ranks they
span), Kendall's tau-b (concordant minus discordant pairs over the geometric mean of the
pairs untied on each side), both SciPy's, and their percentile bootstrap intervals. No file,
no flag: the callers say what the values are.
"""

from __future__ import annotations

import math

import numpy as np

LEVEL = 0.95


def _ranked(x, y) -> bool:
    """Whether both sides rank something (neither has every value tied)."""
    return len(x) > 1 and np.ptp(x) > 0 and np.ptp(y) > 0


def spearman(x, y) -> float:
    """Spearman's rho (``scipy.stats.spearmanr``); NaN when one side has every value tied
    (no ranking)."""
    from scipy.stats import spearmanr

    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    return float(spearmanr(x, y).statistic) if _ranked(x, y) else math.nan


def kendall(x, y) -> float:
    """Kendall's tau-b (``scipy.stats.kendalltau``); NaN when one side has every value tied."""
    from scipy.stats import kendalltau

    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    return float(kendalltau(x, y).statistic) if _ranked(x, y) else math.nan


def bootstrap(x, y, n: int = 2000, seed: int = 0,
              level: float = LEVEL) -> dict[str, tuple[float, float] | None]:
    """Percentile intervals (``level``) of Spearman's rho and Kendall's tau from the same
    ``n`` resamples: each draws ``len(x)`` indices with replacement from a generator seeded
    by ``seed`` (the same inputs and seed give the same intervals); a resample in which one
    side has every value tied has no ranking and is drawn again. None for both when fewer
    than ``n`` such resamples turn up in ``50 n`` draws. (``scipy.stats.bootstrap`` cannot
    draw a resample again: with a handful of models many resamples tie a side, and its
    percentile of their NaN would be NaN.)"""
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
