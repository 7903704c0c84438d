"""Names whose module is imported on first use, not when the module naming them is imported.

``from shapeverify._lazy import cKDTree`` in place of ``from scipy.spatial import cKDTree``:
``scipy.spatial`` costs 0.2-0.3 s of CPU to import (sparse matrices, Qhull, the array-API
layer), and most commands never build a k-d tree (an inspection against a prepared model does
not), so the command line should not pay for it at start (issue 32 item 7).

The k-d tree is scipy's own class, ``scipy.spatial._ckdtree.cKDTree`` (what
``scipy.spatial.cKDTree`` is), loaded without ``scipy.spatial``'s package:
:func:`kdtree_class`, :func:`bare_scipy_extension`.
"""

from __future__ import annotations

import sys
import threading

__all__ = ["bare_scipy_extension", "cKDTree", "kdtree_class"]

_CLASS = []
_LOCK = threading.Lock()


def cKDTree(*args, **kwargs):  # noqa: N802 - the name of the class it stands for
    """``scipy.spatial.cKDTree(*args, **kwargs)``, the class loaded on first use
    (:func:`kdtree_class`)."""
    cls = _CLASS[0] if _CLASS else kdtree_class()
    return cls(*args, **kwargs)


def kdtree_class() -> type:
    """``scipy.spatial.cKDTree``.  When ``scipy.spatial`` is not imported yet, its compiled
    k-d tree module (``scipy.spatial._ckdtree``) is loaded by itself in ~0.002 s of CPU instead
    of the package's 0.1-0.3 s: the package's ``__init__`` imports Qhull, distances, rotations,
    ``scipy.linalg`` and ``scipy.special``, and the module itself imports ``scipy.sparse`` (for
    ``sparse_distance_matrix``'s output) and ``scipy._lib._util`` (for one constant,
    ``copy_if_needed``), which pull in scipy's array-API layer (it copies numpy's namespace,
    importing ``numpy.f2py`` and ``numpy.testing``).  While the module loads those two are
    placeholders (:func:`bare_scipy_extension`); the module is then taken out of
    ``sys.modules``, so that a later ``import scipy.spatial`` imports it as its submodule
    (Cython hands back the module already made: the same class)."""
    with _LOCK:
        if not _CLASS:
            _CLASS.append(_load_kdtree())
    return _CLASS[0]


def _load_kdtree() -> type:
    if "scipy.spatial" not in sys.modules and "scipy.spatial._ckdtree" not in sys.modules:
        try:
            module = bare_scipy_extension("scipy.spatial._ckdtree", keep=False)
        except Exception:   # noqa: BLE001 - anything unexpected: scipy's own import
            module = None
        if module is not None:
            return module.cKDTree
    from scipy.spatial import cKDTree as cls

    return cls


def bare_scipy_extension(name: str, keep: bool = True):
    """Load scipy's compiled module ``name`` (e.g. ``scipy.spatial._ckdtree``,
    ``scipy.linalg.cython_blas``) without importing its package's ``__init__``; None when it
    is not a compiled module of this scipy or numpy is older than 2 (below).  ``keep``: left in
    ``sys.modules`` (a later ``import name`` finds it there without importing the package;
    the package, when imported, then lacks the attribute ``name``'s last part until something
    imports it through the package), else taken out once made.

    While it loads, ``scipy.sparse`` and ``scipy._lib._util`` (those not imported yet) are
    placeholders: compiled modules import them at load for names they use only when called
    (``scipy.sparse.coo_matrix`` through the ``scipy`` package, which imports the real one on
    that use) or for ``copy_if_needed``, whose value the placeholder gives by scipy's own rule
    (``None`` from numpy 2.0.0 on).  The placeholders are removed afterwards."""
    import importlib.machinery
    import importlib.util
    import os
    import types

    import numpy as np
    import scipy
    import scipy._lib

    if name in sys.modules:
        return sys.modules[name]
    if int(np.__version__.split(".")[0]) < 2:
        return None                     # copy_if_needed is not None there
    package, _, leaf = name.rpartition(".")
    folder = os.path.join(os.path.dirname(scipy.__file__), *package.split(".")[1:])
    path = next((os.path.join(folder, leaf + s) for s in importlib.machinery.EXTENSION_SUFFIXES
                 if os.path.isfile(os.path.join(folder, leaf + s))), None)
    if path is None:
        return None
    sparse = types.ModuleType("scipy.sparse")
    util = types.ModuleType("scipy._lib._util")
    util.copy_if_needed = None          # scipy._lib._util's value from numpy 2.0.0 on
    stand_ins = [(parent, attr, mod) for parent, attr, mod in
                 ((scipy, "sparse", sparse), (scipy._lib, "_util", util))
                 if mod.__name__ not in sys.modules]
    import _imp

    # the placeholders are in sys.modules for the load only: another thread's import waits
    _imp.acquire_lock()
    try:
        for parent, attr, mod in stand_ins:
            sys.modules[mod.__name__] = mod
            setattr(parent, attr, mod)
        loader = importlib.machinery.ExtensionFileLoader(name, path)
        spec = importlib.util.spec_from_file_location(name, path, loader=loader)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        ok = False
        try:
            loader.exec_module(module)
            ok = True
        finally:
            if not (ok and keep):
                sys.modules.pop(name, None)
    finally:
        for parent, attr, mod in stand_ins:
            if sys.modules.get(mod.__name__) is mod:
                del sys.modules[mod.__name__]
            if parent.__dict__.get(attr) is mod:
                delattr(parent, attr)
        _imp.release_lock()
    return module
