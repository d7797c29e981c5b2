"""What a report is made of: the user's results files (scored as ``robodepth score`` scores
them), the published models as context, and (optionally) the dataset build they came from.

A :class:`Row` is one line of every table: the user's models first, in the order given,
then the published ones. Nothing here imports matplotlib.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from .. import benchmark_facts
from ..evaluation import results, scores as scores_mod
from ..evaluation.csvrows import ResultsTable, normalise_name
from ..errors import RobodepthError, counted
from . import published

KITTI_S = "kitti-s"
BENCHMARK_CHOICES = (*benchmark_facts.BENCHMARKS, KITTI_S)


def style_names() -> tuple[str, ...]:
    """The KITTI-S styles in the benchmark's order (the published table's columns)."""
    return tuple(published.style_models()[0].dee)


@dataclass
class Row:
    """One model in the tables: ``kind`` is ``yours``, ``baseline`` or ``published``."""

    name: str
    kind: str
    clean: float | None
    scores: scores_mod.Scores | None = None  # KITTI-C / NYUDepth2-C
    styles: dict[str, float] | None = None  # KITTI-S: DEE per style
    source: str = ""  # the results file (yours) or the paper

    @property
    def mine(self) -> bool:
        return self.kind == "yours"

    @property
    def mdee(self) -> float:
        if self.scores is not None:
            return self.scores.overall.dee
        return results.mean(self.styles.values())


@dataclass
class Model:
    """One of the user's results files, read and scored."""

    name: str
    path: Path
    row: Row
    variants: list[dict] = field(default_factory=list)  # the CSV's rows, numbers as floats
    sha256: str = ""
    own_depth: str = ""  # a warning: judged on corruptions made from its own depth predictions
    severity_size: str = "none"  # the build's, as the results file records it


def model_names(paths: Sequence[Path], names: Sequence[str]) -> list[str]:
    """``--name`` per file (in order) or the file stems; duplicates refused."""
    if names and len(names) != len(paths):
        raise RobodepthError(f"--name given {counted(len(names), 'time')} for "
                             f"{counted(len(paths), 'results file')}; "
                             "give it once per file, in the same order, or not at all")
    chosen = list(names) if names else [p.stem for p in paths]
    for n in chosen:
        if not n.strip():
            raise RobodepthError("--name: a model name cannot be empty")
    seen: dict[str, Path] = {}
    for n, p in zip(chosen, paths):
        if n in seen:
            hint = "" if names else " (use --name to tell them apart)"
            raise RobodepthError(f"{p}: model name {n!r} is also the name of {seen[n]}{hint}")
        seen[n] = p
    return chosen


def infer(tables: Sequence[ResultsTable], benchmark: str | None) -> str:
    """The benchmark of every results table: ``benchmark`` when given, else inferred from
    the rows (as ``robodepth score`` infers it); files of different benchmarks are refused."""
    if benchmark:
        return benchmark
    found = {t.source: results.infer_benchmark(t, style_names()) for t in tables}
    kinds = sorted(set(found.values()))
    if len(kinds) > 1:
        first = {k: next(p for p, v in found.items() if v == k) for k in kinds}
        raise RobodepthError("the results are on different benchmarks ("
                             + ", ".join(f"{first[k]} is {k}" for k in kinds)
                             + "); make one report per benchmark")
    return kinds[0]


def variant_rows(table: ResultsTable) -> list[dict]:
    """The results table's rows with every numeric cell as a float (already validated by
    the score parser, which read the same table)."""
    out = []
    for raw in table.records():
        row: dict = {}
        for key, v in raw.items():
            if key == "corruption":
                chained = ":" in (v or "") or "+" in (v or "")  # a chain keeps its canonical text
                row[key] = "".join((v or "").split()) if chained else normalise_name(v or "")
            elif key == "level":
                level = float(v) if (v or "").strip() else 0.0  # a chain's row may leave it empty
                row[key] = int(level) if level.is_integer() else level
            else:
                try:
                    row[key] = float(v)
                except (TypeError, ValueError):
                    continue
        out.append(row)
    return out


def load(tables: Sequence[ResultsTable], names: Sequence[str], benchmark: str) -> list[Model]:
    """Score every results table; a file missing variants is refused (a report compares
    complete results only)."""
    from ..evaluation.owndepth import warning

    out = []
    paths = [Path(t.source) for t in tables]
    for name, path, table in zip(model_names(paths, names), paths, tables):
        if benchmark == KITTI_S:
            res = results.parse_style_results(table, style_names())
            row = Row(name, "yours", res.clean, styles=res.dee, source=str(path))
        else:
            bench = benchmark_facts.get_benchmark(benchmark)
            res = results.read_results(table, bench)
            missing = results.missing_message(res, bench)
            if missing:
                raise RobodepthError(missing)
            row = Row(name, "yours", res.clean, scores=scores_mod.score(res, bench), source=str(path))
        out.append(Model(name, path, row, variant_rows(table), table.sha256, warning(table),
                         table.severity_size()))
    return out


def beyond_only(models: Sequence[Model]) -> str:
    """Why there is no mCE, mRR or mDEE when every model's results hold rows beyond the
    benchmark only (chains, decimal levels); "" when all have the benchmark's rows. A
    report of both kinds is refused: its tables could not compare them."""
    notes = [m.row.scores.note if m.row.scores is not None else "" for m in models]
    if any(notes) and not all(notes):
        only = next(m for m, n in zip(models, notes) if n)
        full = next(m for m, n in zip(models, notes) if not n)
        raise RobodepthError(f"{only.path}: has rows beyond the benchmark only, {full.path} has the "
                             "benchmark's: make one report of each kind")
    return notes[0] if all(notes) else ""


def context(benchmark: str, which: str) -> list[Row]:
    """The published models as rows: ``all`` of them, only the ``baseline`` or ``none``."""
    if which == "none":
        return []
    cite = f"{published.CITATION} ({published.CITATION_URL})"
    if benchmark == KITTI_S:
        rows = [Row(m.name, "baseline" if m.block == "baseline" else "published", None,
                    styles=dict(m.dee), source=cite) for m in published.style_models()]
    else:
        bench = benchmark_facts.get_benchmark(benchmark)
        rows = [Row(m.name, "baseline" if m.block == "baseline" else "published", m.clean_dee,
                    scores=scores_mod.score(m.results(), bench), source=cite) for m in published.models(benchmark)]
    return [r for r in rows if which == "all" or r.kind == "baseline"]


# --------------------------------------------------------------------------- the dataset build

def dataset_info(path: Path, benchmark: str) -> dict:
    """What identifies a dataset build: its name, seed, robodepth version and a fingerprint
    (sha256 over the sorted ``output sha256`` pairs of its manifest, so two builds with the
    same bytes have the same fingerprint whatever their order of work)."""
    import hashlib

    from .. import open_dataset
    from ..output.folder import OutputFolder

    ds = open_dataset(path)
    if ds.name != benchmark:
        raise RobodepthError(f"--dataset {path}: is a {ds.name} build, but the results are {benchmark}")
    rows = OutputFolder(path).rows()
    digest = hashlib.sha256()
    for out in sorted(rows):
        digest.update(f"{out} {rows[out].sha256}\n".encode())
    record = ds.record
    return {"name": ds.name, "path": str(path), "fingerprint": digest.hexdigest(),
            "files": len(rows), "images": len(ds.keys), "seed": record.seed,
            "robodepth": record.robodepth or None}
