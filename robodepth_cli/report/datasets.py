"""Results of several datasets in one report (docs/report.md, several datasets): which
dataset (and split) each results file is on (its own columns, else ``--on``, else the rows
as ``score`` infers them), the files of a dataset without a published baseline scored
against the ``--baseline`` model on the same dataset (without one, DEE and RR only), one
table per such dataset and a summary across all of them."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from .. import benchmark_facts
from ..errors import RobodepthError, counted
from ..evaluation import results, scores as scores_mod
from ..evaluation.csvrows import ResultsTable, ScoreError
from . import inputs
from . import synreal
from . import tables as tables_mod
from .tables import HIGH, LOW, Column, Table

PUBLISHED = inputs.BENCHMARK_CHOICES  # datasets with the paper's tables: the full report


@dataclass
class Entry:
    """One results file: whose (``name``), on which dataset and split (``key``)."""

    name: str
    path: Path
    key: tuple[str, str]
    variants: list[dict]  # the CSV's rows, numbers as floats
    sha256: str
    model: inputs.Model | None = None  # scored as its benchmark (kitti-c, nyudepth2-c, kitti-s)
    scores: scores_mod.Scores | None = None  # other datasets with corruption rows
    severity_size: str = "none"  # the build's, as the results file records it

    def value(self, corruption: str | None, metric: str) -> float | None:
        """The clean row's error (``corruption`` None), or the corruption's mean over its
        integer levels; None where the file has no such row."""
        rows = [v for v in self.variants
                if v.get("corruption") == (corruption or benchmark_facts.CLEAN) and isinstance(v.get("level"), int)
                and (corruption is None) == (v["level"] == 0)]
        if not rows:
            return None
        if metric == "abs_rel" and "abs_rel" not in rows[0]:
            raise RobodepthError(f"{self.path}: has no abs_rel column (--metric abs_rel)")
        return results.mean(_error(v, metric) for v in rows)


def _error(row: dict, metric: str) -> float:
    if metric == "dee" and "dee" in row:
        return row["dee"]
    return results.dee(row["abs_rel"], row["a1"]) if metric == "dee" else row["abs_rel"]


def keys_of(tables: Sequence[ResultsTable], on: Sequence[str], benchmark: str | None) -> list[tuple[str, str]]:
    """Each file's (dataset, split): from ``--on`` (once per file, or once for all), else
    the one the file names, else its benchmark as inferred from its rows. A file that names
    another than ``--on`` (or ``--benchmark``) is refused."""
    if on and len(on) not in (1, len(tables)):
        raise RobodepthError(f"--on given {counted(len(on), 'time')} for "
                             f"{counted(len(tables), 'results file')}; give it "
                             "once per file, in the same order, or once for all")
    given = [synreal.parse_key(t) for t in (on * len(tables) if len(on) == 1 else on)]
    for text, key in zip(on, given):
        if not key[0]:
            raise RobodepthError(f"--on {text!r}: expected DATASET or DATASET:SPLIT")
    out = []
    for i, table in enumerate(tables):
        p, own = table.source, table.dataset()
        key = given[i] if given else own
        if own is not None and own != key:
            raise RobodepthError(f"--on {synreal.key_text(key)}: {p} says its results are on "
                                 f"{synreal.key_text(own)} (its dataset column)")
        if own is not None and benchmark and not given and own != (benchmark, ""):
            raise RobodepthError(f"--benchmark {benchmark}: {p} says its results are on "
                                 f"{synreal.key_text(own)} (its dataset column)")
        if key is None:
            try:
                key = (inputs.infer([table], benchmark), "")
            except ScoreError as exc:
                raise RobodepthError(f"{exc} (results on another dataset: name it with --on "
                                     "DATASET[:SPLIT])") from None
        out.append(key)
    return out


def load(tables: Sequence[ResultsTable], names: Sequence[str], keys: Sequence[tuple[str, str]],
         baseline: str | None) -> list[Entry]:
    """Check every results table (a model's name may repeat across datasets, never within
    one) and score it: a published benchmark as ``robodepth score`` does, another dataset's
    corruption rows against ``baseline``'s results on the same dataset, if given."""
    paths = [Path(t.source) for t in tables]
    chosen = list(names) if names else [p.stem for p in paths]
    if names and len(names) != len(paths):
        raise RobodepthError(f"--name given {counted(len(names), 'time')} for "
                             f"{counted(len(paths), 'results file')}; "
                             "give it once per file, in the same order, or not at all")
    seen: dict[tuple, Path] = {}
    for n, p, k in zip(chosen, paths, keys):
        if not n.strip():
            raise RobodepthError("--name: a model name cannot be empty")
        if (n, k) in seen:
            hint = "" if names else " (use --name to tell them apart)"
            raise RobodepthError(f"{p}: model name {n!r} on {synreal.key_text(k)} is also the name of "
                                 f"{seen[n, k]}{hint}")
        seen[n, k] = p
    entries = []
    for n, p, k, t in zip(chosen, paths, keys, tables):
        if k[0] in PUBLISHED:
            (model,) = inputs.load([t], [n], k[0])
            entries.append(Entry(n, p, k, model.variants, model.sha256, model=model,
                                 severity_size=model.severity_size))
        else:
            _check(t)
            entries.append(Entry(n, p, k, inputs.variant_rows(t), t.sha256, severity_size=t.severity_size()))
    if baseline is not None and baseline not in chosen:
        raise RobodepthError(f"--baseline {baseline!r}: no results file has that model name "
                             f"(the names: {', '.join(dict.fromkeys(chosen))})")
    for e in entries:
        if e.model is None and _corrupted(e):
            base = next((b for b in entries if b.name == baseline and b.key == e.key), None)
            if baseline is not None and (base is None or not _corrupted(base)):
                raise RobodepthError(f"--baseline {baseline}: has no results with corruption rows "
                                     f"on {synreal.key_text(e.key)}, which {e.path} has")
            e.scores = _score(e, base)
    return entries


def _corrupted(e: Entry) -> bool:
    """Whether ``e`` has rows of the benchmark's corruptions (the depth-aware ones have no
    baseline and never enter mCE, mRR or mDEE, as in ``score``)."""
    return any(v["corruption"] in benchmark_facts.CORRUPTIONS and isinstance(v["level"], int) for v in e.variants)


def _check(table: ResultsTable) -> None:
    """Every number checked (as ``score`` checks them), corruptions known, one row per
    variant, a clean row."""
    for _ in results.checked_rows(table, None, "the report needs the clean error"):
        pass


def _results(e: Entry) -> tuple[results.Results, benchmark_facts.Benchmark]:
    table: dict[str, dict[int, float]] = {}
    for v in e.variants:
        if v["corruption"] in benchmark_facts.CORRUPTIONS and isinstance(v["level"], int):
            table.setdefault(v["corruption"], {})[v["level"]] = _error(v, "dee")
    names = tuple(n for n in benchmark_facts.CORRUPTIONS if n in table)
    top = max(lv for levels in table.values() for lv in levels)
    # Without a baseline, CE is not shown: a unit baseline lets the one scoring function
    # give DEE and RR.
    unit = benchmark_facts.Baseline("", 0.0, dict.fromkeys(names, 1.0))
    return (results.Results(str(e.path), e.value(None, "dee"), {n: dict(sorted(table[n].items())) for n in names}),
            benchmark_facts.Benchmark(e.key[0], names, top, unit))


def _score(e: Entry, base: Entry | None) -> scores_mod.Scores:
    res, bench = _results(e)
    baseline = None
    if base is not None:
        bres, bbench = _results(base)
        if bbench.corruptions != bench.corruptions or bbench.n_levels != bench.n_levels:
            raise RobodepthError(f"--baseline: {base.path} and {e.path} on {synreal.key_text(e.key)} do "
                                 "not have the same corruptions and levels")
        baseline = results.baseline_from_results(bres, bbench)
        baseline = benchmark_facts.Baseline(base.name, baseline.clean, baseline.dee)
    return scores_mod.score(res, bench, baseline, allow_partial=True)


# --------------------------------------------------------------------------- tables

@dataclass
class Section:
    """A dataset of the report beyond its main benchmark: a heading and its tables."""

    key: tuple[str, str]
    tables: list[Table] = field(default_factory=list)

    @property
    def title(self) -> str:
        return tables_mod.bench_name(self.key[0]) + (f", {self.key[1]}" if self.key[1] else "")


def groups(entries: Sequence[Entry]) -> dict[tuple[str, str], list[Entry]]:
    out: dict[tuple[str, str], list[Entry]] = {}
    for e in entries:
        out.setdefault(e.key, []).append(e)
    return out


def section(key: tuple[str, str], entries: Sequence[Entry], context: str) -> Section:
    """One dataset's tables: a published benchmark's summary and DEE per corruption (the
    paper's rows as context), or the clean errors and, with corruption rows, mDEE, mRR and
    (with a baseline) mCE."""
    sec = Section(key)
    label = "dataset-" + "-".join(p for p in key if p)
    if key[0] in PUBLISHED:
        rows = [e.model.row for e in entries]
        if key[0] == inputs.KITTI_S:
            t = tables_mod.styles_table(rows + inputs.context(key[0], context))
            sec.tables.append(_relabel(t, label))
        else:
            rows += inputs.context(key[0], context)
            sec.tables += [_relabel(tables_mod.summary_table(rows, key[0]), label),
                           _relabel(tables_mod.corruption_table(rows, key[0], "dee"), label + "-dee")]
        return sec
    cols = [Column("abs_rel", "AbsRel", "Clean", LOW, 3), Column("a1", "δ1", "Clean", HIGH, 3)]
    metrics = any("abs_rel" in e.variants[0] for e in entries)
    if not metrics:
        cols = []  # results of DEE alone
    cols.append(Column("clean", "DEE", "Clean", LOW, 3))
    scored = [e.scores for e in entries if e.scores is not None]
    with_ce = any(s.baseline.name for s in scored)
    if scored:
        cols += [Column("mDEE", "mDEE", "Corruptions", LOW, 3), Column("mRR", "mRR", "Corruptions", HIGH, 2)]
        cols += [Column("mCE", "mCE", "Corruptions", LOW, 2)] if with_ce else []
    values = []
    for e in entries:
        clean = next(v for v in e.variants if v["corruption"] == benchmark_facts.CLEAN)
        v = {"abs_rel": clean.get("abs_rel"), "a1": clean.get("a1"), "clean": e.value(None, "dee")}
        if e.scores is not None:
            v.update({"mDEE": e.scores.overall.dee, "mRR": e.scores.overall.rr,
                      "mCE": e.scores.overall.ce if with_ce else None})
        values.append(v)
    base = next((s.baseline.name for s in scored if s.baseline.name), "")
    what = (f"; mCE against {base} = 100 (--baseline)" if base else
            "; mCE needs --baseline (no published baseline)" if scored else "")
    sec.tables.append(Table(f"Results on {sec.title}", label,
                            f"The clean images' {'AbsRel, δ1 and ' if metrics else ''}DEE "
                            f"on {sec.title}"
                            + ("; over its corruptions, mDEE and mRR" if scored else "") + what
                            + ". Bold: best; underlined: second." + _mixed(entries),
                            cols, [inputs.Row(e.name, "yours", e.value(None, "dee"), source=str(e.path))
                                   for e in entries], values))
    return sec


def _mixed(entries: Sequence[Entry]) -> str:
    """The caption's sentence when ``entries`` were made at different severity sizes."""
    note = tables_mod.mixed_note(e.severity_size for e in entries)
    return f" {note}." if note else ""


def _relabel(t: Table, label: str) -> Table:
    t.label = label  # ids stay unique on a page of several datasets
    return t


def across(entries: Sequence[Entry]) -> Table:
    """Every model on every dataset: the clean DEE and, where there are corruptions, mDEE."""
    by_key = groups(entries)
    cols = []
    for key, es in by_key.items():
        title = tables_mod.bench_name(key[0]) + (f" {key[1]}" if key[1] else "")
        cols.append(Column(f"{synreal.key_text(key)} clean", "clean DEE", title, LOW, 3))
        if any(_mdee(e) is not None for e in es):
            cols.append(Column(f"{synreal.key_text(key)} mDEE", "mDEE", title, LOW, 3))
    models = list(dict.fromkeys(e.name for e in entries))
    values = []
    for m in models:
        v: dict = {}
        for e in entries:
            if e.name == m:
                v[f"{synreal.key_text(e.key)} clean"] = e.value(None, "dee")
                v[f"{synreal.key_text(e.key)} mDEE"] = _mdee(e)
        values.append(v)
    return Table("Across datasets", "across", "Each model's clean DEE on every dataset and, "
                 "where the dataset has corruptions, its mDEE (lower is better; n/a: no results "
                 "there). Bold: best; underlined: second." + _mixed(entries), cols,
                 [inputs.Row(m, "yours", None) for m in models], values)


def _mdee(e: Entry) -> float | None:
    if e.model is not None:
        return e.model.row.mdee if not (e.model.row.scores and e.model.row.scores.note) else None
    return e.scores.overall.dee if e.scores is not None else None
