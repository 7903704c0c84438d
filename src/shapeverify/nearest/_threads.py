"""Both cores for the closest-point kernels: queries split into contiguous chunks, each run
by a thread of one shared pool on the (``nogil``) numba kernels.

Every query is answered independently of the others, so the answers are identical for any
number of workers.  :func:`set_workers` (or the environment variable
``SHAPEVERIFY_WORKERS``) sets how many; 1 runs everything in the calling thread (e.g. in a
service that already runs one request per core).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

__all__ = ["set_workers", "get_workers", "run_chunks"]

MIN_CHUNK = 8192  # fewer queries per worker are not worth a thread hand-off

_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None
_workers: int | None = None


def _default() -> int:
    env = os.environ.get("SHAPEVERIFY_WORKERS", "").strip()
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            raise ValueError(f"SHAPEVERIFY_WORKERS must be a whole number >= 1, got {env!r}") \
                from None
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
               else (os.cpu_count() or 1))


def set_workers(n: int | None) -> None:
    """Threads used by ``Prepared.closest`` (None: every core the process may use).

    Raises
    ------
    ValueError
        If ``n`` is not None or a whole number >= 1.
    """
    global _workers, _pool
    if n is not None and (isinstance(n, bool) or int(n) != n or n < 1):
        raise ValueError(f"workers must be a whole number >= 1 or None, got {n!r}")
    with _lock:
        _workers = None if n is None else int(n)
        if _pool is not None:
            _pool.shutdown(wait=False)
            _pool = None


def get_workers() -> int:
    """The number of threads ``Prepared.closest`` uses."""
    return _default() if _workers is None else _workers


def run_chunks(fn, n: int, min_chunk: int = MIN_CHUNK) -> None:
    """Call ``fn(lo, hi)`` on contiguous chunks covering ``range(n)``, in parallel."""
    global _pool
    w = min(get_workers(), n // max(1, min_chunk))
    if w <= 1:
        fn(0, n)
        return
    with _lock:
        if _pool is None or _pool._max_workers < w:  # noqa: SLF001 - size check only
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(max_workers=w, thread_name_prefix="shapeverify-closest")
        pool = _pool
    # a few chunks per thread: a thread the OS holds back does not hold up the others
    k = min(4 * w, max(w, n // max(1, min_chunk)))
    cuts = np.linspace(0, n, k + 1).astype(np.int64)
    futures = [pool.submit(fn, int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:])]
    for f in futures:
        f.result()
