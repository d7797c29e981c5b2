"""Benchmark: the exact (same bits on every CPU) filters against the OpenCV calls they
replaced, per corruption, one core.

For each corruption that used a CPU-dependent OpenCV call (defocus_blur, glass_blur,
elastic_transform, frost, near_focus, far_focus), CPU time of one image at every level on the
192 x 640 KITTI-like frame (with bench/depth.py's street depth for the depth-aware two)
and on the 480 x 640 NYU frame, with the current code ("exact") and with the OpenCV call
patched back in ("opencv"), side by side in one process. Then the whole per-image cost of
a build (every corruption of the preset at every level, the unchanged ones timed once)
both ways: the goal is at most 10 % more CPU per image.

    python -m bench.exact [--repeats N]
"""

from __future__ import annotations

import os

# One core: set before numpy / OpenCV / numba are imported.
for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import contextlib  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import scipy.fft  # noqa: E402

from bench import cpu_name  # noqa: E402
from bench.depth import frames  # noqa: E402
from robodepth_cli.corruptions import NAMES, REGISTRY, corrupt  # noqa: E402
from robodepth_cli.building.jobs import _keep_freed_memory  # noqa: E402
from robodepth_cli.corruptions import _lens, _ops, defocus_blur, elastic_transform, frost  # noqa: E402

CHANGED = ("defocus_blur", "glass_blur", "elastic_transform", "frost", "near_focus", "far_focus")
BUDGET = 1.10


def _filter2d(x, k, spectrum_kernel=None):
    return cv2.filter2D(np.ascontiguousarray(x, np.float32), -1, k, borderType=cv2.BORDER_REFLECT_101)


def _defocus_before(x, k, spectrum_kernel=None):
    """defocus_blur's filter before: OpenCV's filter2D up to 11 wide, else a float32 FFT
    with numpy's (CPU-dependent) complex product."""
    if k.shape[0] <= 11:
        return _filter2d(x, k)
    kf = spectrum_kernel.astype(np.float64)
    h, w = x.shape[:2]
    r = k.shape[0] // 2
    padded = cv2.copyMakeBorder(np.ascontiguousarray(x), r, r, r, r, cv2.BORDER_REFLECT_101)
    shape = (scipy.fft.next_fast_len(h + 2 * r, real=True), scipy.fft.next_fast_len(w + 2 * r, real=True))
    spec = scipy.fft.rfft2(padded.astype(np.float32), s=shape, axes=(0, 1), workers=1)
    spec *= scipy.fft.rfft2(kf, s=shape)[:, :, None].astype(np.complex64)
    return scipy.fft.irfft2(spec, s=shape, axes=(0, 1), workers=1)[2 * r:2 * r + h, 2 * r:2 * r + w]


def _separable(src, ky, kx, mode):
    borders = {"reflect": cv2.BORDER_REFLECT, "mirror": cv2.BORDER_REFLECT_101,
               "nearest": cv2.BORDER_REPLICATE, "constant": cv2.BORDER_CONSTANT}
    return cv2.sepFilter2D(src, -1, np.asarray(kx, src.dtype), np.asarray(ky, src.dtype), borderType=borders[mode])


def _remap(x, coords):
    out = cv2.remap(x.astype(np.float32), coords, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return _ops.truncate_to_uint8(out, 1.0)


def _resize(img, size):
    return cv2.resize(img, size, interpolation=cv2.INTER_CUBIC)


@contextlib.contextmanager
def opencv_calls():
    """The modules' exact kernels swapped for the OpenCV calls they replaced."""
    swaps = [(defocus_blur, "correlate2d", _defocus_before), (_lens, "correlate2d", _filter2d),
             (_ops, "separable", _separable), (elastic_transform, "remap_reflect", _remap),
             (frost, "resize_cubic", _resize)]
    saved = [(mod, name, getattr(mod, name)) for mod, name, _ in swaps]
    for mod, name, fn in swaps:
        setattr(mod, name, fn)
    frost.scaled_texture.cache_clear()
    try:
        yield
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)
        frost.scaled_texture.cache_clear()


def cpu_ms(fn, repeats: int) -> float:
    fn()  # warm-up: numba compilation, kernel and texture caches
    runs = []
    for _ in range(repeats):
        t = time.process_time()
        fn()
        runs.append(time.process_time() - t)
    return 1000 * statistics.median(runs)


def per_level(x, depth, name, repeats):
    """CPU ms of one image at every level of ``name``. frost's five resized textures are
    made first: a build makes them once per process and image size."""
    if name == "frost":
        for i in range(len(frost.TEXTURES)):
            frost.scaled_texture(i, x.shape[:2])
    rng = np.random.default_rng(0)
    d = depth if REGISTRY[name].needs_depth else None
    return sum(cpu_ms(lambda: corrupt(x, name, lv, rng, depth=d), repeats)
               for lv in range(1, REGISTRY[name].n_levels + 1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed calls per level (median)")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    _keep_freed_memory()  # as a build's worker does: no fresh pages for every temporary
    print(f"CPU: {cpu_name()}; load average {os.getloadavg()[0]:.2f}; CPU ms per image, all levels summed")
    ok = True
    for label, x, depth in frames():
        names = [n for n in CHANGED if n in NAMES or REGISTRY[n].needs_depth]
        print(f"{label}:\n{'corruption':<18} {'opencv':>8} {'exact':>8} {'ratio':>6}")
        old_total = new_total = 0.0
        for name in names:
            new = per_level(x, depth, name, args.repeats)
            with opencv_calls():
                old = per_level(x, depth, name, args.repeats)
            old_total += old
            new_total += new
            print(f"{name:<18} {old:8.1f} {new:8.1f} {new / old:6.2f}")
        rest = sum(per_level(x, depth, n, 1) for n in NAMES if n not in CHANGED)
        ratio = (rest + new_total) / (rest + old_total)
        print(f"whole image (the 18 + near/far focus, all levels; the rest {rest:.0f} ms): "
              f"{rest + old_total:.0f} -> {rest + new_total:.0f} ms, ratio {ratio:.3f} "
              f"({'within' if ratio <= BUDGET else 'OVER'} the {BUDGET:.2f} budget)")
        ok &= ratio <= BUDGET
        size = frost.scaled_size(frost.texture_bgr(0).shape[:2], x.shape[:2])
        new = cpu_ms(lambda: frost.resize_cubic(frost.texture_bgr(0), size), args.repeats)
        old = cpu_ms(lambda: _resize(frost.texture_bgr(0), size), args.repeats)
        print(f"frost's texture resize, once per process and image size: {old:.1f} -> {new:.1f} ms")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
