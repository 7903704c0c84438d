"""numba kernels that pack the DVG tree's seed lists (private; used by
:func:`shapeverify.nearest.dvg_build._pack_lists`).

The multi-seed leaves of a level give (M, 16) rows of seeds with counts.  Each distinct list
(the same seeds in any order) is stored once as (count, seeds...), the lists in lexicographic
order of their sorted seeds, a missing seed counting as larger than any (the order
``np.unique(axis=0)`` gave on rows padded with the int32 maximum).  The rows are ordered by a
64-bit key of their first two seeds (a stable numpy sort), and only runs of equal keys that
hold a longer row are merge-sorted by the full comparison: the order of a stable sort by the
full comparison, without its 20 passes of row comparisons over the whole array.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_MISSING = 2147483647  # a missing second seed in the key (larger than any point index)


@njit(cache=True, nogil=True, inline="always")
def _row_less(seeds, cnt, i, j):
    """Row i before row j: lexicographic over the sorted seeds, a missing seed counting as
    larger than any (as int32 max padding sorts)."""
    n = min(cnt[i], cnt[j])
    for k in range(n):
        a = seeds[i, k]
        b = seeds[j, k]
        if a != b:
            return a < b
    return cnt[i] > cnt[j]


@njit(cache=True, nogil=True)
def sort_rows(seeds, cnt):
    """Sorts each row's ``cnt`` seeds in place (insertion sort, at most 16); returns the rows'
    keys (M,) int64: first seed * 2**31 + second seed (``_MISSING`` for a single seed), whose
    order is the order of the rows' first two seeds under :func:`_row_less`."""
    m = seeds.shape[0]
    key = np.empty(m, dtype=np.int64)
    for i in range(m):
        for v in range(1, cnt[i]):
            x = seeds[i, v]
            w = v
            while w > 0 and seeds[i, w - 1] > x:
                seeds[i, w] = seeds[i, w - 1]
                w -= 1
            seeds[i, w] = x
        s1 = seeds[i, 1] if cnt[i] > 1 else _MISSING
        key[i] = (np.int64(seeds[i, 0]) << 31) | np.int64(s1)
    return key


@njit(cache=True, nogil=True)
def _merge_run(seeds, cnt, order, tmp, r0, r1):
    """Stable bottom-up merge sort of ``order[r0:r1]`` by :func:`_row_less` (``tmp``:
    scratch of the same length as ``order``)."""
    src = order
    dst = tmp
    width = 1
    passes = 0
    while width < r1 - r0:
        for lo in range(r0, r1, 2 * width):
            mid = min(lo + width, r1)
            hi = min(lo + 2 * width, r1)
            a = lo
            b = mid
            for k in range(lo, hi):
                if a < mid and (b >= hi or not _row_less(seeds, cnt, src[b], src[a])):
                    dst[k] = src[a]
                    a += 1
                else:
                    dst[k] = src[b]
                    b += 1
        src, dst = dst, src
        width *= 2
        passes += 1
    if passes % 2 == 1:  # the sorted run is in tmp
        for k in range(r0, r1):
            order[k] = src[k]


@njit(cache=True, nogil=True)
def pack_sorted(seeds, cnt, key, order):
    """The rows in ``order`` (a stable sort by ``key``, :func:`sort_rows`) put in the order of
    a stable sort by :func:`_row_less` (runs of equal keys holding a row of more than two
    seeds merge-sorted), and each distinct list stored once as (count, seeds...).  Returns
    (buffer int32, offset of each row's list (M,) int64)."""
    m = seeds.shape[0]
    tmp = np.empty(m, dtype=np.int64)
    r0 = 0
    while r0 < m:
        r1 = r0 + 1
        longer = cnt[order[r0]] > 2
        while r1 < m and key[order[r1]] == key[order[r0]]:
            longer |= cnt[order[r1]] > 2
            r1 += 1
        if r1 - r0 > 1 and longer:
            _merge_run(seeds, cnt, order, tmp, r0, r1)
        r0 = r1
    pos_of = tmp  # reused: offset of each row's list
    total = 0
    for k in range(m):
        i = order[k]
        if k > 0:
            j = order[k - 1]
            same = cnt[i] == cnt[j]
            if same:
                for s in range(cnt[i]):
                    if seeds[i, s] != seeds[j, s]:
                        same = False
                        break
            if same:
                pos_of[i] = pos_of[j]
                continue
        pos_of[i] = total
        total += cnt[i] + 1
    buf = np.empty(total, dtype=np.int32)
    for i in range(m):
        p = pos_of[i]
        buf[p] = cnt[i]
        for s in range(cnt[i]):
            buf[p + 1 + s] = seeds[i, s]
    return buf, pos_of
