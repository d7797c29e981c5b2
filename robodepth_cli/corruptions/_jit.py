"""numba compilation with an on-disk cache that also works from a read-only install."""

from __future__ import annotations

import os
import tempfile

import numba


def _fallback_cache_dir() -> str:
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    return os.path.join(tempfile.gettempdir(), f"robodepth-numba-{uid}")


def njit(fn):
    """``numba.njit(cache=True, nogil=True)(fn)``, usable as a decorator.

    The compiled code is cached on disk so that each worker process of a build loads it
    instead of compiling again (about a second per kernel). numba caches next to the
    module, else under ``NUMBA_CACHE_DIR`` or ``~/.cache/numba``; when none of these is
    writable (read-only install and home) it raises at decoration time, so the cache then
    goes to a per-user directory under the system temporary directory, and if even that
    fails the kernel is compiled without a cache, once per process.
    """
    try:
        return numba.njit(cache=True, nogil=True)(fn)
    except RuntimeError:  # "cannot cache function ...: no locator available"
        pass
    if not numba.config.CACHE_DIR:
        path = _fallback_cache_dir()
        try:
            os.makedirs(path, mode=0o700, exist_ok=True)
            numba.config.CACHE_DIR = path
            return numba.njit(cache=True, nogil=True)(fn)
        except (OSError, RuntimeError):
            numba.config.CACHE_DIR = ""
    return numba.njit(cache=False, nogil=True)(fn)
