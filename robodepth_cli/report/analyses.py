"""The paper's further analyses in a report, each drawn where its inputs are present:
robustness against size (:mod:`.sizes`), variants that differ in one property
(:mod:`.groups`), the fine-tuning matrix (:mod:`.finetune`)."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from ..errors import RobodepthError
from . import inputs
from . import tags as TG


def add(report, *, tags: Sequence[str] = (), params: Sequence[str] = (),
        flops: Sequence[str] = (), sizes: Path | None = None, groups: str = "yours") -> None:
    """Add to ``report.figures`` the figures whose inputs are there: ``size`` (any model
    with a parameter or FLOP count), ``modality``/``pretrain``/``resolution`` (a group of
    variants: of the user's models, or with ``groups`` ``all`` of the paper's too) and
    ``finetune`` (models tagged ``finetune``). Bad flags are one-line refusals."""
    given = bool(tags or params or flops or sizes is not None)
    scored = [m for m in report.models if m.row.scores is not None and not m.row.scores.note]
    if report.benchmark == inputs.KITTI_S or not scored:
        if given:
            raise RobodepthError("--tag, --params, --flops and --sizes need results on kitti-c or "
                                 "nyudepth2-c with their corruptions (the analyses use CE)")
        return
    bench = report.benchmark
    mine = [m.name for m in scored]
    context = inputs.context(bench, "all")
    everyone = mine + [r.name for r in context if r.name not in mine]
    tagged = TG.parse_tags(tags, mine)
    counts = TG.read_sizes(sizes, everyone) if sizes is not None else {}
    for key, values, flag in (("params", params, "--params"), ("flops", flops, "--flops")):
        for name, value in TG.parse_counts(values, flag, everyone).items():
            counts.setdefault(name, {})[key] = value
    _add_sizes(report, scored, context, counts)
    _add_groups(report, scored, tagged, context if groups == "all" else [])
    _add_finetune(report, scored, tagged)


def _add_sizes(report, scored, context, counts) -> None:
    from . import sizes as sizes_mod

    points = sizes_mod.collect(scored, context, counts)
    if points:
        report.figures.append((
            "size", "mCE against model size",
            "Each model's mCE against its parameters and its FLOPs per image (a multiply-add "
            "counts 2), log axes: measured by robodepth predict, or given with --params, "
            "--flops and --sizes.", sizes_mod.figure(points, report.benchmark)))


def _add_groups(report, scored, tagged, context) -> None:
    from . import groups as groups_mod

    found = groups_mod.groups(groups_mod.members(scored, tagged, context, report.benchmark))
    for prop, gs in found.items():
        report.figures.append((
            f"groups-{prop}", f"{groups_mod.TITLES[prop]} compared",
            f"CE per corruption of variants of one model that differ only in "
            f"{groups_mod.TITLES[prop].lower()} (the paper's Figs. 3 and 4), one panel per model: the "
            "published columns, or --tag.", groups_mod.figure(prop, gs, report.benchmark)))


def _add_finetune(report, scored, tagged) -> None:
    from . import finetune as FT

    mx = FT.matrix(scored, tagged, report.benchmark)
    if mx is not None:
        report.figures.append((
            "finetune", "Fine-tuning with corruptions",
            "Abs Rel of a model fine-tuned with each corruption (rows, --tag MODEL:finetune=...) "
            "tested on each corruption (columns, mean over the levels), the baseline first; each "
            "column shaded from its lowest to its highest value (the paper's Fig. 6).",
            FT.figure(mx, report.benchmark)))
