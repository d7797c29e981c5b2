"""Facts about the RoboDepth benchmarks, in one light module.

The corruption names in benchmark order, the category of each, each benchmark's own
corruptions and levels, and the published baselines. Everything that needs one of these
facts (the corruption registry, the build configuration, ``robodepth score`` and its chart)
reads it from here. This module imports nothing beyond the standard library, so scoring a
results file or checking a configuration never loads the corruption engine (numba, OpenCV)
or torch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

from .errors import InvalidValueError

# The paper, as the report page and an export's dataset card cite it.
BIBTEX = """@inproceedings{kong2023robodepth,
  title     = {RoboDepth: Robust Out-of-Distribution Depth Estimation under Corruptions},
  author    = {Kong, Lingdong and Xie, Shaoyuan and Hu, Hanjiang and Ng, Lai Xing and
               Cottereau, Benoit R. and Ooi, Wei Tsang},
  booktitle = {Advances in Neural Information Processing Systems (NeurIPS), Datasets and Benchmarks Track},
  year      = {2023}
}"""

WEATHER = "weather & lighting"
SENSOR = "sensor & movement"
DATA = "data & processing"
CATEGORIES = (WEATHER, SENSOR, DATA)

CLEAN = "clean"
"""The uncorrupted image: a build's ``clean/`` variant and the ``clean`` row of a results file."""

# Every corruption in benchmark order (the order of every listing, table and score), with
# its category.
CATEGORY: dict[str, str] = {
    "brightness": WEATHER, "dark": WEATHER, "fog": WEATHER, "frost": WEATHER, "snow": WEATHER,
    "contrast": WEATHER,
    "defocus_blur": SENSOR, "glass_blur": SENSOR, "motion_blur": SENSOR, "zoom_blur": SENSOR,
    "elastic_transform": SENSOR, "color_quant": SENSOR,
    "gaussian_noise": DATA, "impulse_noise": DATA, "shot_noise": DATA, "iso_noise": DATA,
    "pixelate": DATA, "jpeg_compression": DATA,
}
CORRUPTIONS: tuple[str, ...] = tuple(CATEGORY)
N_LEVELS = 5  # every corruption defines levels 1..5; a benchmark may use fewer
# The corruptions over time (corruptions/temporal.py): they act on a test frame's sequence,
# so a KITTI build makes them only with --frames. Not part of any benchmark's score.
TEMPORAL: tuple[str, ...] = ("frame_lost", "frame_freeze", "h264_crf", "h265_crf", "bit_error")

# Corruptions beyond the benchmarks, made from the scene's depth as well as its image
# (docs/depth-aware-corruptions.md). No benchmark, score or baseline includes them, and
# 'all' never selects them: they need a depth map that not every input has.
DEPTH_AWARE: dict[str, str] = {
    "fog_3d": WEATHER, "near_focus": SENSOR, "far_focus": SENSOR, "motion_3d": SENSOR,
    "zoom_3d": SENSOR, "rain_3d": WEATHER,
}
ALL_CATEGORY: dict[str, str] = {**CATEGORY, **DEPTH_AWARE}
"""Every corruption robodepth makes, the benchmarks' 18 first, with its category."""
ALL_CORRUPTIONS: tuple[str, ...] = tuple(ALL_CATEGORY)


@dataclass(frozen=True)
class Baseline:
    """A reference model: its clean DEE and its level-averaged DEE per corruption."""

    name: str
    clean: float
    dee: Mapping[str, float]


@dataclass(frozen=True)
class Benchmark:
    """One corruption benchmark: its corruptions (in benchmark order), its levels
    ``1..n_levels`` and the published baseline its CE is measured against."""

    name: str
    corruptions: tuple[str, ...]
    n_levels: int
    baseline: Baseline | None  # None: no published one (:func:`unpublished`)
    # The levels when they are not all of 1..n_levels: an unpublished dataset's are those
    # its results (or its build) have, e.g. (1, 3).
    level_set: tuple[int, ...] | None = None

    @property
    def levels(self) -> Sequence[int]:
        return self.level_set if self.level_set is not None else range(1, self.n_levels + 1)


def _baseline(name: str, clean: float, corruptions: tuple[str, ...], dees: str) -> Baseline:
    values = [float(v) for v in dees.split()]
    if len(values) != len(corruptions):
        raise ValueError(f"baseline {name}: {len(values)} values for {len(corruptions)} corruptions")
    return Baseline(name, clean, dict(zip(corruptions, values)))


# NYU Depth V2 is indoors: no fog, frost or snow, and only the four milder levels.
_NYU = tuple(n for n in CORRUPTIONS if n not in ("fog", "frost", "snow"))

# The published baselines: level-averaged DEE, the clean DEE apart, in benchmark order.
BENCHMARKS: dict[str, Benchmark] = {
    "kitti-c": Benchmark("kitti-c", CORRUPTIONS, 5, _baseline(
        "MonoDepth2 R18, 640x192", 0.119, CORRUPTIONS,
        ".130 .280 .155 .277 .511 .187 .244 .242 .216 .201 .129 .193 .384 .389 .340 .388 "
        ".145 .196")),
    "nyudepth2-c": Benchmark("nyudepth2-c", _NYU, 4, _baseline(
        "AdaBins EfficientNet-B5", 0.112, _NYU,
        ".132 .194 .212 .235 .206 .184 .384 .153 .151 .390 .374 .294 .380 .124 .154")),
}


def unpublished(name: str, corruptions: tuple[str, ...] = CORRUPTIONS,
                n_levels: int = N_LEVELS, levels: Sequence[int] | None = None) -> Benchmark:
    """The benchmark of a dataset without a published baseline (by default every corruption
    at levels 1..5; a build of fewer: those it has, at ``levels`` when given), baseline None."""
    chosen = tuple(sorted(set(levels))) if levels else None
    return Benchmark(name, tuple(c for c in CORRUPTIONS if c in corruptions),
                     max(chosen) if chosen else n_levels, None, chosen)


def get_benchmark(name: str) -> Benchmark:
    """The benchmark called ``name``; :class:`InvalidValueError` listing the valid names otherwise."""
    try:
        return BENCHMARKS[name]
    except KeyError:
        raise InvalidValueError(f"unknown benchmark {name!r}; valid: {', '.join(BENCHMARKS)}") from None


def looks_like_chain(text: str) -> bool:
    """Whether a variant name is meant as a chain (it has a ``:`` or a ``+``) rather than a
    single corruption's name."""
    return isinstance(text, str) and (":" in text or "+" in text)
