"""The dataset card, ``README.md``: the YAML header the Hugging Face Hub and
``datasets.load_dataset`` read (one configuration per variant, one split per level, each
split's files), then what the data is, how it was made, its licence and its citation."""

from __future__ import annotations

import json

from .layout import FORMATS, GT_CONFIG

# Where each source dataset's terms are published: the export copies its images, so they
# apply to it. robodepth cannot decide them; the card says which to check.
SOURCE_TERMS = {
    "kitti": ("KITTI raw data (Geiger, Lenz, Stiller, Urtasun, IJRR 2013)",
              "cc-by-nc-sa-3.0",
              "KITTI's raw data is published under Creative Commons "
              "Attribution-NonCommercial-ShareAlike 3.0; check the terms on the KITTI website "
              "before publishing."),
    "nyu": ("NYU Depth Dataset V2 (Silberman, Hoiem, Kohli, Fergus, ECCV 2012)", "other",
            "Check the terms of NYU Depth V2 on its website before publishing."),
    "custom": ("your own images", "other",
               "The licence of the source images applies; check it before publishing."),
}


def _source(dataset: str) -> tuple[str, str, str]:
    if dataset.startswith("kitti"):
        return SOURCE_TERMS["kitti"]
    return SOURCE_TERMS["nyu" if dataset.startswith("nyu") else "custom"]


def _parameters(variants: list[str]) -> list[str]:
    """The section with the parameters of each level of the exported corruptions (a
    chain's steps included), as ``robodepth list`` gives them; none for styles."""
    from ..corruptions import REGISTRY
    from ..docs import corruption_table

    names = {step.split("-")[0] for v in variants for step in v.split("+")} & set(REGISTRY)
    if not names:
        return []
    return ["## Corruption parameters", "", "Per level, as `robodepth list` states them "
            "(the formulas: robodepth's docs/corruptions.md):", "",
            corruption_table(markdown=True, names=names), ""]


def _severity_line(conf: dict) -> str:
    """The card's line on the severity size (build.json's ``extra.severity_size``; a build
    record without it predates the option: none)."""
    size = (conf.get("extra") or {}).get("severity_size") or "none"
    if size == "none":
        return ("- Severity size: none: each level's blur radii, streaks and flakes are the "
                "tabulated pixels at any image size.")
    return (f"- Severity size: {size} (HxW): each level's spatial parameters (blur radii, streaks, "
            "flakes, warps) are those of an image of that size, scaled to each image by the "
            "square root of the area ratio.")


def card(record, shards: list[dict], fmt: str, version: str) -> str:
    """The card's text for an export of the build ``record`` made of ``shards`` (the
    export record's entries)."""
    from ..report.published import BIBTEX

    ext = FORMATS[fmt]
    configs: dict[str, list[str]] = {}
    for s in shards:
        splits = configs.setdefault(s["config"], [])
        if s["split"] not in splits:
            splits.append(s["split"])
    head = ["---", f"license: {_source(record.dataset)[1]}", f"pretty_name: {record.dataset} "
            "(robodepth build)", "configs:"]
    for config, splits in configs.items():
        head += [f"- config_name: {json.dumps(config)}", "  data_files:"]
        for split in splits:
            head += [f"  - split: {json.dumps(split)}",
                     f"    path: {json.dumps(f'data/{config}/{split}-*.{ext}')}"]
    head.append("---")
    source, _, terms = _source(record.dataset)
    variants = [c for c in configs if c not in ("clean", GT_CONFIG)]
    conf = record.config or {}
    size = conf.get("size")
    body = [
        f"# {record.dataset}, built by robodepth",
        "",
        f"The images of a `robodepth build {record.dataset}` of {len(record.keys or [])} images of "
        f"{source}, byte for byte as built ({fmt} shards). Each configuration is one variant: "
        f"`clean`, {', '.join(f'`{v}`' for v in variants) or 'no corruption'}"
        f"{', and `' + GT_CONFIG + '` (the ground truth, once)' if GT_CONFIG in configs else ''}; "
        "each split one level (`level_3`) or `test` for a variant without levels. Every row "
        "has the image's key (its path in the split), variant, level, seed and sha256.",
        "",
        "## How it was made",
        "",
        f"- robodepth {record.robodepth or 'unknown'} built it; robodepth {version} exported it.",
        f"- Seed {record.seed}; levels {conf.get('levels')}; size "
        f"{'x'.join(map(str, size)) + ' (HxW)' if size else 'each image its own'}.",
        _severity_line(conf),
        f"- Corruption parameters: the RoboDepth benchmark's, as robodepth {record.robodepth} "
        "states them (`robodepth list`); the build's whole configuration and command are in "
        "`robodepth/build.json`, and `robodepth/manifest.csv` lists every file with its sha256 "
        "(`robodepth verify` checks an export against it).",
        f"- Command: `{' '.join(record.command)}`" if record.command else "",
        "",
        *_parameters(variants),
        "## Licence to check",
        "",
        terms + " The corruptions add no terms of their own.",
        "",
        "## Citation",
        "",
        "```bibtex",
        BIBTEX,
        "```",
        "",
    ]
    return "\n".join(head + [""] + [b for b in body if b is not None]) + "\n"
