"""Synthetic against real: does a synthetic corruption rank models as the real condition does?

A pair (:data:`PAIRS`, extended by ``report --pairs FILE``) names a synthetic corruption on
a dataset and a real condition (a dataset and split taken in it). Each model with results
on both sides gives its error (DEE or AbsRel) on the corruption, averaged over its levels,
and on the real condition's clean row; the two rankings are compared by Spearman's rho and
Kendall's tau-b, with a percentile bootstrap over the models seeded by ``seed``
(docs/report.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from ..benchmark_facts import CORRUPTIONS
from ..errors import RobodepthError
from ..evaluation.csvrows import normalise_name
from ..evaluation.ranking import LEVEL, bootstrap, kendall, spearman
from .tablefile import table_rows

PAIRS = Path(__file__).resolve().parent / "pairs.csv"
MIN_MODELS = 3  # two models have one pair to order: no ranking to speak of
METRICS = {"dee": "DEE", "abs_rel": "AbsRel"}


def parse_key(text: str) -> tuple[str, str]:
    """``drivingstereo-c:foggy`` -> ``("drivingstereo-c", "foggy")``; no split -> ``""``."""
    dataset, _, split = text.strip().partition(":")
    return dataset.strip().lower(), split.strip().lower()


def key_text(key: tuple[str, str]) -> str:
    return f"{key[0]}:{key[1]}" if key[1] else key[0]


@dataclass(frozen=True)
class Pair:
    synthetic: tuple[str, str]  # (dataset, split) of the corrupted results
    corruption: str
    real: tuple[str, str]  # (dataset, split) of the real condition's clean results

    @property
    def label(self) -> str:
        return f"{self.corruption} ({key_text(self.synthetic)}) : {key_text(self.real)}"


def read_pairs(paths: Sequence[Path]) -> list[Pair]:
    """The pairs of every table in ``paths``, in order, duplicates once. A table is a CSV
    with the columns ``synthetic,corruption,real`` (``#`` lines are comments)."""
    pairs: dict[Pair, None] = {}
    for path in paths:
        for where, row in table_rows("--pairs", Path(path), ("synthetic", "corruption", "real"), RobodepthError):
            if len(row) != 3 or not all(c.strip() for c in row):
                raise RobodepthError(f"{where}: expected three cells: DATASET[:SPLIT],CORRUPTION,"
                                     "DATASET[:SPLIT]")
            corruption = normalise_name(row[1])
            if corruption not in CORRUPTIONS:
                raise RobodepthError(f"{where}: unknown corruption {row[1].strip()!r}; valid: "
                                     f"{', '.join(CORRUPTIONS)}")
            pairs[Pair(parse_key(row[0]), corruption, parse_key(row[2]))] = None
    return list(pairs)


# --------------------------------------------------------------------------- comparisons

@dataclass(frozen=True)
class Comparison:
    """One pair over the models with results on both of its sides."""

    pair: Pair
    metric: str  # dee or abs_rel
    models: tuple[str, ...]
    synthetic: tuple[float, ...]  # per model
    real: tuple[float, ...]
    spearman: float | None  # None: fewer than MIN_MODELS models, or no ranking on a side
    kendall: float | None
    spearman_ci: tuple[float, float] | None
    kendall_ci: tuple[float, float] | None
    note: str = ""  # why there is no correlation

    def to_json(self, n_boot: int, seed: int) -> dict:
        return {"synthetic": {"dataset": self.pair.synthetic[0], "split": self.pair.synthetic[1] or None,
                              "corruption": self.pair.corruption},
                "real": {"dataset": self.pair.real[0], "split": self.pair.real[1] or None},
                "metric": self.metric, "models": {
                    m: {"synthetic": s, "real": r}
                    for m, s, r in zip(self.models, self.synthetic, self.real)},
                "spearman": self.spearman, "kendall": self.kendall,
                "interval": {"level": LEVEL, "resamples": n_boot, "seed": seed, "over": "models",
                             "spearman": list(self.spearman_ci) if self.spearman_ci else None,
                             "kendall": list(self.kendall_ci) if self.kendall_ci else None},
                **({"note": self.note} if self.note else {})}


Lookup = Callable[[str, tuple[str, str], "str | None"], "float | None"]


def compare(models: Sequence[str], pairs: Sequence[Pair], value: Lookup, metric: str = "dee",
            n_boot: int = 2000, seed: int = 0) -> list[Comparison]:
    """Each pair that at least one model has results on both sides of, models in the order
    given. ``value(model, (dataset, split), corruption)`` is the model's error there (the
    corruption's level mean, or with corruption None the clean row), None where it has none."""
    out = []
    for pair in pairs:
        both = []
        for m in models:
            s, r = value(m, pair.synthetic, pair.corruption), value(m, pair.real, None)
            if s is not None and r is not None:
                both.append((m, s, r))
        if not both:
            continue
        names, xs, ys = (tuple(v) for v in zip(*both))
        rho = tau = None
        cis: dict = {"spearman": None, "kendall": None}
        note = ""
        if len(both) < MIN_MODELS:
            note = f"{len(both)} model{'s' if len(both) > 1 else ''} with both; a ranking needs {MIN_MODELS}"
        elif math.isnan(rho := spearman(xs, ys)):
            rho = None
            note = "every model has the same error on one side: no ranking to compare"
        else:
            tau = kendall(xs, ys)
            cis = bootstrap(xs, ys, n_boot, seed)
        out.append(Comparison(pair, metric, names, xs, ys, rho, tau, cis["spearman"],
                              cis["kendall"], note))
    return out


# --------------------------------------------------------------------------- tables

def tables(comparisons: Sequence[Comparison]) -> list:
    """The agreement per pair (rho and tau with their intervals), then each model's two
    errors per pair (what the scatter shows)."""
    from .inputs import Row
    from .tables import HIGH, LOW, Column, Table

    metric = METRICS[comparisons[0].metric]
    cols = [Column("n", "models", "", HIGH, 0)]
    for stat, sym in (("spearman", "ρ"), ("kendall", "τ")):
        group = "Spearman" if stat == "spearman" else "Kendall (tau-b)"
        cols += [Column(stat, sym, group, HIGH, 2), Column(f"{stat} low", f"{LEVEL:.0%} low", group, HIGH, 2),
                 Column(f"{stat} high", f"{LEVEL:.0%} high", group, HIGH, 2)]
    values = []
    for c in comparisons:
        v = {"n": len(c.models), "spearman": c.spearman, "kendall": c.kendall}
        for stat, ci in (("spearman", c.spearman_ci), ("kendall", c.kendall_ci)):
            v[f"{stat} low"], v[f"{stat} high"] = ci if ci else (None, None)
        values.append(v)
    notes = "; ".join(f"{c.pair.label}: {c.note}" for c in comparisons if c.note)
    agreement = Table(
        "Synthetic against real", "synthetic-real",
        f"How well each synthetic corruption ranks the models as the real condition does: rank "
        f"correlation of the models' {metric} on the corruption (mean over its levels) and on the "
        f"real condition's clean images (1: the same order, -1: reversed), with {LEVEL:.0%} "
        "percentile bootstrap intervals over the models." + (f" n/a: {notes}." if notes else ""),
        cols, [Row(c.pair.label, "yours", None) for c in comparisons], values, ranked=False)
    models = list(dict.fromkeys(m for c in comparisons for m in c.models))
    cols, values = [], [dict() for _ in models]
    for k, c in enumerate(comparisons):
        group = c.pair.label
        cols += [Column(f"{k} s", f"{metric} {c.pair.corruption}", group, LOW, 3),
                 Column(f"{k} r", f"{metric} real", group, LOW, 3)]
        for m, s, r in zip(c.models, c.synthetic, c.real):
            values[models.index(m)].update({f"{k} s": s, f"{k} r": r})
    errors = Table("Synthetic and real errors", "synthetic-real-errors",
                   f"Each model's {metric} on the synthetic corruption (mean over its levels) and on "
                   "the real condition (lower is better; n/a: no results there). Bold: best; "
                   "underlined: second.", cols, [Row(m, "yours", None) for m in models], values)
    return [agreement, errors]
