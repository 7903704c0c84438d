"""numba kernels of the coverage test (private; callers validate their input).

``any_within`` answers "is some reference point closer than r?" for every query point with a
uniform grid of cells at least r wide: only the 27 cells around a query can hold such a point,
and the search stops at the first one found.  It gives the same answer as
``np.isfinite(cKDTree(ref).query(q, k=1, distance_upper_bound=r)[0])`` (a squared distance
``dx*dx + dy*dy + dz*dz < r*r``), without looking for the nearest point.
"""
import numpy as np
from numba import njit

#: at most this many grid cells per reference point (cells are widened beyond r to stay below)
CELLS_PER_POINT = 4


@njit(cache=True, nogil=True)
def any_within(ref, q, r, out):
    """``out[i] = True`` when a row of ``ref`` is closer than ``r`` to ``q[i]`` (strictly).

    ref : (n, 3) float64, n >= 1; q : (m, 3) float64; r : float > 0; out : (m,) bool, written.
    """
    n = ref.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for a in range(3):
        lo[a] = ref[0, a]
        hi[a] = ref[0, a]
    for k in range(1, n):
        for a in range(3):
            v = ref[k, a]
            if v < lo[a]:
                lo[a] = v
            if v > hi[a]:
                hi[a] = v
    # cells of side h >= r; widened until the grid has at most CELLS_PER_POINT * n + 64 cells
    h = r * (1.0 + 1e-6)     # a margin over r: rounding never hides a cell
    limit = CELLS_PER_POINT * n + 64
    dims = np.empty(3, np.int64)
    while True:
        total = 1.0
        for a in range(3):
            total *= np.floor((hi[a] - lo[a]) / h) + 1.0
        if total <= limit:
            break
        h *= 1.5
    for a in range(3):
        dims[a] = np.int64(np.floor((hi[a] - lo[a]) / h)) + 1
    ny, nz = dims[1], dims[2]
    n_cells = dims[0] * ny * nz
    # counting sort of the reference points by cell
    cell = np.empty(n, np.int64)
    start = np.zeros(n_cells + 1, np.int64)
    for k in range(n):
        ix = min(np.int64((ref[k, 0] - lo[0]) / h), dims[0] - 1)
        iy = min(np.int64((ref[k, 1] - lo[1]) / h), ny - 1)
        iz = min(np.int64((ref[k, 2] - lo[2]) / h), nz - 1)
        c = (ix * ny + iy) * nz + iz
        cell[k] = c
        start[c + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    pts = np.empty((n, 3))
    for k in range(n):
        j = fill[cell[k]]
        fill[cell[k]] += 1
        for a in range(3):
            pts[j, a] = ref[k, a]
    r2 = r * r
    for i in range(q.shape[0]):
        x, y, z = q[i, 0], q[i, 1], q[i, 2]
        out[i] = False
        # the cells within one cell of the query's (clamped to the grid; none when it is
        # more than a cell outside the grid in any direction)
        fx = np.floor((x - lo[0]) / h)
        fy = np.floor((y - lo[1]) / h)
        fz = np.floor((z - lo[2]) / h)
        if (fx < -1.0 or fy < -1.0 or fz < -1.0 or fx > dims[0] or fy > ny or fz > nz):
            continue
        cx, cy, cz = np.int64(fx), np.int64(fy), np.int64(fz)
        found = False
        for ix in range(max(cx - 1, 0), min(cx + 1, dims[0] - 1) + 1):
            for iy in range(max(cy - 1, 0), min(cy + 1, ny - 1) + 1):
                base = (ix * ny + iy) * nz
                for iz in range(max(cz - 1, 0), min(cz + 1, nz - 1) + 1):
                    c = base + iz
                    for j in range(start[c], start[c + 1]):
                        dx = x - pts[j, 0]
                        dy = y - pts[j, 1]
                        dz = z - pts[j, 2]
                        if dx * dx + dy * dy + dz * dz < r2:
                            found = True
                            break
                    if found:
                        break
                if found:
                    break
            if found:
                break
        out[i] = found
