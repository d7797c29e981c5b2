"""The benchmark's robustness scores: DEE, CE, mCE, RR, mRR, mDEE.

Everything here is pure: a results CSV read into :class:`~.results.Results`, :func:`score` it
against a :class:`Baseline` into a :class:`Scores` record that renders as a table or as
JSON. Problems with the input raise :class:`ScoreError`, whose message is one line naming
the file (and the line, where there is one).

The results CSV and its reader: :mod:`.results`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..benchmark_facts import CATEGORIES, CATEGORY, CORRUPTIONS, Baseline, Benchmark
from ..errors import counted
from .results import Results, ScoreError, check_complete, corruption_error, mean, resilience_rate


# --------------------------------------------------------------------------- scoring

@dataclass(frozen=True)
class CorruptionScore:
    name: str
    category: str
    level_dee: dict[int, float]  # empty when the corruption is absent (partial scoring)
    dee: float | None  # mean over the levels present
    ce: float | None  # percent
    rr: float | None  # percent


@dataclass(frozen=True)
class GroupScore:
    name: str
    n: int  # corruptions with rows
    dee: float | None
    ce: float | None
    rr: float | None


@dataclass(frozen=True)
class Scores:
    benchmark: str
    n_levels: int
    source: str
    baseline: Baseline | None  # None: no baseline, so no CE
    clean_dee: float
    corruptions: tuple[CorruptionScore, ...]
    categories: tuple[GroupScore, ...]
    overall: GroupScore
    missing: tuple[tuple[str, int], ...]
    # Beyond the benchmark, not in mCE/mRR/mDEE: per corruption with decimal-level rows, its
    # DEE at every level present (integer and decimal, ascending); chains' DEE.
    curves: dict[str, dict[float, float]] = field(default_factory=dict)
    chains: dict[str, float] = field(default_factory=dict)
    note: str = ""  # why there is no mCE, mRR or mDEE (rows beyond the benchmark only)
    levels: tuple[int, ...] = ()  # the benchmark's levels (an unpublished set's: its own)

    def to_json(self) -> dict:
        """The JSON form; keys are documented in docs/score.md and stay stable. A results file
        with rows beyond the benchmark adds ``beyond_benchmark``."""
        doc = {
            "benchmark": self.benchmark,
            "results": self.source,
            "baseline": None if self.baseline is None else {
                "name": self.baseline.name, "clean_dee": self.baseline.clean,
                "dee": dict(self.baseline.dee)},
            "clean_dee": self.clean_dee,
            "corruptions": {
                c.name: {"category": c.category, "dee": c.dee, "ce": c.ce, "rr": c.rr,
                         "levels": {str(lv): d for lv, d in c.level_dee.items()}}
                for c in self.corruptions},
            "categories": {g.name: {"n": g.n, "dee": g.dee, "ce": g.ce, "rr": g.rr}
                           for g in self.categories},
            "mdee": self.overall.dee,
            "mce": self.overall.ce,
            "mrr": self.overall.rr,
            "partial": bool(self.missing),
            "missing": [{"corruption": n, "level": lv} for n, lv in self.missing],
        }
        if self.note:
            doc["note"] = self.note
        if self.curves or self.chains:
            from ..sourcekeys import level_text

            doc["beyond_benchmark"] = {
                "severity_curves": {n: {level_text(lv): d for lv, d in curve.items()}
                                    for n, curve in self.curves.items()},
                "chains": dict(self.chains)}
        return doc


def _group(name: str, members: list[CorruptionScore]) -> GroupScore:
    present = [c for c in members if c.dee is not None]
    if not present:
        return GroupScore(name, 0, None, None, None)
    ce = None if present[0].ce is None else mean(c.ce for c in present)
    return GroupScore(name, len(present), mean(c.dee for c in present), ce,
                      mean(c.rr for c in present))


def score(results: Results, benchmark: Benchmark, baseline: Baseline | None = None,
          *, allow_partial: bool = False) -> Scores:
    """Score ``results`` against ``baseline`` (default: the benchmark's published one; with
    neither, CE, mCE and their category means are None: DEE and RR need no baseline).

    Per corruption: DEE is the mean over the levels present, CE and RR as in
    :func:`corruption_error` and :func:`resilience_rate`. Category means and the overall
    mDEE, mCE, mRR average the corruptions present. Missing variants raise ScoreError
    unless ``allow_partial``; then they are listed in ``Scores.missing``.
    """
    baseline = baseline or benchmark.baseline
    for name in benchmark.corruptions if baseline is not None else ():
        if name in results.dee and not baseline.dee[name] > 0.0:
            # CE divides by it; a zero is a broken or placeholder baseline, not a model.
            raise ScoreError(f"{baseline.name}: the baseline DEE of {name} is "
                             f"{baseline.dee[name]:g}; CE divides by it, so it must be above 0")
    missing = [] if results.beyond_only else results.missing(benchmark)
    if missing and not allow_partial:
        check_complete(results, benchmark)
    rows = []
    for name in benchmark.corruptions:
        levels = results.dee.get(name, {})
        if levels:
            d = levels.values()
            rows.append(CorruptionScore(name, CATEGORY[name], dict(levels), mean(d),
                                        None if baseline is None
                                        else corruption_error(d, baseline.dee[name]),
                                        resilience_rate(d, results.clean)))
        else:
            rows.append(CorruptionScore(name, CATEGORY[name], {}, None, None, None))
    categories = tuple(_group(cat, [r for r in rows if r.category == cat]) for cat in CATEGORIES)
    curves = {n: dict(sorted({**results.dee.get(n, {}), **d}.items())) for n, d in results.decimal.items()}
    return Scores(benchmark.name, benchmark.n_levels, results.source, baseline, results.clean, tuple(rows),
                  categories, _group("overall", rows), tuple(missing), curves, dict(results.chains),
                  no_score_note(benchmark) if results.beyond_only else "", tuple(benchmark.levels))


def no_score_note(benchmark: Benchmark) -> str:
    """Why results with rows beyond the benchmark only have no mCE, mRR or mDEE."""
    return (f"no mCE, mRR or mDEE: they are defined on {benchmark.name}'s corruptions at its "
            f"integer levels 1..{benchmark.n_levels}, and these results have no such row, only "
            "rows beyond the benchmark (chains, decimal levels), whose DEE is shown")


# --------------------------------------------------------------------------- table

def _cell(value: float | None, spec: str, width: int) -> str:
    return f"{'n/a' if value is None else format(value, spec):>{width}}"


def _partial_note(c: CorruptionScore, s: Scores) -> str:
    if not c.level_dee:
        return "  (missing)"
    levels = s.levels or tuple(range(1, s.n_levels + 1))
    if set(levels) - set(c.level_dee):
        every = (f"1..{s.n_levels}" if levels == tuple(range(1, s.n_levels + 1))
                 else ",".join(map(str, levels)))
        return f"  (levels {','.join(map(str, c.level_dee))} of {every})"
    return ""


def format_table(s: Scores) -> str:
    """A plain-text table: per corruption DEE, CE, RR; category means; mDEE, mCE, mRR."""
    w = max(len(n) for n in (*CORRUPTIONS, *CATEGORIES)) + 2
    head = f"{'':<{w}}{'DEE':>8}{'CE %':>9}{'RR %':>9}"
    lines = [f"{s.benchmark}: {s.source}",
             (f"baseline: {s.baseline.name} (clean DEE {s.baseline.clean:.3f})" if s.baseline
              else f"baseline: none ({s.benchmark} has no published one; --baseline CSV, any "
                   "model's results on it, gives CE and mCE)"),
             f"clean DEE: {s.clean_dee:.3f}", "", head]
    if s.note:
        return "\n".join([lines[0], lines[2], "", s.note] + _beyond(s)) + "\n"
    for cat, group in zip(CATEGORIES, s.categories):
        if not any(c.category == cat for c in s.corruptions):
            continue  # a set without this category's corruptions (a custom build's)
        lines.append(cat)
        for c in s.corruptions:
            if c.category == cat:
                lines.append(f"  {c.name:<{w - 2}}{_cell(c.dee, '.3f', 8)}"
                             f"{_cell(c.ce, '.2f', 9)}{_cell(c.rr, '.2f', 9)}{_partial_note(c, s)}")
        lines += [f"  {'mean':<{w - 2}}{_cell(group.dee, '.3f', 8)}"
                  f"{_cell(group.ce, '.2f', 9)}{_cell(group.rr, '.2f', 9)}", ""]
    o = s.overall
    lines.append(f"mCE {_cell(o.ce, '.2f', 0)}   mRR {_cell(o.rr, '.2f', 0)}   "
                 f"mDEE {_cell(o.dee, '.3f', 0)}")
    if s.missing:
        lines.append(f"partial: {counted(len(s.missing), 'variant')} missing, scores average the "
                     f"{o.n} corruptions present")
    return "\n".join(lines + _beyond(s)) + "\n"


def _beyond(s: Scores) -> list[str]:
    """The section of rows beyond the benchmark: severity curves and chains."""
    if not s.curves and not s.chains:
        return []
    from ..sourcekeys import level_text

    lines = ["", "Beyond the benchmark (not in mCE, mRR or mDEE)"]
    if s.curves:
        lines.append("severity curves, DEE by level:")
        w = max(map(len, s.curves)) + 2
        for name, curve in s.curves.items():
            points = "  ".join(f"{level_text(lv)}: {d:.3f}" for lv, d in curve.items())
            lines.append(f"  {name:<{w}}{points}")
    if s.chains:
        lines.append("chains, DEE:")
        w = max(map(len, s.chains)) + 2
        lines += [f"  {text:<{w}}{d:.3f}" for text, d in s.chains.items()]
    return lines
