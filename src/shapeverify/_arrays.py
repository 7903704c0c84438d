"""Small array helpers shared by the packages (private): fast one-pass checks of (N, 3) point
arrays, and write-protected result arrays.

numpy's ``np.isfinite(a).all(axis=1)`` and ``a.min(axis=0)`` on a narrow (N, 3) array cost
0.4-0.8 ms per 30,000 points (axis reductions over 3 columns); the inspection path ran about
twenty of them per scan.  One numba pass does each in a few microseconds.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _count_nonfinite_rows(a):
    n = 0
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            if not np.isfinite(a[i, j]):
                n += 1
                break
    return n


@njit(cache=True, nogil=True)
def _bounds(a, lo, hi):
    for j in range(a.shape[1]):
        lo[j] = np.inf
        hi[j] = -np.inf
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            x = a[i, j]
            if x < lo[j]:
                lo[j] = x
            if x > hi[j]:
                hi[j] = x


def count_nonfinite_rows(a: np.ndarray) -> int:
    """Rows of the 2-D float array ``a`` holding a NaN or an infinity."""
    if a.size == 0:
        return 0
    with np.errstate(invalid="ignore", over="ignore"):   # inf - inf, huge + huge
        if np.isfinite(a.sum()):                # a sum is finite only if every value is
            return 0
    return int(_count_nonfinite_rows(np.ascontiguousarray(a, dtype=np.float64)))


def bounds(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Column-wise (min, max) of a finite, non-empty 2-D float array."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    lo = np.empty(a.shape[1])
    hi = np.empty(a.shape[1])
    _bounds(a, lo, hi)
    return lo, hi


def readonly(a) -> np.ndarray:
    """A C-contiguous, write-protected array (a copy only when ``a`` is not C-contiguous)."""
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a
