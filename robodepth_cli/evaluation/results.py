"""A results CSV (what ``robodepth evaluate`` writes and ``robodepth score`` reads), read
into :class:`Results`, and the per-variant formulas (DEE, CE, RR) its rows need.

Results CSV
    A header row is required; columns are found by name (case-insensitive, surrounding
    spaces ignored, in any order; the other columns are not scored, but their numbers are
    checked: :class:`.csvrows.ResultsTable`, which reads and writes the file).
    Required: ``corruption``, ``level`` and either both ``abs_rel`` and ``a1`` or ``dee``
    (not both, which would be ambiguous). One row per (corruption, level); the clean row has
    corruption ``clean`` and level ``0``. Blank lines and lines starting with ``#`` are
    skipped. ``a1`` is a fraction in [0, 1]; ``abs_rel`` is finite and >= 0; ``dee`` is in
    [0, 1] (a value above 1 is almost surely the paper's DES1 = abs_rel - a1 + 1, which
    lacks the halving).

    Rows beyond the benchmark are read too, and kept apart: a corruption at a decimal level
    (``fog,2.5``) or a depth-aware one (``fog_3d,3``: no baseline), and a chain
    (``fog:3+gaussian_noise:2.5``, level 0 or empty), as ``robodepth evaluate`` writes them. mCE, mRR and mDEE stay
    defined as the benchmark defines them, on its corruptions at its integer levels; the
    extra rows are reported as severity curves (DEE against the level, integer and decimal
    levels together) and chain DEE rows, in a section of their own. A file with such rows
    only (a chain set's) has no mCE, mRR or mDEE, and says why (:attr:`Results.beyond_only`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Iterator, Mapping

from ..benchmark_facts import ALL_CORRUPTIONS, BENCHMARKS, CATEGORY, CLEAN, DEPTH_AWARE, Baseline, Benchmark
from ..errors import RobodepthError
from .csvrows import ResultsTable, ScoreError, level as _level, normalise_name, number


class FitError(ScoreError):
    """A row that another benchmark could take: a corruption or level not of this one."""


def dee(abs_rel: float, a1: float) -> float:
    """Depth estimation error ``(abs_rel - a1 + 1) / 2``."""
    return (abs_rel - a1 + 1.0) / 2.0


def row_dee(cells: Mapping[str, str], use_dee: bool, where: str) -> float:
    """The DEE of a row: its ``dee`` cell, or ``(abs_rel - a1 + 1) / 2``."""
    if use_dee:
        d = number(cells["dee"], "dee", where)
        if not 0.0 <= d <= 1.0:
            hint = " (DES1 = abs_rel - a1 + 1? DEE is half of it)" if d > 1.0 else ""
            raise ScoreError(f"{where}: dee {d:g} is outside [0, 1]{hint}")
        return d
    return dee(number(cells["abs_rel"], "abs_rel", where), number(cells["a1"], "a1", where))


def mean(values: Iterable[float]) -> float:
    """Arithmetic mean; ``ValueError`` on no values (a silent 0 or nan would hide a bug)."""
    values = list(values)
    if not values:
        raise ValueError("mean of no values")
    return math.fsum(values) / len(values)


def corruption_error(level_dees: Iterable[float], baseline_dee: float) -> float:
    """CE in percent: ``100 * mean_l DEE_l / baseline_dee``.

    ``baseline_dee`` is the baseline's level-averaged DEE for the same corruption; with all
    levels present this equals the benchmark's ``sum_l DEE_l / sum_l DEE^base_l``.
    """
    return 100.0 * mean(level_dees) / baseline_dee


def resilience_rate(level_dees: Iterable[float], clean_dee: float) -> float:
    """RR in percent: ``100 * sum_l (1 - DEE_l) / (L * (1 - clean_dee))``, L = number of levels."""
    return 100.0 * mean(1.0 - d for d in level_dees) / (1.0 - clean_dee)


# --------------------------------------------------------------------------- parsing

@dataclass
class Results:
    """Parsed results: the clean DEE and the DEE of every (corruption, level) present."""

    source: str
    clean: float
    dee: dict[str, dict[int, float]] = field(default_factory=dict)  # name -> level -> DEE
    # Another benchmark these rows are a complete set of ("" if none): a model scored
    # against the wrong one shows up as missing variants, which would not say why.
    looks_like: str = ""
    # Beyond the benchmark (never in mCE/mRR): decimal levels, and chains' DEE.
    decimal: dict[str, dict[float, float]] = field(default_factory=dict)  # name -> level -> DEE
    chains: dict[str, float] = field(default_factory=dict)  # canonical chain text -> DEE

    @property
    def beyond_only(self) -> bool:
        """Rows beyond the benchmark and none of it (a chains-only build's): no mCE, mRR
        or mDEE to compute, and nothing of the benchmark missing by mistake."""
        return not self.dee and bool(self.decimal or self.chains)

    def missing(self, benchmark: Benchmark) -> list[tuple[str, int]]:
        """The (corruption, level) variants of ``benchmark`` with no row, in benchmark order."""
        return [(n, lv) for n in benchmark.corruptions for lv in benchmark.levels
                if lv not in self.dee.get(n, {})]


def checked_rows(table: ResultsTable, benchmark: Benchmark | None,
                 needs_clean: str) -> Iterator[tuple[int, str, str, int | float | None, float]]:
    """The one check of a results CSV's rows: ``(line, where, name, level, dee)`` for each,
    in file order; :class:`ScoreError` for the first row that fails.

    Each row is a known corruption (of ``benchmark``, or a depth-aware one: a
    :class:`FitError` otherwise; any corruption, depth-aware ones included, when ``benchmark`` is None,
    a dataset beyond the benchmarks), a level in range (0 for clean; ``1..n_levels`` of
    ``benchmark``, at least 1 without one), its numbers finite and in range, and no
    (corruption, level) twice. With a ``benchmark``, a chain's row is allowed too (its
    canonical text as the name, level None). After the last row, a file without the clean
    row is refused, ``needs_clean`` saying what needs it."""
    seen: dict[tuple[str, int | float | None], int] = {}
    for line, where, cells, use_dee in table.data_rows():
        if benchmark is not None and (":" in cells["corruption"] or "+" in cells["corruption"]):
            name, level = _chain(cells, benchmark, where), None
        else:
            name = normalise_name(cells["corruption"])
            if not name:
                raise ScoreError(f"{where}: empty corruption")
            level = _level(cells["level"], where)
            _check_variant(name, level, cells, where, benchmark)
        if (name, level) in seen:
            what = f"chain {name}" if level is None else f"{name} level {level}"
            raise ScoreError(f"{where}: duplicate row for {what} (first on line {seen[name, level]})")
        seen[name, level] = line
        yield line, where, name, level, row_dee(cells, use_dee, where)
    if (CLEAN, 0) not in seen:
        raise ScoreError(f"{table.source}: no clean row (corruption 'clean', level 0); {needs_clean}")


def _check_variant(name: str, level: int | float, cells: Mapping[str, str], where: str,
                   benchmark: Benchmark | None) -> None:
    if name == CLEAN:
        if level != 0:
            raise ScoreError(f"{where}: the clean row must have level 0, not {level}")
    elif benchmark is None:
        if name not in ALL_CORRUPTIONS:
            raise ScoreError(f"{where}: unknown corruption {cells['corruption'].strip()!r}; "
                             f"valid: clean, {', '.join(ALL_CORRUPTIONS)}")
        if not level >= 1:
            raise ScoreError(f"{where}: level {level} of {name}: corruption levels start at 1")
    elif name not in benchmark.corruptions and name not in DEPTH_AWARE:
        if name in CATEGORY:
            raise FitError(f"{where}: {name} is not a corruption of {benchmark.name}")
        raise FitError(f"{where}: unknown corruption {cells['corruption'].strip()!r}; "
                       f"valid: clean, {', '.join(benchmark.corruptions)}")
    elif not 1 <= level <= benchmark.n_levels:
        raise FitError(f"{where}: level {level} of {name} is outside "
                       f"1..{benchmark.n_levels} for {benchmark.name}")


def parse_results(table: ResultsTable, benchmark: Benchmark) -> Results:
    """Read a results CSV's rows (format in the module docstring) for ``benchmark``.

    Every row is checked (:func:`checked_rows`), and the clean DEE is below 1.
    Completeness is not checked here: see :meth:`Results.missing`. Raises
    :class:`ScoreError`.
    """
    clean: float | None = None
    levels: dict[str, dict[int, float]] = {}
    decimal: dict[str, dict[float, float]] = {}
    chains: dict[str, float] = {}
    source = table.source
    for _, where, name, level, value in checked_rows(table, benchmark, "RR needs the clean DEE"):
        if level is None:  # a chain
            chains[name] = value
        elif name == CLEAN:
            if value >= 1.0:
                raise ScoreError(f"{where}: clean DEE {value:g} must be below 1 "
                                 "(RR divides by 1 - clean DEE)")
            clean = value
        elif isinstance(level, float) or name in DEPTH_AWARE:  # a severity curve
            decimal.setdefault(name, {})[level] = value
        else:
            levels.setdefault(name, {})[level] = value
    if not levels and not decimal and not chains:
        raise ScoreError(f"{source}: no corruption rows, only the clean one")
    return Results(source, clean, {n: dict(sorted(levels[n].items()))
                                   for n in benchmark.corruptions if n in levels},
                   decimal={n: dict(sorted(decimal[n].items())) for n in (*benchmark.corruptions, *DEPTH_AWARE) if n in decimal},
                   chains=dict(sorted(chains.items())))


def _chain(cells: Mapping[str, str], benchmark: Benchmark, where: str) -> str:
    """The canonical text of a chain row's corruption cell, its steps checked against
    ``benchmark``; its level must be 0 or empty (a chain's levels are in its name)."""
    from ..corruptions.chains import parse_chain  # only for such rows: light anyway

    try:
        chain = parse_chain(cells["corruption"], top=benchmark.n_levels)
    except RobodepthError as exc:
        raise ScoreError(f"{where}: {exc}") from None
    for step in chain.steps:
        if step.name not in benchmark.corruptions and step.name not in DEPTH_AWARE:
            raise FitError(f"{where}: chain {chain.text}: {step.name} is not a corruption of {benchmark.name}")
    if cells["level"].strip() not in ("", "0", "0.0"):
        raise ScoreError(f"{where}: a chain's row has level 0 (its levels are in its name), "
                         f"not {cells['level'].strip()!r}")
    return chain.text


def other_benchmark(table: ResultsTable, benchmark: Benchmark) -> str:
    """The name of another benchmark of which ``table`` holds every variant, or ""."""
    for other in BENCHMARKS.values():
        if other.name == benchmark.name:
            continue
        try:
            if not parse_results(table, other).missing(other):
                return other.name
        except ScoreError:
            pass
    return ""


def _looks_like(name: str) -> str:
    b = BENCHMARKS[name]
    return (f"the rows look like {name} results ({len(b.corruptions)} corruptions x "
            f"{b.n_levels} levels): use --benchmark {name}")


def read_results(table: ResultsTable, benchmark: Benchmark) -> Results:
    """A results CSV's rows for ``benchmark``. When they do not fit it but are a complete set
    of another one, the error (or :attr:`Results.looks_like`, for rows that merely leave
    variants missing) says so."""
    try:
        results = parse_results(table, benchmark)
    except ScoreError as exc:
        other = other_benchmark(table, benchmark)
        if other:
            raise ScoreError(f"{exc}; {_looks_like(other)}") from None
        raise
    if results.missing(benchmark):
        results.looks_like = other_benchmark(table, benchmark)
    return results


def infer_benchmark(table: ResultsTable, styles: Iterable[str] = ()) -> str:
    """The benchmark a results file is on, from its rows: ``kitti-s`` when they name
    ``styles``; else the one benchmark of which they are a complete set, or the only one
    whose corruptions and levels they fit. ScoreError when the rows fit none or both."""
    path = table.source
    names = set(table.corruption_names()) - {CLEAN}
    styles = set(styles)
    if styles and names and names <= styles:
        return "kitti-s"
    if styles and names & styles:
        raise ScoreError(f"{path}: mixes KITTI-S styles ({', '.join(sorted(names & styles))}) "
                         f"with corruptions ({', '.join(sorted(names - styles))})")
    fits, complete, errors = [], [], []
    for bench in BENCHMARKS.values():
        try:
            results = parse_results(table, bench)
        except ScoreError as exc:
            errors.append(exc)
            continue
        fits.append(bench.name)
        if not results.missing(bench):
            complete.append(bench.name)
    if len(complete) == 1:
        return complete[0]
    if len(fits) == 1:
        return fits[0]
    if not fits:
        # A bad header, number or duplicate is wrong whatever the benchmark: naming one
        # would not help. Rows that merely fit none (a corruption or level of neither) might.
        real = [e for e in errors if not isinstance(e, FitError)]
        raise real[0] if real else ScoreError(f"{errors[0]} (with --benchmark, the error may be clearer)")
    raise ScoreError(f"{path}: the rows fit {' and '.join(fits)}; say which with --benchmark")


@dataclass
class StyleResults:
    """Parsed KITTI-S results: the DEE of every style present (and the clean DEE, if any)."""

    source: str
    clean: float | None
    dee: dict[str, float]  # style -> DEE, in the order of the styles given to the parser

    @property
    def mdee(self) -> float:
        """KITTI-S's one score: the mean DEE over the styles."""
        return mean(self.dee.values())


def parse_style_results(table: ResultsTable, styles: tuple[str, ...]) -> StyleResults:
    """Parse KITTI-S results (rows ``<style>,0`` and optionally ``clean,0``, in the same
    columns as any results CSV; a style has no levels). Every style of ``styles`` must have
    a row; anything else is a ScoreError naming the line."""
    seen: dict[str, int] = {}
    values: dict[str, float] = {}
    source = table.source
    for line, where, cells, use_dee in table.data_rows():
        name = normalise_name(cells["corruption"])
        if name != CLEAN and name not in styles:
            raise ScoreError(f"{where}: unknown style {cells['corruption'].strip()!r}; "
                             f"valid: clean, {', '.join(styles)}")
        level = _level(cells["level"], where)
        if level != 0:
            raise ScoreError(f"{where}: {name} has level {level}; KITTI-S rows have level 0")
        if name in seen:
            raise ScoreError(f"{where}: duplicate row for {name} (first on line {seen[name]})")
        seen[name] = line
        values[name] = row_dee(cells, use_dee, where)
    missing = [s for s in styles if s not in values]
    if missing:
        raise ScoreError(f"{source}: missing {len(missing)} of {len(styles)} KITTI-S styles: "
                         f"{', '.join(missing)}")
    return StyleResults(source, values.get(CLEAN), {s: values[s] for s in styles})


def describe_missing(missing: list[tuple[str, int]], benchmark: Benchmark) -> str:
    """``[("fog", 1), ..., ("fog", 5), ("snow", 3)]`` -> ``"fog (all levels), snow 3"``."""
    return describe_variants(missing, benchmark.n_levels)


def describe_variants(variants: Iterable[tuple[str, int | None]], n_levels: int | None = None,
                      most: int | None = None) -> str:
    """Variants as every message writes them: ``"clean, fog 1,2, snow 3"``; a corruption
    with all ``n_levels`` levels is ``"fog (all levels)"``; beyond ``most`` names,
    ``", ... (N more)"``."""
    by_name: dict[str, list[int]] = {}
    for name, level in variants:
        by_name.setdefault(name, []).extend([] if level is None else [level])
    parts = []
    for name, levels in by_name.items():
        if not levels:
            parts.append(name)
        elif n_levels is not None and len(levels) == n_levels:
            parts.append(f"{name} (all levels)")
        else:
            parts.append(f"{name} {','.join(map(str, levels))}")
    if most is not None and len(parts) > most:
        return ", ".join(parts[:most]) + f", ... ({len(parts) - most} more)"
    return ", ".join(parts)


def missing_message(results: Results, benchmark: Benchmark) -> str | None:
    """``"FILE: missing N of M variants: ..."``, or None when every variant has a row."""
    missing = results.missing(benchmark)
    if not missing or results.beyond_only:
        return None
    total = len(benchmark.corruptions) * benchmark.n_levels
    if results.looks_like:  # the list of missing variants would only bury this
        return (f"{results.source}: {_looks_like(results.looks_like)} (as {benchmark.name} "
                f"results, {len(missing)} of {total} variants are missing)")
    return (f"{results.source}: missing {len(missing)} of {total} variants: "
            f"{describe_missing(missing, benchmark)}")


def check_complete(results: Results, benchmark: Benchmark) -> None:
    """Raise ScoreError naming the missing variants, if any."""
    message = missing_message(results, benchmark)
    if message:
        raise ScoreError(message)


def baseline_from_results(results: Results, benchmark: Benchmark) -> Baseline:
    """A complete results file as a baseline (level-averaged, like the published ones)."""
    check_complete(results, benchmark)
    return Baseline(results.source, results.clean,
                    {n: mean(results.dee[n].values()) for n in benchmark.corruptions})


def implausible_dee(metrics: dict, setup) -> str:
    """``"clean DEE 1.234 is implausible (...); check --kind, ..."`` for clean metrics whose
    DEE is at least 1 (every rate divides by 1 - DEE), else ""."""
    value = dee(metrics["abs_rel"], metrics["a1"])
    if value < 1:
        return ""
    return (f"clean DEE {value:.3f} is implausible (at least 1, with {setup.describe()}); "
            "check --kind, --stereo and --png-scale")
