"""The layout of a build's output directory: every name robodepth writes into OUT, and the
rule that places each output. Nothing else in the package spells these names.

::

    OUT/manifest.csv             one row per output file (:data:`MANIFEST`)
    OUT/build.json               the build record (:data:`RECORD`)
    OUT/.robodepth.lock          held by the build writing here (:data:`LOCK`)
    OUT/.robodepth.journal/      rows of the outputs written, one file per worker, while a
                                 build runs (:data:`JOURNAL`; see :class:`.folder.Journal`)
    OUT/clean/<key>              the resized clean images
    OUT/<corruption>/<level>/<key>
    OUT/<style>/<key>            KITTI-S: styles have no level
    OUT/<chain dir>/<key>        a chain of corruptions, e.g. fog-3+gaussian_noise-2.5/
    OUT/gt_depths.npz            KITTI ground truth, monodepth2's format (:data:`GT_FILE`)
    OUT/gt/<depth path>          NYU ground truth, BTS's layout (:data:`GT_DIR`)
    OUT/gt/<key stem>.npy        a build with depth (custom --depth, the zero-shot presets):
                                 float32 metres, NaN where invalid, at the map's own size

``<key>`` is the dataset-relative path of the source image with the extension ``.png``
(KITTI: ``kitti_data/<date>/<drive>/image_02/data/<frame>.png``), so each variant directory
mirrors the benchmark's own tree.
"""

from __future__ import annotations

from ..benchmark_facts import CLEAN
from ..corruptions.severity import level_text

MANIFEST = "manifest.csv"
RECORD = "build.json"
LOCK = ".robodepth.lock"
JOURNAL = ".robodepth.journal"  # a directory
BOOKKEEPING = frozenset({MANIFEST, RECORD, LOCK})
GT_FILE = "gt_depths.npz"
GT_DIR = "gt"
# A neighbour frame's manifest params begin with it and its test frame's key (--frames).
NEIGHBOUR_OF = "neighbour_of="
# A torch-engine output's manifest params hold it, so the two engines' files never mix.
TORCH_FINGERPRINT = "engine=torch"
# A scaled output's manifest params name its severity size: ``severity_size=HxW``.
SEVERITY_SIZE = "severity_size="

__all__ = ["MANIFEST", "RECORD", "LOCK", "JOURNAL", "BOOKKEEPING", "GT_FILE", "GT_DIR", "CLEAN",
           "NEIGHBOUR_OF", "TORCH_FINGERPRINT", "SEVERITY_SIZE",
           "variant_dir", "output_path", "depth_gt_name",
           "variant_order"]


def variant_dir(variant: str, level: float | None) -> str:
    """``clean``, ``<corruption>/<level>``, ``<style>`` or a chain's directory name: a
    variant's directory under OUT (and, with ``.npy``, its prediction file under PRED).
    ``level`` is None for the clean images, styles and chains; an integer level is written
    ``3``, a decimal one ``2.5``; a chain (its canonical text ``fog:3+gaussian_noise:2.5``
    or its directory name) by its directory name ``fog-3+gaussian_noise-2.5``."""
    if level is not None:
        return f"{variant}/{level_text(level)}"
    from ..corruptions.chains import looks_like_chain, parse_chain

    return parse_chain(variant).dirname if looks_like_chain(variant) else variant


def output_path(variant: str, level: float | None, key: str) -> str:
    """The path of one output relative to OUT: ``<variant dir>/<key>``."""
    return f"{variant_dir(variant, level)}/{key}"



def depth_gt_name(key: str) -> str:
    """Where a build with depth keeps the ground truth of the image with ``key``, relative
    to :data:`GT_DIR`: the key with ``.npy`` for its ``.png``."""
    return key[: -len(".png")] + ".npy" if key.endswith(".png") else key + ".npy"


def variant_order(ds, built) -> list[tuple[str, int | float | None]]:
    """The ``(variant, level)`` pairs of ``built`` that are variants of dataset ``ds``, in
    the order of its results: clean, the benchmark's corruptions (or styles) with levels
    ascending, the depth-aware ones, the corruptions over time of a build with --frames,
    then the chains by name."""
    from ..benchmark_facts import TEMPORAL, looks_like_chain

    order = [CLEAN, *ds.variant_names(), *ds.depth_variant_names(), *TEMPORAL,
             *sorted({v for v, _ in built if looks_like_chain(v)})]
    return sorted((vl for vl in built if vl[0] in order),
                  key=lambda vl: (order.index(vl[0]), vl[1] or 0))
