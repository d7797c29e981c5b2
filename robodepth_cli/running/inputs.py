"""What ``robodepth run`` needs before its first prediction, all checked before any work:
the build configuration's sources (each decoded once, as a build decodes it), the variants
in the order of the results, the renderer of the chosen engine, and the ground truth read
from the root into memory.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..api import Variant
from ..output.layout import variant_order
from ..building.config import BuildConfig
from ..building.gather import check_root, gather_sources
from ..building.jobs import Source, load_source
from ..errors import RobodepthError
from ..building.renderers import Renderer
from ..sources.datasets import Dataset, Job, get_dataset, preset_names

ENGINES = ("numpy", "torch")


class RunError(RobodepthError):
    """A run that cannot start (its dataset, root, sources, ground truth or engine)."""


@dataclass
class RunInputs:
    cfg: BuildConfig
    ds: Dataset
    root: Path  # absolute
    split: dict  # gather_sources' account: path, sha256, keys
    sources: list[Source]
    variants: list[tuple[Variant, Job]]  # in the order of the results CSV

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(s.key for s in self.sources)


def engine_flags(engine: str, device: str) -> dict:
    """The one place where ``run`` chooses its corruption engine: the configuration flags
    that select it (none for the numpy engine, the default of every build); the build's
    configuration checks the device."""
    if engine not in ENGINES:
        raise RunError(f"--engine {engine!r}: valid: {', '.join(ENGINES)}")
    if engine == "numpy":
        return {}
    return {"engine": "torch", "device": device}


def check_dataset(name: str) -> Dataset:
    """The dataset ``run`` can judge a model on: a corruption benchmark with ground truth."""
    ds = get_dataset(name)
    if ds.discovers_sources or not ds.leveled:
        benchmarks = ", ".join(preset_names(lambda d: d.leveled and not d.discovers_sources))
        raise RunError(f"{name}: run judges a model on the corruption benchmarks ({benchmarks}); "
                       f"build {name} and use predict and evaluate")
    return ds


def gather(cfg: BuildConfig, root: Path, out: Path) -> RunInputs:
    """The run's sources and variants; :class:`RunError` for a source the split lists that
    cannot be used (every image is needed to evaluate a variant)."""
    ds = check_dataset(cfg.dataset)
    typed_root, root = root, check_root(root, labeled_ok=ds.split_format == "nyu")
    sources, split = gather_sources(ds, cfg, root, Path(out), typed_root)
    bad = [s for s in sources if s.error]
    if bad:
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        raise RunError(f"{bad[0].error}{more}; every image of the split is needed to evaluate "
                       "a variant (--limit N: only the first N)")
    keys = tuple(s.key for s in sources)
    jobs = {(j.variant, j.level): j for j in ds.jobs(cfg.variants, cfg.levels)}
    variants = [(Variant(Path(out).parent, name, level, keys), jobs[name, level])
                for name, level in variant_order(ds, set(jobs))]
    return RunInputs(cfg, ds, root, split, sources, variants)


def decode(inputs: RunInputs, progress=None) -> list[np.ndarray]:
    """Every source image decoded and resized once, as a build makes its clean images,
    read-only (the renderers take them as they are); :class:`RunError` for one that cannot
    be read."""
    from concurrent.futures import ThreadPoolExecutor

    def one(src: Source) -> np.ndarray:
        clean, message = load_source(src, inputs.cfg.size)
        if clean is None:
            raise RunError(message)
        clean.flags.writeable = False
        if progress:
            progress(1)
        return clean

    with ThreadPoolExecutor(max(1, min(4, os.cpu_count() or 1))) as pool:
        return list(pool.map(one, inputs.sources))


def renderer(inputs: RunInputs) -> Renderer:
    """The build's renderer for this configuration (the engine :func:`engine_flags` chose)."""
    from ..building.pipeline import make_renderer

    return make_renderer(inputs.ds, inputs.cfg, inputs.root, inputs.split.get("path"), inputs.sources)


def ground_truth(inputs: RunInputs, setup):
    """The ground truth of the run's images, read from the root into memory with the readers
    of ``robodepth gt`` and ``evaluate``: the same maps a build writes beside its images
    (KITTI: from the velodyne scans; NYU: the split's depth PNGs, or the labeled file)."""
    from ..groundtruth.read import GroundTruth, load_ground_truth

    split_path = Path(inputs.split["path"])
    n = len(inputs.sources)
    if inputs.ds.split_format == "eigen":
        from ..groundtruth import kitti as kitti_raw

        frames = kitti_raw.read_frames(split_path)[:n]
        missing = kitti_raw.missing_velodyne(inputs.root, frames)
        if missing:
            more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
            raise RunError(f"no ground truth: {missing[0].velodyne(inputs.root)} (split line "
                           f"{missing[0].line}){more} missing; the run needs every frame's scan")
        truth = GroundTruth(f"{inputs.root} (velodyne scans)", setup.protocol, setup.valid)
        for depth in kitti_raw.depth_maps(inputs.root, frames, str(split_path)):
            truth.add(depth)
        return truth
    from ..groundtruth import nyu as nyu_labeled

    frames = nyu_labeled.read_frames(split_path)[:n]
    if inputs.root.is_file():
        labeled = nyu_labeled.opened(inputs.root)
        truth = GroundTruth(str(inputs.root), setup.protocol, setup.valid)
        for f in frames:
            raw = nyu_labeled.sync_depth(labeled.depth(nyu_labeled.frame_index(labeled, f.rgb)))
            truth.add(raw.astype(np.float32) / 1000.0, raw, 1000.0)
        return truth
    missing = [f for f in frames if not (inputs.root / f.depth).is_file()]
    if missing:
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        raise RunError(f"no ground truth: {inputs.root / missing[0].depth} (split line "
                       f"{missing[0].line}){more} missing; the run needs every image's depth")
    return load_ground_truth(inputs.root, [f.depth for f in frames], setup.protocol, setup.valid)
