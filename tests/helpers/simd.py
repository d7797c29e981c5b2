"""The stand-ins for other CPUs: environment variables that switch each library's SIMD
paths (or its CPU model) off, for the same-bytes-on-any-CPU tests."""

from __future__ import annotations


def opencv_features() -> str:
    """Every CPU feature OpenCV dispatches on, by the names OPENCV_CPU_DISABLE takes (its
    build information spells a few differently), with the ones they imply."""
    import cv2

    line = next(ln for ln in cv2.getBuildInformation().splitlines() if "Dispatched code generation" in ln)
    spelled = {"SSE4_1": "SSE4.1", "SSE4_2": "SSE4.2", "AVX512_SKX": "AVX512-SKX"}
    names = [spelled.get(n, n) for n in line.split(":", 1)[1].split()]
    return ",".join(names + ["POPCNT", "FMA3", "AVX512F"])


def numpy_features() -> str:
    """numpy's run-time dispatched features this CPU has (its baseline cannot be switched off)."""
    from numpy._core import _multiarray_umath as umath

    return ",".join(f for f in umath.__cpu_dispatch__ if umath.__cpu_features__.get(f))


def stand_ins() -> dict[str, dict[str, str]]:
    alone = {
        "opencv": {"OPENCV_CPU_DISABLE": opencv_features()},
        "ipp": {"OPENCV_IPP": "disabled"},
        "numpy": {"NPY_DISABLE_CPU_FEATURES": numpy_features()},
        "numba": {"NUMBA_CPU_NAME": "generic"},
        "libjpeg-turbo": {"JSIMD_FORCENONE": "1"},
    }
    return {**alone, "all": {k: v for env in alone.values() for k, v in env.items()}}
