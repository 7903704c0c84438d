"""The numba passes behind :mod:`shapeverify._arrays` (private; imported on first use)."""

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
