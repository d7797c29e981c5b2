"""Benchmark: what hashing each source image costs a build.

The manifest records each source's size, modification time and sha256, so that a source
replaced under the same name redoes its outputs. The hash was to be kept only if it costs
under 2% of a build; this measures it, in one process and one thread (the work of one
build worker), on a KITTI-sized source (375 x 1242 PNG) and an NYU-sized one (480 x 640
JPEG), both synthetic (smooth colour plus sensor-like noise, so the files have the size
of the real ones):

- hash: ``sha256`` of the source file (warm page cache; best of 20);
- full build of that source: decode + Lanczos resize, every corruption at every level of
  the dataset, PNG encoding of all outputs (the clean one too): what a worker spends on it;
- smallest build: the same with one cheap corruption at one level (``--corruptions
  contrast --levels 1``), the case where the hash weighs most;
- rerun with nothing to do: sha256 of the existing outputs, which a rerun re-checks.

A warm-up pass on another image compiles the numba kernels first.

    python -m bench.source_hash
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import hashlib  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402


from robodepth_cli.benchmark_facts import BENCHMARKS  # noqa: E402
from robodepth_cli.corruptions import corrupt  # noqa: E402
from robodepth_cli.imageio import encode_png, load_clean  # noqa: E402
from robodepth_cli.files import sha256_file  # noqa: E402
from robodepth_cli.seeding import job_rng  # noqa: E402


def synthetic(h: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 16, w // 16, 3), dtype=np.uint8)
    smooth = np.asarray(Image.fromarray(small).resize((w, h), Image.BICUBIC), dtype=np.float64)
    return np.clip(smooth + rng.normal(0, 6, smooth.shape), 0, 255).astype(np.uint8)


def render(path: Path, size, names, levels) -> tuple[float, list[bytes]]:
    t0 = time.process_time()
    clean = load_clean(path, size)
    outputs = [encode_png(clean)]
    for name in names:
        for lv in levels:
            outputs.append(encode_png(corrupt(clean, name, lv, job_rng(0, "bench", name, lv, path.name))))
    return time.process_time() - t0, outputs


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def case(label, tmp: Path, shape, ext, size, names, levels) -> None:
    warm = tmp / f"warm{ext}"
    src = tmp / f"src{ext}"
    Image.fromarray(synthetic(*shape, 1)).save(warm, quality=95)
    Image.fromarray(synthetic(*shape, 2)).save(src, quality=95)
    render(warm, size, names, levels)  # numba compilation, caches
    hash_s = best(lambda: sha256_file(src), 20)
    full_s, outputs = render(src, size, names, levels)
    small_s, _ = render(src, size, names[:1], levels[:1])
    rerun_s = best(lambda: [hashlib.sha256(o).hexdigest() for o in outputs], 5)
    print(f"{label}: source {src.stat().st_size / 1e3:.0f} kB; sha256 {hash_s * 1e3:.2f} ms")
    print(f"  full build of the source ({len(outputs)} PNGs): {full_s:.2f} s CPU"
          f" -> hash = {100 * hash_s / full_s:.3f}%")
    print(f"  one corruption at one level (2 PNGs): {small_s * 1e3:.0f} ms CPU"
          f" -> hash = {100 * hash_s / small_s:.2f}%")
    print(f"  rerun with nothing to do (hash the {len(outputs)} outputs): {rerun_s * 1e3:.1f} ms"
          f" -> source hash adds {100 * hash_s / rerun_s:.1f}%")


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        kc, ny = BENCHMARKS["kitti-c"], BENCHMARKS["nyudepth2-c"]
        case("KITTI-C (192 x 640)", tmp, (375, 1242), ".png", (192, 640),
             ["contrast", *[n for n in kc.corruptions if n != "contrast"]], list(kc.levels))
        case("NYUDepth2-C (480 x 640)", tmp, (480, 640), ".jpg", (480, 640),
             ["contrast", *[n for n in ny.corruptions if n != "contrast"]], list(ny.levels))


if __name__ == "__main__":
    main()
