"""The dataset card, ``README.md``: the YAML header the Hugging Face Hub and
``datasets.load_dataset`` read (one configuration per variant, one split per level, each
split's files), then what the data is, how it was made, its licence and its citation."""

from __future__ import annotations

import json

from ..errors import counted
from .layout import FORMATS, GT_CONFIG, NEIGHBOURS

NEIGHBOUR_TEXT = (", and `<split>_neighbours` (`level_3_neighbours`) the neighbour frames of a "
                  "build with `--frames`, by key: a frame's key holds its frame number")

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
    "custom": ("your own folder of images", "other",
               "The licence of the source images applies; check it before publishing."),
}


def _source(dataset: str) -> tuple[str, str, str]:
    """(where the images come from, as the card's first sentence names it, the licence
    id, the terms to check)."""
    if dataset.startswith("kitti"):
        return SOURCE_TERMS["kitti"]
    if dataset.startswith("nyu"):
        return SOURCE_TERMS["nyu"]
    name, licence, terms = SOURCE_TERMS["custom"]
    # A zero-shot set (diode-c, ...) is built from its own download, not from your folder.
    return (name if dataset == "custom" else f"the {dataset.removesuffix('-c')} download",
            licence, terms)


def _parameters(variants: list[str]) -> list[str]:
    """The section with the parameters of each level of the exported corruptions (a
    chain's steps included), as ``robodepth list`` gives them; none for styles."""
    from ..corruptions import REGISTRY
    from ..listing import corruption_table

    names = {step.split("-")[0] for v in variants for step in v.split("+")} & set(REGISTRY)
    if not names:
        return []
    return ["## Corruption parameters", "", "Per level, as `robodepth list` states them "
            "(the formulas: robodepth's docs/corruptions.md):", "",
            corruption_table(markdown=True, names=names), ""]


def holdings(shards, rows: dict) -> dict[str, dict]:
    """What the export holds, per configuration (:class:`~.plan.Shard` s): its ``levels``,
    ``seeds``, ``engines`` (``numpy``, ``torch``; none for the clean images and the
    ground truth) and ``severity`` sizes (``HxW`` or ``none``, for the variants a severity
    size changes), from the manifest ``rows`` of its files: every build request into the
    build counts, not only the last."""
    from ..corruptions import scaled_variant
    from ..output.layout import SEVERITY_SIZE, TORCH_FINGERPRINT

    held: dict[str, dict] = {}
    for s in shards:
        h = held.setdefault(s.config, {"levels": set(), "seeds": set(), "engines": set(),
                                       "severity": set()})
        scaled = s.config not in ("clean", GT_CONFIG) and scaled_variant(s.config)
        for item in s.items:
            if item.level is not None:
                h["levels"].add(item.level)
            h["seeds"].add(item.seed)
            if s.config not in ("clean", GT_CONFIG):
                params = rows[item.output].parsed.parts()
                h["engines"].add("torch" if TORCH_FINGERPRINT in params else "numpy")
                if scaled:
                    h["severity"].add(next((p[len(SEVERITY_SIZE):] for p in params
                                            if p.startswith(SEVERITY_SIZE)), "none"))
    return {c: {k: sorted(v) for k, v in h.items()} for c, h in held.items()}


def _held_lines(held: dict[str, dict]) -> list[str]:
    """One line per configuration: its levels, seeds, engines and severity sizes."""
    from ..sourcekeys import level_text

    lines = []
    for config, h in held.items():
        parts = [f"levels {', '.join(level_text(lv) for lv in h['levels'])}" if h["levels"] else "",
                 f"seed {', '.join(map(str, h['seeds']))}",
                 f"{' and '.join(h['engines'])} engine" if h["engines"] else "",
                 f"severity size {', '.join(h['severity'])}" if h.get("severity") else ""]
        lines.append(f"- `{config}`: " + "; ".join(p for p in parts if p))
    return lines


def _yaml(record, configs: dict[str, list[str]], ext: str) -> list[str]:
    """The YAML header: the licence, the name, each configuration's splits and their files."""
    head = ["---", f"license: {_source(record.dataset)[1]}", f"pretty_name: {record.dataset} "
            "(robodepth build)", "configs:"]
    for config, splits in configs.items():
        head += [f"- config_name: {json.dumps(config)}", "  data_files:"]
        for split in splits:
            head += [f"  - split: {json.dumps(split)}",
                     f"    path: {json.dumps(f'data/{config}/{split}-*.{ext}')}"]
    return head + ["---"]


def card(record, shards: list[dict], fmt: str, version: str, held: dict[str, dict]) -> str:
    """The card's text for an export of the build ``record`` made of ``shards`` (the
    export record's entries) holding ``held`` (:func:`holdings`)."""
    from ..benchmark_facts import BIBTEX

    configs: dict[str, list[str]] = {}
    for s in shards:
        splits = configs.setdefault(s["config"], [])
        if s["split"] not in splits:
            splits.append(s["split"])
    head = _yaml(record, configs, FORMATS[fmt])
    source, _, terms = _source(record.dataset)
    variants = [c for c in configs if c not in ("clean", GT_CONFIG)]
    conf = record.config or {}
    size = conf.get("size")
    body = [
        f"# {record.dataset}, built by robodepth",
        "",
        f"The images of a `robodepth build {record.dataset}` of "
        f"{counted(len(record.keys or []), 'image')} from {source}, byte for byte as built ({fmt} shards). Each configuration is one variant: "
        f"`clean`, {', '.join(f'`{v}`' for v in variants) or 'no corruption'}"
        f"{', and `' + GT_CONFIG + '` (the ground truth: one row per image, `depth` its map, float32 metres, NaN where there is no measurement)' if GT_CONFIG in configs else ''}; "
        "each split one level (`level_3`) or `test` for a variant without levels"
        f"{NEIGHBOUR_TEXT if any(s['split'].endswith(NEIGHBOURS) for s in shards) else ''}. Every row "
        "has the image's key (its path in the split), variant, level, seed and sha256.",
        "",
        "## What it holds",
        "",
        *_held_lines(held),
        "",
        "## How it was made",
        "",
        f"- robodepth {record.robodepth or 'unknown'} built it; robodepth {version} exported it.",
        f"- Size {'x'.join(map(str, size)) + ' (HxW)' if size else 'each image its own'}.",
        "- Severity size (above, per configuration): `none` keeps each level's blur radii, "
        "streaks and flakes at the tabulated pixels at any image size; `HxW` takes the "
        "spatial parameters of an image of that size, scaled to each image by the square root "
        "of the area ratio." if any(h.get("severity") for h in held.values()) else "",
        f"- Corruption parameters: the RoboDepth benchmark's, as robodepth {record.robodepth} "
        "states them (`robodepth list`); the build's whole configuration and command are in "
        "`robodepth/build.json`, and `robodepth/manifest.csv` lists every file with its sha256 "
        "(`robodepth verify` checks an export against it).",
        f"- The last build command into it: `{' '.join(record.command)}`" if record.command else "",
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
