"""``python -m robodepth_cli.warmup``: compile every numba kernel of the package into its
on-disk cache now, so that no command waits for a compile later.

``make install`` runs it. Each kernel is compiled for exactly the argument types the
corruptions give it (numba compiles one specialisation per dtype, dimension count, layout
and writability), by running them: every corruption, the depth-aware ones with a depth map,
at every whole level and a decimal one, on small frames of :data:`SHAPES` (each layout a
kernel meets at some image size), and those with a size rule also at a severity size
smaller and larger than the frame (their scaled paths). The cache is the one the package reads at run time
(``robodepth_cli/corruptions/_jit.py`` says where). Run it again after upgrading numba, on
another CPU, or with ``NUMBA_CACHE_DIR`` set to the folder the commands will use.
"""

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
    return kernels(), refused


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
