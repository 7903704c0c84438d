"""What the three samplers of :mod:`shapeverify.cad.sampling` share (private).

The spacing ratios (Poisson-disk radius and candidate step per spacing), the point limit, the
greedy Poisson-disk thinning (spatial hash with cells of the disk radius; Bridson 2007), the
accumulator of sample columns, the count check made before any fine work and the
near-a-free-edge flag.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from shapeverify._lazy import cKDTree

#: Largest number of model points :func:`sample_model` agrees to make.
MAX_POINTS = 20_000_000

_RADIUS = 0.85  # Poisson-disk radius / spacing
_CAND = 0.5  # candidate step / spacing
_COS_SAME_SIDE = -0.5  # points whose normals differ by more than 120 deg do not suppress each other
_BATCH_CANDIDATES = 4_000_000


# ------------------------------------------------------------------------------ thinning
@njit(cache=True)
def _hash_slot(keys, key, mask):
    h = (key * 0x9E3779B1 + (key >> 29)) & mask
    while keys[h] != -1 and keys[h] != key:
        h = (h + 1) & mask
    return h


@njit(cache=True)
def _thin_kernel(P, N, r, cos_min, use_normals, keep):
    """Greedy Poisson-disk thinning in the given order (spatial hash, cells of size r)."""
    n = P.shape[0]
    if n == 0:
        return
    lo = np.empty(3)
    for k in range(3):
        lo[k] = P[0, k]
        for i in range(n):
            if P[i, k] < lo[k]:
                lo[k] = P[i, k]
    inv = 1.0 / r
    cell = np.empty((n, 3), np.int64)
    dims = np.zeros(3, np.int64)
    for i in range(n):
        for k in range(3):
            c = np.int64((P[i, k] - lo[k]) * inv)
            cell[i, k] = c
            if c + 1 > dims[k]:
                dims[k] = c + 1
    size = 1
    while size < 2 * n + 16:
        size *= 2
    mask = size - 1
    keys = np.full(size, -1, np.int64)
    head = np.full(size, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    r2 = r * r
    for i in range(n):
        ok = True
        for dx in range(-1, 2):
            cx = cell[i, 0] + dx
            if cx < 0 or cx >= dims[0] or not ok:
                continue
            for dy in range(-1, 2):
                cy = cell[i, 1] + dy
                if cy < 0 or cy >= dims[1] or not ok:
                    continue
                for dz in range(-1, 2):
                    cz = cell[i, 2] + dz
                    if cz < 0 or cz >= dims[2]:
                        continue
                    key = cx + dims[0] * (cy + dims[1] * cz)
                    h = _hash_slot(keys, key, mask)
                    j = head[h] if keys[h] == key else -1
                    while j >= 0:
                        d0 = P[i, 0] - P[j, 0]
                        d1 = P[i, 1] - P[j, 1]
                        d2 = P[i, 2] - P[j, 2]
                        if d0 * d0 + d1 * d1 + d2 * d2 < r2:
                            if not use_normals or (N[i, 0] * N[j, 0] + N[i, 1] * N[j, 1]
                                                   + N[i, 2] * N[j, 2]) > cos_min:
                                ok = False
                                break
                        j = nxt[j]
                    if not ok:
                        break
        if ok:
            keep[i] = True
            key = cell[i, 0] + dims[0] * (cell[i, 1] + dims[1] * cell[i, 2])
            h = _hash_slot(keys, key, mask)
            keys[h] = key
            nxt[i] = head[h]
            head[h] = i


def _thin(P, N, r, order=None, use_normals=True):
    """Indices (into P) of the points kept by the Poisson-disk thinning, visiting ``order``
    (default: the given order)."""
    if order is None:
        Po, No = np.ascontiguousarray(P), (np.ascontiguousarray(N) if use_normals else None)
    else:
        Po = np.ascontiguousarray(P[order])
        No = np.ascontiguousarray(N[order]) if use_normals else None
    if len(Po) == 0:
        return np.empty(0, np.int64)
    if No is None:
        No = np.zeros((1, 3))
    ext = Po.max(axis=0) - Po.min(axis=0)
    if np.prod(ext / r + 2.0) > 2.0 ** 62:
        raise ValueError(f"spacing {r / _RADIUS!r} is too small for a model of extent "
                         f"{ext.max():.6g}; use a larger spacing")
    keep = np.zeros(len(Po), np.bool_)
    _thin_kernel(Po, No, float(r), _COS_SAME_SIDE, use_normals, keep)
    kept = np.flatnonzero(keep)
    return kept if order is None else np.asarray(order)[kept]


class _Parts:
    """Accumulated sample columns (points, normals, Su-direction, face, uv)."""

    def __init__(self):
        self.P, self.N, self.T, self.F, self.UV = [], [], [], [], []

    def add(self, P, N, T, F, UV):
        self.P.append(P)
        self.N.append(N)
        self.T.append(T)
        self.F.append(F)
        self.UV.append(UV)

    def cat(self):
        if not self.P:
            return (np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)),
                    np.empty(0, np.int32), np.empty((0, 2)))
        return (np.concatenate(self.P), np.concatenate(self.N), np.concatenate(self.T),
                np.concatenate(self.F).astype(np.int32), np.concatenate(self.UV))


def _cross(a, b):
    """Row-wise cross product (faster than np.cross for (N, 3))."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _near(samples, pts, s):
    if not samples or len(pts) == 0:
        return np.zeros(len(pts), bool)
    tree = cKDTree(np.concatenate(samples))
    dist, _ = tree.query(pts, k=1, distance_upper_bound=s)
    return np.isfinite(dist)


def _check_count(area, s):
    n = area / (s * s)
    if not np.isfinite(n) or n > MAX_POINTS:
        smin = math.sqrt(area / MAX_POINTS) if np.isfinite(area) else float("nan")
        raise ValueError(
            f"spacing {s!r} mm on a surface of about {area:.6g} mm^2 would make about {n:.3g} "
            f"model points (limit {MAX_POINTS:,}); use spacing >= {smin:.3g} mm")
