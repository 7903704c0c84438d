"""numba kernels: the k nearest model points of every model point on a uniform grid (private;
used by :func:`shapeverify.nearest.dvg.neighbor_graph`), the other-face links of ``prepare``
(:func:`other_face_first`) and the Morton codes of
:func:`shapeverify.nearest.dvg.morton_order`.

Model points sample a surface about ``spacing`` apart, so a grid of cells of twice the spacing
holds a few points per cell and the 9 nearest points of a point lie in its own and the 26
neighbouring cells (rings of cells further out are searched until the k-th distance is
certain).  The answers are those of scipy's ``cKDTree.query`` (nearest first): the squared
distances are formed the same way (``((0 + e0^2) + e1^2) + e2^2``), and a point whose sorted
distances have a near tie (relative gap below ``1e-12``, where the kd-tree's order among equal
distances is its own) is flagged, so that the caller asks the kd-tree for that point.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _slot(keys, key, mask):
    h = (key * 0x9E3779B1 + (key >> 29)) & mask
    while keys[h] != -1 and keys[h] != key:
        h = (h + 1) & mask
    return h


@njit(cache=True, nogil=True, inline="always")
def _gap(d, f, cell):
    """Squared gap along one axis between a point (``f`` from its cell's lower side) and the
    cell ``d`` cells away (a lower bound, max(0, ...) clipped)."""
    if d == 0:
        return 0.0
    g = (d - 1) * cell + (cell - f) if d > 0 else (-d - 1) * cell + f
    g = max(g, 0.0)
    return g * g


@njit(cache=True, nogil=True)
def grid_cells(points, lo, cell):
    """Bin the points on a grid of side ``cell`` from corner ``lo``: (gc (N, 3) int64 cell
    coordinates, dims (3,), keys (hash table of the occupied cells), cstart (start of each
    table slot's run in ``order``, -1 if empty), cend, order (points sorted by cell),
    sorted coordinates (N, 3))."""
    n = points.shape[0]
    gc = np.empty((n, 3), dtype=np.int64)
    dims = np.zeros(3, dtype=np.int64)
    for i in range(n):
        for a in range(3):
            g = np.int64((points[i, a] - lo[a]) / cell)
            gc[i, a] = g
            dims[a] = max(dims[a], g + 1)
    size = 1
    while size < 2 * n + 16:
        size *= 2
    mask = size - 1
    keys = np.full(size, -1, dtype=np.int64)
    count = np.zeros(size, dtype=np.int64)
    slot = np.empty(n, dtype=np.int64)
    for i in range(n):
        key = (gc[i, 0] * dims[1] + gc[i, 1]) * dims[2] + gc[i, 2]
        h = _slot(keys, key, mask)
        keys[h] = key
        count[h] += 1
        slot[i] = h
    cstart = np.full(size, -1, dtype=np.int64)
    cend = np.full(size, -1, dtype=np.int64)
    pos = 0
    for i in range(n):  # runs in order of first appearance
        h = slot[i]
        if cstart[h] < 0:
            cstart[h] = pos
            cend[h] = pos
            pos += count[h]
    order = np.empty(n, dtype=np.int64)
    xyz = np.empty((n, 3))
    for i in range(n):
        h = slot[i]
        j = cend[h]
        order[j] = i
        xyz[j, 0] = points[i, 0]
        xyz[j, 1] = points[i, 1]
        xyz[j, 2] = points[i, 2]
        cend[h] = j + 1
    return gc, dims, keys, cstart, cend, order, xyz


@njit(cache=True, nogil=True)
def knn(points, lo, cell, gc, dims, keys, cstart, cend, order, xyz, k, a, b, out_i, out_d2,
        tie):
    """The k + 1 nearest points (the point itself included) of points a..b-1, nearest first,
    into ``out_i`` (b - a, k + 1) int64 and ``out_d2`` (squared distances); ``tie[i - a]``
    True where two of the k + 1 sorted squared distances are within a relative 1e-12 (or
    fewer than k + 1 points exist): the order or the set of the first k may then be the
    kd-tree's own."""
    mask = keys.shape[0] - 1
    kk = k + 1
    n = points.shape[0]
    for i in range(a, b):
        r = i - a
        q0 = points[i, 0]
        q1 = points[i, 1]
        q2 = points[i, 2]
        cnt = 0
        # distance from q to the border of its own cell (the radius ring 0 surely covers)
        edge = np.inf
        fx = points[i, 0] - (lo[0] + cell * gc[i, 0])
        fy = points[i, 1] - (lo[1] + cell * gc[i, 1])
        fz = points[i, 2] - (lo[2] + cell * gc[i, 2])
        edge = max(min(fx, cell - fx, fy, cell - fy, fz, cell - fz), 0.0)
        R = 0
        while True:
            for dx in range(-R, R + 1):
                cx = gc[i, 0] + dx
                if cx < 0 or cx >= dims[0]:
                    continue
                for dy in range(-R, R + 1):
                    cy = gc[i, 1] + dy
                    if cy < 0 or cy >= dims[1]:
                        continue
                    ring_xy = abs(dx) == R or abs(dy) == R
                    gxy = _gap(dx, fx, cell) + _gap(dy, fy, cell)
                    for dz in range(-R, R + 1):
                        if not ring_xy and abs(dz) != R:
                            continue
                        cz = gc[i, 2] + dz
                        if cz < 0 or cz >= dims[2]:
                            continue
                        if cnt == kk and gxy + _gap(dz, fz, cell) > out_d2[r, kk - 1] * (
                                1.0 + 1e-9):
                            continue  # the cell is farther than the k-th point
                        h = _slot(keys, (cx * dims[1] + cy) * dims[2] + cz, mask)
                        if keys[h] == -1:
                            continue
                        for s in range(cstart[h], cend[h]):
                            e0 = xyz[s, 0] - q0
                            e1 = xyz[s, 1] - q1
                            e2 = xyz[s, 2] - q2
                            d = ((0.0 + e0 * e0) + e1 * e1) + e2 * e2
                            if cnt == kk and d >= out_d2[r, kk - 1]:
                                continue
                            w = cnt if cnt < kk else kk - 1
                            while w > 0 and out_d2[r, w - 1] > d:
                                if w < kk:
                                    out_d2[r, w] = out_d2[r, w - 1]
                                    out_i[r, w] = out_i[r, w - 1]
                                w -= 1
                            out_d2[r, w] = d
                            out_i[r, w] = order[s]
                            if cnt < kk:
                                cnt += 1
            reach = R * cell + edge
            if cnt == kk and out_d2[r, kk - 1] <= reach * reach * (1.0 - 1e-9):
                break
            if cnt >= n or (R > dims[0] and R > dims[1] and R > dims[2]):
                break
            R += 1
        t = cnt < kk
        for w in range(1, cnt):
            if out_d2[r, w] - out_d2[r, w - 1] <= 1e-12 * out_d2[r, w]:
                t = True
        tie[r] = t


@njit(cache=True, nogil=True)
def morton_codes(g):
    """Morton (Z-order) codes of (N, 3) int64 grid coordinates of at most 21 bits: bit b of
    axis a goes to bit 3 b + a."""
    n = g.shape[0]
    code = np.zeros(n, dtype=np.int64)
    for i in range(n):
        c = np.int64(0)
        for bit in range(21):
            for ax in range(3):
                c |= ((g[i, ax] >> bit) & 1) << (3 * bit + ax)
        code[i] = c
    return code


@njit(cache=True, nogil=True)
def other_face_first(points, face, lo, cell, gc, dims, keys, cstart, cend, order, xyz, cand,
                     k, out, flag):
    """For each point i = cand[c]: among its k nearest points (itself included) closer than
    ``cell`` (the grid's side, so its own and the 26 neighbouring cells hold them all), the
    first of another face, as scipy's ``cKDTree.query(k=k, distance_upper_bound=cell)`` lists
    them; into ``out[c]`` (-1: none).  That is the nearest point a of another face if fewer
    than k points are closer than a.  ``flag[c]`` is set where the answer depends on the
    kd-tree's own order: another point's distance is within a relative 1e-12 of a's (a tie
    for the first place or across the k-th), a distance is within a relative 1e-9 of the
    bound, or more than 1024 points lie within it.  Squared distances are formed as the
    kd-tree forms them."""
    mask = keys.shape[0] - 1
    cap = 1024
    bd = np.empty(cap)
    r2 = cell * cell
    for c in range(cand.shape[0]):
        i = cand[c]
        fi = face[i]
        q0 = points[i, 0]
        q1 = points[i, 1]
        q2 = points[i, 2]
        fx = q0 - (lo[0] + cell * gc[i, 0])
        fy = q1 - (lo[1] + cell * gc[i, 1])
        fz = q2 - (lo[2] + cell * gc[i, 2])
        cnt = 0
        bad = False
        da = np.inf
        a = -1
        for dx in range(-1, 2):
            cx = gc[i, 0] + dx
            if cx < 0 or cx >= dims[0]:
                continue
            for dy in range(-1, 2):
                cy = gc[i, 1] + dy
                if cy < 0 or cy >= dims[1]:
                    continue
                gxy = _gap(dx, fx, cell) + _gap(dy, fy, cell)
                for dz in range(-1, 2):
                    cz = gc[i, 2] + dz
                    if cz < 0 or cz >= dims[2]:
                        continue
                    if gxy + _gap(dz, fz, cell) > r2 * (1.0 + 1e-9):
                        continue
                    h = _slot(keys, (cx * dims[1] + cy) * dims[2] + cz, mask)
                    if keys[h] == -1:
                        continue
                    for s in range(cstart[h], cend[h]):
                        e0 = xyz[s, 0] - q0
                        e1 = xyz[s, 1] - q1
                        e2 = xyz[s, 2] - q2
                        d = ((0.0 + e0 * e0) + e1 * e1) + e2 * e2
                        if d >= r2 * (1.0 + 1e-9):
                            continue
                        if d >= r2 * (1.0 - 1e-9):
                            bad = True  # at the bound: in or out is the kd-tree's call
                        if cnt == cap:
                            bad = True
                            continue
                        bd[cnt] = d
                        cnt += 1
                        j = order[s]
                        if face[j] != fi and (d < da or (d == da and j < a)):
                            da = d
                            a = j
        ans = -1
        if a >= 0:
            closer = 0
            near = 0
            for t in range(cnt):
                if abs(bd[t] - da) <= 1e-12 * da:
                    near += 1
                elif bd[t] < da:
                    closer += 1
            if near > 1:  # a itself is one of them
                bad = True
            if closer < k:
                ans = a
        out[c] = ans
        flag[c] = bad
