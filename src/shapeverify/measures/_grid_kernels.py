"""numba kernels of the inspection's neighbour questions (private; callers validate their input).

Both search a uniform grid of cells at least ``h`` wide (a counting sort of the points by
cell): every point closer than ``h`` to a query lies in the 27 cells around the query's.

* ``any_within`` answers "is some reference point closer than r?" and stops at the first one
  found: the same answer as ``np.isfinite(cKDTree(ref).query(q, k=1,
  distance_upper_bound=r)[0])`` (squared distance ``dx*dx + dy*dy + dz*dz < r*r``) without
  looking for the nearest point.
* ``mark_within`` answers the same question the other way round (each of a few query points
  marks the reference points around it).
* ``nearest_other`` gives the distance from a point of the set to its nearest other point
  (``cKDTree(ref).query(ref[i], k=2)[0][1]``, the same ``sqrt`` of the same sum), or -1 when
  that is not closer than the cell width (then the caller asks the tree).
"""
import numpy as np
from numba import njit

#: at most this many grid cells per reference point, plus MIN_CELLS (cells are widened beyond
#: h to stay below)
CELLS_PER_POINT = 4
MIN_CELLS = 1 << 16
#: margin of the cell width over the distance asked about: rounding never hides a cell
MARGIN = 1e-6


def kernel_array(a, dtype=np.float64) -> np.ndarray:
    """``a`` as the one array flavour the kernels are compiled for: C-contiguous, writable,
    ``dtype`` (a copy only when ``a`` is not; numba compiles another version for a read-only
    array, e.g. a loaded model's points)."""
    a = np.ascontiguousarray(a, dtype=dtype)
    return a if a.flags.writeable else a.copy()


@njit(cache=True, nogil=True)
def _grid(ref, h):
    """Grid of ``ref`` with cells at least ``h`` wide: ``(lo, dims, h, start, order, pts)``;
    the points of cell c are ``pts[start[c]:start[c + 1]]`` (rows ``order[...]`` of ref)."""
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
    limit = CELLS_PER_POINT * n + MIN_CELLS
    while True:
        total = 1.0
        for a in range(3):
            total *= np.floor((hi[a] - lo[a]) / h) + 1.0
        if total <= limit:
            break
        h *= 1.5
    dims = np.empty(3, np.int64)
    for a in range(3):
        dims[a] = np.int64(np.floor((hi[a] - lo[a]) / h)) + 1
    ny, nz = dims[1], dims[2]
    n_cells = dims[0] * ny * nz
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
    order = np.empty(n, np.int64)
    pts = np.empty((n, 3))
    for k in range(n):
        j = fill[cell[k]]
        fill[cell[k]] += 1
        order[j] = k
        for a in range(3):
            pts[j, a] = ref[k, a]
    return lo, dims, h, start, order, pts


@njit(cache=True, nogil=True)
def _block(x, y, z, lo, dims, h):
    """The cell ranges ``(x0, x1, y0, y1, z0, z1)`` (inclusive) within one cell of a query's,
    clamped to the grid; x0 > x1 when the query is more than a cell outside the grid."""
    fx = np.floor((x - lo[0]) / h)
    fy = np.floor((y - lo[1]) / h)
    fz = np.floor((z - lo[2]) / h)
    if fx < -1.0 or fy < -1.0 or fz < -1.0 or fx > dims[0] or fy > dims[1] or fz > dims[2]:
        return 1, 0, 1, 0, 1, 0
    cx, cy, cz = np.int64(fx), np.int64(fy), np.int64(fz)
    return (max(cx - 1, 0), min(cx + 1, dims[0] - 1), max(cy - 1, 0), min(cy + 1, dims[1] - 1),
            max(cz - 1, 0), min(cz + 1, dims[2] - 1))


@njit(cache=True, nogil=True, inline="always")
def _hit(x, y, z, pts, j0, j1, r2):
    """Whether one of ``pts[j0:j1]`` is closer than ``sqrt(r2)`` to (x, y, z) (strictly)."""
    for j in range(j0, j1):
        dx = x - pts[j, 0]
        dy = y - pts[j, 1]
        dz = z - pts[j, 2]
        if dx * dx + dy * dy + dz * dz < r2:
            return True
    return False


@njit(cache=True, nogil=True)
def any_within(ref, q, r, out):
    """``out[i] = True`` when a row of ``ref`` is closer than ``r`` to ``q[i]`` (strictly).

    ref : (n, 3) float64, n >= 1; q : (m, 3) float64; r : float > 0; out : (m,) bool, written.
    """
    lo, dims, h, start, order, pts = _grid(ref, r * (1.0 + MARGIN))
    ny, nz = dims[1], dims[2]
    r2 = r * r
    for i in range(q.shape[0]):
        x, y, z = q[i, 0], q[i, 1], q[i, 2]
        x0, x1, y0, y1, z0, z1 = _block(x, y, z, lo, dims, h)
        found = False
        if x0 <= x1:                   # the query's own cell first: on a dense surface it has one
            fx = (x - lo[0]) / h
            fy = (y - lo[1]) / h
            fz = (z - lo[2]) / h
            if 0.0 <= fx < dims[0] and 0.0 <= fy < ny and 0.0 <= fz < nz:
                c = (np.int64(fx) * ny + np.int64(fy)) * nz + np.int64(fz)
                found = _hit(x, y, z, pts, start[c], start[c + 1], r2)
        if found:
            out[i] = True
            continue
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                base = (ix * ny + iy) * nz
                if z1 >= z0 and _hit(x, y, z, pts, start[base + z0], start[base + z1 + 1], r2):
                    found = True
                    break
            if found:
                break
        out[i] = found


@njit(cache=True, nogil=True)
def nearest_other(ref, idx, h, out):
    """``out[k]`` = distance from ``ref[idx[k]]`` to the nearest other row of ``ref`` (0 for a
    duplicate), or -1 when none is closer than the cell width (at least ``h``): search farther.

    ref : (n, 3) float64, n >= 1; idx : (m,) int64; h : float > 0; out : (m,) float64, written.
    """
    lo, dims, hh, start, order, pts = _grid(ref, h)
    ny, nz = dims[1], dims[2]
    sure = hh * (1.0 - MARGIN)
    sure2 = sure * sure
    for k in range(idx.shape[0]):
        i = idx[k]
        x, y, z = ref[i, 0], ref[i, 1], ref[i, 2]
        x0, x1, y0, y1, z0, z1 = _block(x, y, z, lo, dims, hh)
        best = np.inf
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                base = (ix * ny + iy) * nz
                for j in range(start[base + z0], start[base + z1 + 1] if z1 >= z0 else 0):
                    if order[j] == i:
                        continue
                    dx = x - pts[j, 0]
                    dy = y - pts[j, 1]
                    dz = z - pts[j, 2]
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 < best:
                        best = d2
        out[k] = np.sqrt(best) if best < sure2 else -1.0


@njit(cache=True, nogil=True)
def mark_within(ref, q, r, out):
    """``out[j] = True`` when a row of ``q`` is closer than ``r`` to ``ref[j]`` (strictly); the
    same answer as ``any_within(q, ref, r, out)``, fast when ``q`` holds few points: each of
    them marks the points of ``ref`` around it.

    ref : (n, 3) float64, n >= 1; q : (m, 3) float64; r : float > 0; out : (n,) bool, written.
    """
    lo, dims, h, start, order, pts = _grid(ref, r * (1.0 + MARGIN))
    ny, nz = dims[1], dims[2]
    r2 = r * r
    out[:] = False
    for i in range(q.shape[0]):
        x, y, z = q[i, 0], q[i, 1], q[i, 2]
        x0, x1, y0, y1, z0, z1 = _block(x, y, z, lo, dims, h)
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                base = (ix * ny + iy) * nz
                for j in range(start[base + z0], start[base + z1 + 1] if z1 >= z0 else 0):
                    dx = pts[j, 0] - x
                    dy = pts[j, 1] - y
                    dz = pts[j, 2] - z
                    if dx * dx + dy * dy + dz * dz < r2:
                        out[order[j]] = True


@njit(cache=True, nogil=True)
def kernel_sums(ref, q, radius, out):
    """``out[i]`` = the sum of ``(1 - (d / radius)^2)^2`` over the rows of ``ref`` at distance
    ``d <= radius`` from ``q[i]``, added in order of increasing ``d`` (the order that makes the
    sum independent of how the points are stored).

    ref : (n, 3) float64, n >= 1; q : (m, 3) float64; radius : float > 0; out : (m,) float64,
    written.
    """
    none = np.empty((0, 3))
    kernel_sums_unfolded(ref, none, q, none, radius, 1.0, out)


@njit(cache=True, nogil=True)
def kernel_sums_unfolded(ref, ref_n, q, q_n, radius, min_cos, out):
    """:func:`kernel_sums` with each distance measured along the surface: the two points'
    tangent planes (unit normals ``ref_n``, ``q_n``) unfolded about the line where they meet,
    ``d^2 = |D|^2 + 2 |D.n_q| |D.n_r| / (1 + n_q.n_r)`` (``D`` the offset; exact on a
    dihedral edge, the chord on one plane).  Pairs whose normals are not more than ``min_cos``
    alike (the other side of a thin wall) keep the chord, as do all pairs when ``ref_n`` has
    no rows (:func:`kernel_sums`).  The unfolded distance is never shorter than the chord: the
    grid's search radius holds every point counted.

    ref, ref_n : (n, 3) float64, n >= 1 (``ref_n``: n or 0 rows); q, q_n : (m, 3) float64;
    radius : float > 0; min_cos : float > -1; out : (m,) float64, written.
    """
    lo, dims, h, start, order, pts = _grid(ref, radius * (1.0 + MARGIN))
    ny, nz = dims[1], dims[2]
    r2 = radius * radius
    unfold = ref_n.shape[0] > 0
    buf = np.empty(64)
    for i in range(q.shape[0]):
        x, y, z = q[i, 0], q[i, 1], q[i, 2]
        x0, x1, y0, y1, z0, z1 = _block(x, y, z, lo, dims, h)
        n = 0
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                base = (ix * ny + iy) * nz
                for j in range(start[base + z0], start[base + z1 + 1] if z1 >= z0 else 0):
                    dx = pts[j, 0] - x
                    dy = pts[j, 1] - y
                    dz = pts[j, 2] - z
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 > r2:
                        continue
                    if unfold:
                        ax, ay, az = q_n[i, 0], q_n[i, 1], q_n[i, 2]
                        k = order[j]
                        bx, by, bz = ref_n[k, 0], ref_n[k, 1], ref_n[k, 2]
                        c = ax * bx + ay * by + az * bz
                        if c > min_cos:
                            d2 += 2.0 * abs(dx * ax + dy * ay + dz * az) * \
                                abs(dx * bx + dy * by + dz * bz) / (1.0 + c)
                            if d2 > r2:
                                continue
                    if n == buf.shape[0]:
                        bigger = np.empty(2 * n)
                        bigger[:n] = buf
                        buf = bigger
                    buf[n] = np.sqrt(d2)
                    n += 1
        d = np.sort(buf[:n])
        s = 0.0
        for k in range(n):
            t = d[k] / radius
            u = 1.0 - t * t
            s += u * u
        out[i] = s


@njit(cache=True, nogil=True)
def count_within(ref, q, r, cap, out):
    """``out[i]`` = how many rows of ``ref`` are closer than ``r`` to ``q[i]`` (strictly),
    counted up to ``cap``: ``out[i] >= k`` (k <= cap) is ``np.isfinite(cKDTree(ref).query(q,
    k=k, distance_upper_bound=r)[0][:, k - 1])``.

    ref : (n, 3) float64, n >= 1; q : (m, 3) float64; r : float > 0; cap : int >= 1;
    out : (m,) int64, written.
    """
    lo, dims, h, start, order, pts = _grid(ref, r * (1.0 + MARGIN))
    ny, nz = dims[1], dims[2]
    r2 = r * r
    for i in range(q.shape[0]):
        x, y, z = q[i, 0], q[i, 1], q[i, 2]
        x0, x1, y0, y1, z0, z1 = _block(x, y, z, lo, dims, h)
        n = 0
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                base = (ix * ny + iy) * nz
                for j in range(start[base + z0], start[base + z1 + 1] if z1 >= z0 else 0):
                    dx = x - pts[j, 0]
                    dy = y - pts[j, 1]
                    dz = z - pts[j, 2]
                    if dx * dx + dy * dy + dz * dz < r2:
                        n += 1
                        if n >= cap:
                            break
                if n >= cap:
                    break
            if n >= cap:
                break
        out[i] = n
