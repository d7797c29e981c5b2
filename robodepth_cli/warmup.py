"""``python -m robodepth_cli.warmup``: compile every numba kernel of the package into its
on-disk cache now (``make install`` runs it), so that no command waits for a compile later.
Each kernel is compiled for exactly the argument types it meets, by running every
corruption at every level and a decimal one on small frames of :data:`SHAPES` (the scaled
ones also at a smaller and a larger severity size), then ``evaluate``'s kernels. Run it
again after upgrading numba, on another CPU, or with ``NUMBA_CACHE_DIR`` set
(docs/development.md)."""

from __future__ import annotations

import sys
import time

# Frames (H, W) whose sizes together give each kernel every argument layout it meets on any
# frame: the snow layer cut to the image is a view for some sizes, a whole array for others;
# the fog map is a view of a wider array when the width is odd.
SHAPES = ((64, 96), (97, 65))
LEVELS = (1, 2, 2.5, 3, 4, 5)
# Severity sizes as multiples of the frame's size: without one (None), below and above it.
SEVERITY_FACTORS = (None, 0.5, 2)


def kernels() -> dict[str, object]:
    """Every numba dispatcher defined in a loaded module of the package, by its
    ``module.name``."""
    from numba.core.registry import CPUDispatcher

    found = {}
    for name, module in list(sys.modules.items()):
        if name == __package__ or name.startswith(__package__ + "."):
            for value in vars(module).values():
                if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name:
                    found[f"{name}.{value.py_func.__qualname__}"] = value
    return found


def warm_up() -> tuple[dict[str, object], dict[str, str]]:
    """Run every corruption at each of :data:`LEVELS` on a random frame and its depth of
    each of :data:`SHAPES` (those with a size rule at each of :data:`SEVERITY_FACTORS`),
    which compiles (or loads from the cache) every kernel they call. Returns
    (:func:`kernels`, {corruption: why it could not run} for those that refused, such as
    frost without its textures)."""
    import numpy as np

    from .corruptions import REGISTRY, render
    from .errors import RobodepthError

    rng = np.random.default_rng(0)
    refused = {}
    for h, w in SHAPES:
        image = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        depth = rng.uniform(1.0, 80.0, (h, w)).astype(np.float32)
        for name, corruption in REGISTRY.items():
            for factor in SEVERITY_FACTORS if corruption.scaled else (None,):
                size = None if factor is None else (int(h * factor), int(w * factor))
                for level in LEVELS:
                    if name in refused:
                        break
                    try:
                        render(image, name, level, seed=0, dataset="image", key="warmup", depth=depth,
                               severity_size=size)
                    except RobodepthError as exc:
                        refused[name] = str(exc)
    _warm_evaluation(rng)
    return kernels(), refused


def _warm_evaluation(rng) -> None:
    """Judge small maps as ``evaluate`` does (the evaluation's kernels): float32 and
    float64 predictions, writable and read-only (a mapped ``.npy``), one at a time and a
    variant's block at a time, under the kitti protocol's modes and the nyu protocol,
    against ground truth as sparse pixels (int32 indices) and as a whole 16-bit map, each
    held in memory and mapped read-only from a file (the ground-truth cache's, or
    ``--jobs N``'s)."""
    import os
    import tempfile

    import numpy as np

    from .evaluation.batch import Plan
    from .evaluation.image import image_errors
    from .evaluation.protocols import make_setup
    from .groundtruth.read import GroundTruth

    h, w = 48, 160
    gt = np.zeros((h, w), np.float32)
    index = np.flatnonzero(rng.random(h * w) < 0.3).astype(np.int32)
    gt.reshape(-1)[index] = rng.uniform(1.0, 70.0, index.size).astype(np.float32)
    truth = ((h, w), index, gt.reshape(-1)[index])
    raw = (rng.uniform(0.5, 9.0, (480, 640)) * 1000).astype(np.uint16)  # NYU's size (its crop)
    nyu_index = np.flatnonzero(raw > 0).astype(np.int32)
    nyu_truth = (raw.shape, nyu_index, (raw.reshape(-1)[nyu_index] / np.float32(1000)).astype(np.float32))
    setups = [make_setup("kitti", kind, stereo, align=align) for kind, stereo, align in
              (("disp", False, None), ("disp", True, None), ("depth", False, None),
               ("sigmoid", False, None), ("disp", False, "scale-shift"), ("depth", False, "none"))]
    nyu = make_setup("nyu", "depth")
    # The same maps as a variant's N x h x w array, judged a block at a time (evaluate's
    # way): against the sparse map, NYU's whole one and NYU's as its pixels.
    kitti_gt, nyu_gt, nyu_pixels = (GroundTruth("warmup", p, make_setup(p).valid) for p in ("kitti", "nyu", "nyu"))
    kitti_gt.add(gt)
    nyu_gt.add(raw / np.float32(1000), raw, 1000.0)
    few = np.zeros(raw.shape, np.float32)  # valid pixels few enough to be kept as such
    few[60:400:7, 50:600:7] = rng.uniform(0.5, 9.0, few[60:400:7, 50:600:7].shape)
    nyu_pixels.add(few)
    with tempfile.TemporaryDirectory(prefix="robodepth-warmup-") as tmp:
        # and as mapped from a file (read-only arrays: the ground-truth cache's, --jobs N's)
        kitti_mapped, nyu_mapped, pixels_mapped = (
            held.share(os.path.join(tmp, f"{k}.bin")).open() for k, held in enumerate((kitti_gt, nyu_gt, nyu_pixels)))
        for dtype in (np.float32, np.float64):
            for readonly in (False, True):
                pred = rng.uniform(0.05, 0.9, (h // 2, w // 2)).astype(dtype)
                dense = rng.uniform(0.5, 9.0, raw.shape).astype(dtype)
                for p in (pred, dense):
                    p.flags.writeable = not readonly
                for setup in setups:
                    for pixels, held in ((truth, kitti_gt), (kitti_mapped.get(0), kitti_mapped)):
                        image_errors(pred, "warmup", pixels, setup, None)
                        Plan(held, setup, pred.shape, pred.dtype).judge(pred[None], 0, 1)
                image_errors(dense, "warmup", None, nyu, None, whole=(raw, 1000.0))
                image_errors(dense, "warmup", None, nyu, None, whole=nyu_mapped.dense(0))
                image_errors(dense, "warmup", nyu_truth, nyu, None)
                for held in (nyu_gt, nyu_pixels, nyu_mapped, pixels_mapped):
                    Plan(held, nyu, dense.shape, dense.dtype).judge(dense[None], 0, 1)

def main() -> int:
    """Warm up and say what was done in one line (and one per corruption that refused:
    its kernels compile on first use once it can run); exit status 0."""
    start = time.perf_counter()
    found, refused = warm_up()
    compiled = sum(sum(d.stats.cache_misses.values()) for d in found.values())
    loaded = sum(sum(d.stats.cache_hits.values()) for d in found.values())
    for name, why in refused.items():
        print(f"warmup: {name} not compiled: {why}")
    print(f"warmup: {len(found)} numba kernels, {compiled + loaded} signatures: {compiled} compiled "
          f"and cached, {loaded} already in the cache ({time.perf_counter() - start:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
