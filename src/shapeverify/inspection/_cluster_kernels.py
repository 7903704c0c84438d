"""numba kernels of the inspection's region measures (private; callers validate their input):
the Voronoi cells of a region's points in their tangent planes (``cell_areas``).  The union-find
of the clustering is :mod:`shapeverify.measures._component_kernels`.
"""
import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _clip(px, py, n, ax, ay, b, qx, qy):
    """Clip the convex polygon ``(px, py)[:n]`` to the half-plane ``ax x + ay y <= b`` into
    ``(qx, qy)``; returns the new vertex count."""
    m = 0
    for k in range(n):
        k1 = k + 1 if k + 1 < n else 0
        x0, y0, x1, y1 = px[k], py[k], px[k1], py[k1]
        s0 = ax * x0 + ay * y0 - b
        s1 = ax * x1 + ay * y1 - b
        if s0 <= 0.0:
            qx[m] = x0
            qy[m] = y0
            m += 1
        if (s0 <= 0.0) != (s1 <= 0.0):
            t = s0 / (s0 - s1)
            qx[m] = x0 + t * (x1 - x0)
            qy[m] = y0 + t * (y1 - y0)
            m += 1
    return m


@njit(cache=True, nogil=True)
def _area(px, py, n):
    s = 0.0
    for k in range(n):
        k1 = k + 1 if k + 1 < n else 0
        s += px[k] * py[k1] - px[k1] * py[k]
    return 0.5 * abs(s)


@njit(cache=True, nogil=True)
def cell_areas(ox, oy, nbr, me, g, gx, gy, bound, cell, part):
    """Voronoi cells in each point's tangent plane, and their part where a linear function is
    positive.

    ox, oy : (m, k) float64 offsets of point i's neighbours in its tangent plane (NaN: none);
    nbr : (m, k) int64 the neighbours' point indices; me : (m,) int64 point i's own index (a
    neighbour at the same place cuts nothing; of coincident points only the lowest index keeps
    the cell); g, gx, gy : (m,) the function's value at point i and its gradient; bound : half
    size of the square that bounds each cell.  Writes ``cell`` (m,) the cell's area and ``part``
    (m,) the area of the cell where ``g + gx x + gy y >= 0``.
    """
    m, k = ox.shape
    cap = 4 + 2 * k + 4
    px = np.empty(cap)
    py = np.empty(cap)
    qx = np.empty(cap)
    qy = np.empty(cap)
    for i in range(m):
        px[0], py[0] = -bound, -bound
        px[1], py[1] = bound, -bound
        px[2], py[2] = bound, bound
        px[3], py[3] = -bound, bound
        n = 4
        r_max2 = 2.0 * bound * bound
        empty = False
        for j in range(k):
            x, y = ox[i, j], oy[i, j]
            if not (x == x):
                continue
            r2 = x * x + y * y
            if r2 <= 1e-24 * bound * bound:
                if nbr[i, j] < me[i]:
                    empty = True
                    break
                continue
            if 0.25 * r2 >= r_max2:
                continue                     # the bisector misses the cell
            n = _clip(px, py, n, x, y, 0.5 * r2, qx, qy)
            r_max2 = 0.0
            for t in range(n):
                px[t], py[t] = qx[t], qy[t]
                r_max2 = max(r_max2, qx[t] * qx[t] + qy[t] * qy[t])
            if n < 3:
                empty = True
                break
        if empty:
            cell[i] = 0.0
            part[i] = 0.0
            continue
        cell[i] = _area(px, py, n)
        # the part where g + gx x + gy y >= 0, i.e. -gx x - gy y <= g
        if gx[i] == 0.0 and gy[i] == 0.0:
            part[i] = cell[i] if g[i] >= 0.0 else 0.0
        else:
            n2 = _clip(px, py, n, -gx[i], -gy[i], g[i], qx, qy)
            part[i] = _area(qx, qy, n2) if n2 >= 3 else 0.0
    return m
