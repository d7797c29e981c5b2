"""The RoboDepth paper's published results, shipped as data (``published/*.csv``).

Source (the numbers are copied from its tables; ``published/README.md`` says which table
each column comes from, and lists the paper's own inconsistencies, kept as printed):

    Lingdong Kong, Shaoyuan Xie, Hanjiang Hu, Lai Xing Ng, Benoit R. Cottereau, Wei Tsang Ooi.
    RoboDepth: Robust Out-of-Distribution Depth Estimation under Corruptions.
    NeurIPS 2023, Datasets and Benchmarks Track. https://github.com/ldkong1205/RoboDepth

The one value that differs from the printed tables is the AdaBins EB5 row of NYUDepth2-C's
per-corruption DEE table, which the paper printed as a copy of BTS R50's row (the README
gives the correct row and its sources).

KITTI-C and NYUDepth2-C models become :class:`~robodepth_cli.evaluation.results.Results` (each level
holding the published level mean, so a level mean is that value) and are scored by the same
code as ``robodepth score``.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ..benchmark_facts import BIBTEX, Benchmark, get_benchmark  # noqa: F401 (the page's citation)
from ..evaluation.results import Results

CITATION = ("Kong, Xie, Hu, Ng, Cottereau, Ooi. RoboDepth: Robust Out-of-Distribution Depth "
            "Estimation under Corruptions. NeurIPS 2023 (Datasets and Benchmarks)")
CITATION_URL = "https://github.com/ldkong1205/RoboDepth"
DATA = Path(__file__).resolve().parent / "published"
FILES = {"kitti-c": "kitti-c.csv", "nyudepth2-c": "nyudepth2-c.csv", "kitti-s": "kitti-s.csv"}
# The summary columns of kitti-c.csv and nyudepth2-c.csv: (prefix, category name or None).
CATEGORY_PREFIX = {"weather_lighting": "weather & lighting", "sensor_movement": "sensor & movement",
                   "data_processing": "data & processing"}


@dataclass(frozen=True)
class PublishedModel:
    """One row of the paper's KITTI-C or NYUDepth2-C tables."""

    benchmark: str
    block: str  # baseline, mono, stereo, mono+stereo (KITTI); baseline, supervised (NYU)
    name: str
    clean_dee: float
    dee: dict[str, float]  # level-averaged DEE per corruption, benchmark order
    printed: dict[str, float]  # the summary as printed: mCE, mRR, mDEE, <category>_mCE, ...

    def results(self) -> Results:
        """The row as results ``robodepth score`` reads: each level holds the level mean."""
        bench = get_benchmark(self.benchmark)
        return Results(f"published: {self.name}", self.clean_dee,
                       {n: {lv: self.dee[n] for lv in bench.levels} for n in bench.corruptions})


@dataclass(frozen=True)
class PublishedStyles:
    """One row of the paper's KITTI-S table: DEE per style and the printed mDEE."""

    block: str
    name: str
    dee: dict[str, float]
    printed_mdee: float


def _rows(name: str) -> list[dict[str, str]]:
    with (DATA / FILES[name]).open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@lru_cache(maxsize=None)
def models(benchmark: str) -> tuple[PublishedModel, ...]:
    """The published models of ``kitti-c`` or ``nyudepth2-c``, in the paper's order."""
    bench: Benchmark = get_benchmark(benchmark)
    out = []
    for row in _rows(benchmark):
        printed = {k: float(row[k]) for k in ("mCE", "mRR", "mDEE")}
        for prefix in CATEGORY_PREFIX:
            for k in ("mCE", "mRR", "mDEE"):
                printed[f"{prefix}_{k}"] = float(row[f"{prefix}_{k}"])
        out.append(PublishedModel(benchmark, row["block"], row["model"], float(row["clean_dee"]),
                                  {n: float(row[n]) for n in bench.corruptions}, printed))
    return tuple(out)


@lru_cache(maxsize=None)
def style_models() -> tuple[PublishedStyles, ...]:
    """The published KITTI-S models, in the paper's order (the styles in its column order)."""
    out = []
    for row in _rows("kitti-s"):
        styles = [k for k in row if k not in ("block", "model", "mDEE")]
        out.append(PublishedStyles(row["block"], row["model"], {s: float(row[s]) for s in styles},
                                   float(row["mDEE"])))
    return tuple(out)


def baseline(benchmark: str):
    """The published baseline row of ``benchmark`` (KITTI-C, NYUDepth2-C or KITTI-S)."""
    rows = style_models() if benchmark == "kitti-s" else models(benchmark)
    return next(r for r in rows if r.block == "baseline")


PROPERTIES = ("modality", "backbone", "resolution", "pretrain")


@lru_cache(maxsize=None)
def properties(benchmark: str) -> dict[str, dict[str, str]]:
    """Each published model's ``modality``, ``backbone``, ``resolution`` and ``pretrain`` as
    printed (KITTI-C; ``{}`` for a benchmark whose table has no such columns), the empty
    cells left out."""
    return {row["model"]: {k: row[k].strip() for k in PROPERTIES if (row.get(k) or "").strip()}
            for row in _rows(benchmark)}
