"""Costs of a command's first kernel that its answer does not need (issue 32 item 7).

Installed by the command line before it imports the inspection
(:func:`shapeverify.cli_start.preimport`) and by the resident worker's preload; the library
itself leaves numba and scipy as they are.

* :func:`defer_numba_registries`: before it loads a kernel from its on-disk cache, numba
  refreshes its target context (``Cache.load_overload`` calls ``target_context.refresh()``):
  the first refresh imports every typing and lowering registry numba has (``numba.cpython.*``,
  ``numba.np.*``, ``numba.typed``, ``numba.experimental`` ...) and installs them, ~0.2 s of
  CPU.  A cached kernel needs none of it: its machine code links only against the symbols the
  context registers when it is made (numba's C helpers, the math library), the NRT runtime
  (``rtsys.initialize``) and the hash secret (``numba.cpython.hashing``, for kernels that hash).
  On a cache miss numba refreshes as before and compiles (its compiler refreshes too).  While
  a kernel loads, llvmlite's lock callbacks (numba's compile-timing events) are off.  The
  kernels run the same machine code: the same answers.
* :func:`import_numba`: ``import numba`` with PyYAML left unimported.  numba imports ``yaml``
  only to read a ``.numba_config.yaml`` in the working directory (18 modules, ~0.02-0.03 s of
  CPU); its config module gets a stand-in that imports PyYAML when numba reads such a file, so
  a config file still counts exactly as before.
"""

from __future__ import annotations

import sys
import types

__all__ = ["KERNEL_ENV_MODULES", "defer_numba_registries", "import_kernel_env_modules",
           "import_numba"]

#: numba's modules that the cached kernels of an inspection name in their environments (the
#: functions they inlined from numba's array, math, sort and linalg implementations): a kernel
#: that loads imports them (21 modules, ~0.1 s).  Imported with the other modules of the
#: command's start, so that the resident worker freezes them with its preload (``gc.freeze``)
#: instead of walking them at every later collection.
KERNEL_ENV_MODULES = ("numba.core.optional", "numba.cpython.charseq", "numba.cpython.mathimpl",
                      "numba.cpython.numbers", "numba.cpython.slicing", "numba.cpython.unicode",
                      "numba.misc.mergesort", "numba.misc.quicksort", "numba.np.arraymath",
                      "numba.np.arrayobj", "numba.np.linalg", "numba.np.npdatetime",
                      "numba.np.npyfuncs", "numba.np.npyimpl")


def defer_numba_registries() -> bool:
    """Make numba load cached kernels without its registries (see the module); idempotent.
    False when this numba lacks what it relies on (then numba is left as it is)."""
    try:
        from numba.core import caching
        from numba.core.runtime import rtsys
    except ImportError:
        return False
    cache = caching.Cache
    if getattr(cache.load_overload, "_shapeverify_deferred", False):
        return True
    if not all(hasattr(cache, n) for n in ("_load_overload", "_guard_against_spurious_io_errors")):
        return False

    def load_overload(self, sig, target_context):
        rtsys.initialize(target_context)          # the NRT symbols; once
        import numba.cpython.hashing  # noqa: F401 - the hash secret's symbols

        data = None
        with _quiet_llvm_lock(), self._guard_against_spurious_io_errors():
            data = self._load_overload(sig, target_context)
        if data is None:                          # a miss: numba compiles next, as before
            target_context.refresh()
        return data

    load_overload._shapeverify_deferred = True
    load_overload.__doc__ = cache.load_overload.__doc__
    cache.load_overload = load_overload
    return True


class _quiet_llvm_lock:
    """While a cached kernel loads: llvmlite's lock held (reentrant) and its callbacks off.
    numba makes every llvmlite call (~300 per kernel loaded: symbols, bitcode) start and end a
    ``numba:llvm_lock`` event, which only times compilations; ~0.035 s of the 21 loads.  The
    lock is held while they are off, so another thread's call cannot start an event whose end
    would be skipped."""

    def __enter__(self):
        try:
            from llvmlite.binding import ffi

            self._lock = ffi.lib._lock
            self._lock._lock.acquire()
        except (ImportError, AttributeError):
            self._lock = None
            return self
        self._saved, self._lock._cblist = self._lock._cblist, []
        return self

    def __exit__(self, *exc):
        if self._lock is not None:
            self._lock._cblist = self._saved
            self._lock._lock.release()
        return False


def import_kernel_env_modules() -> None:
    """Import :data:`KERNEL_ENV_MODULES` (those this numba has).  ``numba.np.arraymath`` asks
    at import whether BLAS is there (``import scipy.linalg.cython_blas``), and the noise
    kernels' ``eigh`` looks up LAPACK's ``dsyevd`` in ``scipy.linalg.cython_lapack`` on its
    first call: both compiled modules are loaded by themselves first
    (:func:`shapeverify._lazy.bare_scipy_extension`, ~0.01 s), without the package
    ``scipy.linalg`` (its array-API layer and the rest, ~0.1 s), which nothing of an
    inspection uses."""
    import importlib

    if "scipy.linalg" not in sys.modules:
        from shapeverify._lazy import bare_scipy_extension

        for name in ("scipy.linalg.cython_blas", "scipy.linalg.cython_lapack"):
            try:
                bare_scipy_extension(name)
            except Exception:   # noqa: BLE001 - then numba imports scipy.linalg as before
                pass
    for name in KERNEL_ENV_MODULES:
        try:
            importlib.import_module(name)
        except ImportError:
            pass


class _YamlOnUse(types.ModuleType):
    """Stands for the ``yaml`` module in numba's config: PyYAML is imported when numba uses it
    (a ``.numba_config.yaml`` is read) and answers as itself.  Dunder names (what the import
    system and ``inspect`` probe on every module) are not PyYAML's: AttributeError."""

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        if sys.modules.get("yaml") is self:
            del sys.modules["yaml"]
        import yaml

        return getattr(yaml, name)


def import_numba() -> None:
    """``import numba`` without importing PyYAML (see the module); a plain import when numba
    or PyYAML is imported already."""
    if "numba" in sys.modules or "yaml" in sys.modules:
        import numba  # noqa: F401
        return
    stand_in = _YamlOnUse("yaml")
    sys.modules["yaml"] = stand_in
    try:
        import numba  # noqa: F401
    finally:
        if sys.modules.get("yaml") is stand_in:
            del sys.modules["yaml"]     # the next ``import yaml`` imports PyYAML itself
