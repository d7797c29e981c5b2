"""numba compilation with an on-disk cache that also serves a read-only install: every numba
kernel of the package is made by :func:`njit`, its machine code cached on disk so that a
process loads it instead of compiling it (``python -m robodepth_cli.warmup`` fills the
cache). Where the cache is written and read, and what an entry is keyed on, are
docs/development.md's."""

from __future__ import annotations

import inspect
import os
import stat
import tempfile

import numba
from numba.core.caching import (
    CompileResultCacheImpl,
    FunctionCache,
    IndexDataCacheFile,
    InTreeCacheLocator,
    UserProvidedCacheLocator,
    UserWideCacheLocator,
)

def _probe_blas_without_scipy() -> None:
    """Load numba's array registry now, with its probe for a BLAS answered from the files
    of SciPy's ``cython_blas`` instead of by importing ``scipy.linalg``. numba loads the
    registry before the first kernel of a process runs or is read from the cache, and its
    probe (``numba.np.arraymath._HAVE_BLAS``, which picks the code of ``np.dot`` of two
    vectors) imports ``scipy.linalg``: 0.17 s of every process that runs a kernel, a
    worker of ``evaluate --jobs`` or of a build included (0.34 against 0.51 s to a first
    kernel's result). The answer is the same: whether that module is there. Left to numba
    when the registry is loaded already or its names are not where this numba has them."""
    import importlib.machinery
    import importlib.util
    import sys

    if "numba.np.arraymath" in sys.modules:
        return
    try:
        import numba.np.linalg as linalg

        real = linalg.ensure_blas
    except (ImportError, AttributeError):
        return

    def probe() -> None:
        spec = importlib.util.find_spec("scipy")  # finds it, imports nothing
        folders = list(spec.submodule_search_locations or ()) if spec else []
        if not any(os.path.isfile(os.path.join(f, "linalg", "cython_blas" + suffix))
                   for f in folders for suffix in importlib.machinery.EXTENSION_SUFFIXES):
            raise ImportError("scipy 0.16+ is required for linear algebra")

    linalg.ensure_blas = probe
    try:
        import numba.np.arraymath as arraymath  # sets _HAVE_BLAS with the probe
    finally:
        linalg.ensure_blas = real
    if getattr(arraymath, "ensure_blas", None) is probe:
        arraymath.ensure_blas = real


_probe_blas_without_scipy()


def _fallback_cache_dir() -> str:
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    return os.path.join(tempfile.gettempdir(), f"robodepth-numba-{uid}")


def _own_private_dir(path: str) -> bool:
    """Whether ``path`` is a folder of this user that no one else may write: the cache holds
    pickles and machine code, so a folder in a shared /tmp that someone else made (or may
    write into) must not be read."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    mine = not hasattr(os, "getuid") or st.st_uid == os.getuid()
    return stat.S_ISDIR(st.st_mode) and mine and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


class _TempDirLocator(UserProvidedCacheLocator):
    """The last writable place: ``robodepth-numba-UID`` under the system temporary folder,
    made with mode 0700 and used only while it is this user's alone."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self._cache_path = os.path.join(_fallback_cache_dir(), self.get_suitable_cache_subpath(py_file))

    def ensure_cache_path(self):
        root = _fallback_cache_dir()
        os.makedirs(root, mode=0o700, exist_ok=True)
        if not _own_private_dir(root):
            raise OSError(f"{root}: not this user's private folder")
        super().ensure_cache_path()

    @classmethod
    def from_function(cls, py_func, py_file):
        # The mixin's from_function, not UserProvidedCacheLocator's (which needs NUMBA_CACHE_DIR).
        return super(UserProvidedCacheLocator, cls).from_function(py_func, py_file)


class _Impl(CompileResultCacheImpl):
    _locator_classes = [UserProvidedCacheLocator, InTreeCacheLocator, UserWideCacheLocator, _TempDirLocator]


class _Cache(FunctionCache):
    """numba's cache in the first writable place above, read from there and then from the
    package's own ``__pycache__``; a cache that cannot be saved costs a compile, never an
    error."""

    _impl_class = _Impl

    def __init__(self, py_func):
        super().__init__(py_func)
        shipped = os.path.join(os.path.dirname(os.path.abspath(inspect.getfile(py_func))), "__pycache__")
        self._shipped = None
        if os.path.abspath(self._cache_path) != shipped and os.path.isdir(shipped):
            self._shipped = IndexDataCacheFile(shipped, self._impl.filename_base,
                                               self._impl.locator.get_source_stamp())

    def _load_overload(self, sig, target_context):
        data = super()._load_overload(sig, target_context)
        if data is None and self._enabled and self._shipped is not None:
            data = self._shipped.load(self._index_key(sig, target_context.codegen()))
            if data is not None:
                data = self._impl.rebuild(target_context, data)
        return data

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        except OSError:  # the folder became unwritable (or full) since: the code is compiled
            pass


def njit(fn):
    """``numba.njit(cache=True, nogil=True)(fn)``, usable as a decorator, with the cache
    above; when no folder at all can be written, the kernel is compiled once per process."""
    dispatcher = numba.njit(nogil=True)(fn)
    try:
        dispatcher._cache = _Cache(fn)  # what cache=True's enable_caching() sets, our class
    except RuntimeError:  # "cannot cache function ...: no locator available"
        pass
    return dispatcher
