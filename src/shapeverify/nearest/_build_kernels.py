"""numba kernels that build the DVG tree below the top grid (private; see :mod:`.dvg`).

The classification of a cell (:func:`shapeverify.nearest._classify_kernels.classify` and
``classify_multi``) needs the exact nearest model point of its 8 vertices (and, for a cell that
failed, of 7 more samples).  Instead of a kd-tree query per vertex, every refined cell carries a
*candidate list*: the model points that can be the nearest one anywhere in the cell.  A child's
list is its parent's list, pruned:

* by distance: a point farther from the cell (box distance) than ``U`` cannot be nearest
  anywhere in it, where ``U = min(min_o d_o + 2 r, max_o d_o + r, max_q |q - a_o|)`` bounds
  the nearest distance of every point of the cell (d_o: nearest distances of the vertices,
  r: half diagonal);
* by *witnesses*, the vertices' nearest points a: a point p is dropped when a is strictly
  closer than p everywhere in the cell.  ``|v - a|^2 - |v - p|^2`` is linear in v, so its
  largest value over the box is ``|c - a|^2 - |c - p|^2 + size * sum_k |p_k - a_k|`` (c: the
  centre); p is dropped when that is negative (with a relative margin of 1e-9 against rounding).

Both tests are made for 8 candidates at once (:func:`._intrinsics.kept8`, read from
coordinate arrays: the top grid's points in bin order, a parent's list gathered once for all
its children).  They only drop points that are nearest nowhere in the cell, so the nearest
point of any point of a cell is in its list, and a brute-force search over the list is exact.
The top grid's lists are collected from the model points binned on the top grid.  Ties (two model
points at exactly the same distance) go to the lower index, as in a linear scan.

Every cell is handled on its own, so the kernels run on contiguous chunks of cells in several
threads with identical results.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._classify_kernels import EXTRA
from ._intrinsics import beaten8, kept8
from ._kernels import walk_inline as walk
from ._kernels import _d2, step, walk_many
from ._lattice_kernels import SCRATCH, nn_extra, nn_lattice

# lattice offsets of a cell's 8 vertices (octant order: x | y << 1 | z << 2)
_CX = np.array([o & 1 for o in range(8)], dtype=np.int64)
_CY = np.array([(o >> 1) & 1 for o in range(8)], dtype=np.int64)
_CZ = np.array([(o >> 2) & 1 for o in range(8)], dtype=np.int64)
WALK_GROUP = 4  # vertex walks of classify_children advanced together


@njit(cache=True, nogil=True)
def _vertex_from_lattice(lat_p, oc, c, origin, size, pts, out_i, out_d):
    """The 8 vertices' nearest points of child ``oc`` (coordinates c) from its parent's lattice
    row ``lat_p`` (27,), and their distances (computed as in
    :func:`._lattice_kernels.nn_lattice`)."""
    for o in range(8):
        t = (_CX[oc] + _CX[o]) + 3 * (_CY[oc] + _CY[o]) + 9 * (_CZ[oc] + _CZ[o])
        j = lat_p[t]
        e0 = pts[j, 0] - (origin[0] + size * (c[0] + _CX[o]))
        e1 = pts[j, 1] - (origin[1] + size * (c[1] + _CY[o]))
        e2 = pts[j, 2] - (origin[2] + size * (c[2] + _CZ[o]))
        out_i[o] = j
        out_d[o] = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@njit(cache=True, nogil=True, inline="always")
def _child_cell(m, parents, lat, origin, size, pts, c, vi, vd):
    """Child ``m`` (8 p + octant) of the refined parents: its cell coordinates into ``c`` (3,)
    and its vertices' nearest points and distances into ``vi``, ``vd`` (8,) from the parent's
    lattice; returns the parent p."""
    p = m // 8
    oc = m % 8
    c[0] = 2 * parents[p, 0] + _CX[oc]
    c[1] = 2 * parents[p, 1] + _CY[oc]
    c[2] = 2 * parents[p, 2] + _CZ[oc]
    _vertex_from_lattice(lat[p], oc, c, origin, size, pts, vi, vd)
    return p


@njit(cache=True, nogil=True, inline="always")
def _witnesses(wit, pts, c0, c1, c2, out):
    """The distinct witnesses of a cell (its vertices' nearest points ``wit`` (8,)) into
    ``out`` (40,) float64 for :func:`._intrinsics.beaten8`: their coordinates, squared
    distances to the centre c and indices, 8 lanes each (the last one repeated in the lanes
    beyond); returns how many."""
    nw = 0
    for w in range(wit.shape[0]):
        a = wit[w]
        dup = False
        for v in range(nw):
            if out[32 + v] == a:
                dup = True
        if dup:
            continue
        y0 = pts[a, 0]
        y1 = pts[a, 1]
        y2 = pts[a, 2]
        out[nw] = y0
        out[8 + nw] = y1
        out[16 + nw] = y2
        out[24 + nw] = (y0 - c0) ** 2 + (y1 - c1) ** 2 + (y2 - c2) ** 2
        out[32 + nw] = np.float64(a)
        nw += 1
    for v in range(nw, 8):
        for k in range(0, 40, 8):
            out[k + v] = out[k + nw - 1]
    return nw


@njit(cache=True, nogil=True, inline="always")
def _keep(p, c0, c1, c2, half, pts, wit, U):
    """Whether model point p can be the nearest one somewhere in the cube (centre c, half
    side ``half``) whose vertices' nearest points (the witnesses ``wit``, :func:`_witnesses`)
    are all within U of every point of it (see the module docstring).  The lists test 8
    points at once (:func:`_append_kept8`); this is their reference (tests)."""
    x0 = pts[p, 0]
    x1 = pts[p, 1]
    x2 = pts[p, 2]
    g0 = max(abs(x0 - c0) - half, 0.0)
    g1 = max(abs(x1 - c1) - half, 0.0)
    g2 = max(abs(x2 - c2) - half, 0.0)
    if g0 * g0 + g1 * g1 + g2 * g2 > U * U:
        return False
    dp = (x0 - c0) ** 2 + (x1 - c1) ** 2 + (x2 - c2) ** 2
    return not beaten8(wit, x0, x1, x2, dp, 2.0 * half, np.float64(p))


@njit(cache=True, nogil=True, inline="always")
def _bound(vd, wit, pts, c0, c1, c2, half):
    """Upper bound U of the nearest distance anywhere in a cube (centre c, half side
    ``half``) from its vertices' nearest distances vd (8,) and points wit (8,):
    min(min vd + 2 r, max vd + r, the farthest corner from any of the wit)."""
    r = np.sqrt(3.0) * half
    lo = np.inf
    hi = 0.0
    for o in range(8):
        lo = min(lo, vd[o])
        hi = max(hi, vd[o])
    u = min(lo + 2.0 * r, hi + r)
    for o in range(8):
        a = wit[o]
        e0 = abs(pts[a, 0] - c0) + half
        e1 = abs(pts[a, 1] - c1) + half
        e2 = abs(pts[a, 2] - c2) + half
        u = min(u, np.sqrt(e0 * e0 + e1 * e1 + e2 * e2))
    return u


@njit(cache=True, nogil=True)
def _grow(buf, need):
    """``buf`` with room for ``need`` entries: itself, or a copy 1.5x larger (at least
    ``need``)."""
    if need <= buf.shape[0]:
        return buf
    new = np.empty(max(need, buf.shape[0] + buf.shape[0] // 2), dtype=buf.dtype)
    new[:buf.shape[0]] = buf
    return new


@njit(cache=True, nogil=True, inline="always")
def _append_kept8(xs, ys, zs, ids, a, b, buf, pos, c0, c1, c2, half, wv, nw, uu):
    """Append to ``buf`` the candidates that :func:`_keep` keeps for the cube centred at c,
    given by their coordinates and indices ``xs[a:b]``, ``ys``, ``zs``, ``ids`` (the arrays
    readable 8 beyond ``b``), tested 8 at a time (:func:`._intrinsics.kept8`, bit for bit
    ``_keep``; ``uu``: U * U); ``buf`` must have room for ``b - a + 8`` more.  Returns the
    new end."""
    for s in range(a, b, 8):
        m = kept8(xs, ys, zs, ids, s, b - s, wv, nw, c0, c1, c2, half, uu, 2.0 * half)
        for k in range(8):  # branch free: every lane written, the kept ones kept
            buf[pos] = ids[s + k]
            pos += (m >> k) & 1
    return pos


@njit(cache=True, nogil=True, inline="always")
def _bin_beaten(ix, iy, iz, origin, size, c0, c1, c2, wit, nw):
    """Whether one witness beats every point of bin (ix, iy, iz) (a top grid cell) everywhere
    in the cube of side ``size`` centred at c: the largest value of ``_keep``'s witness
    expression over the bin's box is negative (``wit``, ``nw``: :func:`_witnesses`)."""
    half = 0.5 * size
    l0 = origin[0] + size * ix
    l1 = origin[1] + size * iy
    l2 = origin[2] + size * iz
    # smallest |c - p|^2 over the bin
    e0 = max(l0 - c0, c0 - (l0 + size), 0.0)
    e1 = max(l1 - c1, c1 - (l1 + size), 0.0)
    e2 = max(l2 - c2, c2 - (l2 + size), 0.0)
    dp = e0 * e0 + e1 * e1 + e2 * e2
    for w in range(nw):
        y0 = wit[w]
        y1 = wit[8 + w]
        y2 = wit[16 + w]
        da = wit[24 + w]
        s = (max(abs(l0 - y0), abs(l0 + size - y0)) + max(abs(l1 - y1), abs(l1 + size - y1))
             + max(abs(l2 - y2), abs(l2 + size - y2)))
        if da - dp + 2.0 * half * s < -1e-9 * (da + dp) - 1e-12 * size * size:
            return True
    return False


@njit(cache=True, nogil=True)
def top_lists(cells, vnn_i, vnn_d, pts, sx, sy, sz, sid, start, dims, origin, size):
    """Candidate lists of refined top cells from the model points binned on the top grid.

    cells : (R, 3) int64 top cell coordinates; vnn_i, vnn_d : (R, 8) exact nearest point and
    distance of each vertex; sx, sy, sz, sid : the points' coordinates and indices (int32)
    sorted by top cell, 8 more entries of padding; start : the start of each cell's run
    (dims.prod() + 1 entries).  Returns (counts (R,) int64,
    concatenated lists int32: the front of a larger buffer, to be copied out).
    """
    R = cells.shape[0]
    counts = np.zeros(R, dtype=np.int64)
    # room for 512 per cell (about 290 at 1M impeller points): pages never written are never
    # resident, and the buffer seldom grows (each growth is a copy)
    buf = np.empty(max(1024, 512 * R), dtype=np.int32)
    pos = 0
    half = 0.5 * size
    wit = np.empty(8, dtype=np.int64)
    wv = np.empty(40)
    for m in range(R):
        for o in range(8):
            wit[o] = vnn_i[m, o]
        c0 = origin[0] + size * (cells[m, 0] + 0.5)
        c1 = origin[1] + size * (cells[m, 1] + 0.5)
        c2 = origin[2] + size * (cells[m, 2] + 0.5)
        U = _bound(vnn_d[m], wit, pts, c0, c1, c2, half) * (1.0 + 1e-9)
        nw = _witnesses(wit, pts, c0, c1, c2, wv)
        k = int(np.ceil(U / size)) + 1
        x0 = max(0, cells[m, 0] - k)
        x1 = min(dims[0] - 1, cells[m, 0] + k)
        y0 = max(0, cells[m, 1] - k)
        y1 = min(dims[1] - 1, cells[m, 1] + k)
        z0 = max(0, cells[m, 2] - k)
        z1 = min(dims[2] - 1, cells[m, 2] + k)
        n0 = pos
        for ix in range(x0, x1 + 1):
            gx = max(abs(ix - cells[m, 0]) - 1, 0) * size
            for iy in range(y0, y1 + 1):
                gy = max(abs(iy - cells[m, 1]) - 1, 0) * size
                if gx * gx + gy * gy > U * U:
                    continue  # the column of bins is farther than U from the cell
                b = (ix * dims[1] + iy) * dims[2]
                for iz in range(z0, z1 + 1):
                    a0 = start[b + iz]
                    a1 = start[b + iz + 1]
                    if a0 == a1:
                        continue
                    gz = max(abs(iz - cells[m, 2]) - 1, 0) * size
                    if gx * gx + gy * gy + gz * gz > U * U:
                        continue
                    if _bin_beaten(ix, iy, iz, origin, size, c0, c1, c2, wv, nw):
                        continue
                    if pos + (a1 - a0) + 8 > buf.shape[0]:
                        buf = _grow(buf, pos + (a1 - a0) + 8)
                    pos = _append_kept8(sx, sy, sz, sid, a0, a1, buf, pos, c0, c1, c2, half,
                                        wv, nw, U * U)
        counts[m] = pos - n0
    return counts, buf[:pos]  # a view: _chunked copies it out (no second copy here)


@njit(cache=True, nogil=True)
def classify_children(parents, off, lst, pts, origin, size, rf, ri, rh, rs, max_distance,
                      max_moves, out_kind, out_seed, out_lat, out_fail):
    """:func:`shapeverify.nearest._classify_kernels.classify` for the 8 children (cell size ``size``)
    of each refined parent cell, the vertices' nearest points found in the parent's list.

    parents : (R, 3) int64 parent coordinates at the level above; off : (R + 1,) int64 offsets
    of their lists in ``lst``.  Child 8 p + o (octant o) has coordinates 2 parents[p] + corner.
    out_kind, out_seed : (8 R,); out_lat : (R, 27) int32, the nearest point of each parent's
    lattice point ``(t % 3, t // 3 % 3, t // 9)`` (in child cell units), for the later passes;
    out_fail : (8 R,) int8, for a failed cell the first vertex (octant order) that the walk
    from its seed gets wrong (all before it are right), else 8.
    """
    r = 0.5 * np.sqrt(3.0) * size
    tol = 1e-12 * size
    li = np.empty(27, dtype=np.int64)
    ld = np.empty(27)
    qx = np.empty(3)
    qy = np.empty(3)
    qz = np.empty(3)
    sq = np.empty(SCRATCH)
    qv = np.empty((8, 3))
    qo = np.empty(8, dtype=np.int64)
    qt = np.empty(8, dtype=np.int64)
    wb = np.empty(8, dtype=np.int64)
    wd = np.empty(8)
    wm = np.empty(8, dtype=np.int64)
    live = np.empty(8, dtype=np.bool_)
    for p in range(parents.shape[0]):
        a = off[p]
        b = off[p + 1]
        b0 = 2 * parents[p, 0]
        b1 = 2 * parents[p, 1]
        b2 = 2 * parents[p, 2]
        for i in range(3):  # lattice point t: (qx[t % 3], qy[t // 3 % 3], qz[t // 9])
            qx[i] = origin[0] + size * (b0 + i)
            qy[i] = origin[1] + size * (b1 + i)
            qz[i] = origin[2] + size * (b2 + i)
        nn_lattice(qx, qy, qz, pts, lst, a, b, sq, li, ld)
        for t in range(27):
            out_lat[p, t] = li[t]
        for oc in range(8):
            m = 8 * p + oc
            cx = _CX[oc]
            cy = _CY[oc]
            cz = _CZ[oc]
            dmin = np.inf
            vmin = 0
            for o in range(8):
                t = (cx + _CX[o]) + 3 * (cy + _CY[o]) + 9 * (cz + _CZ[o])
                if ld[t] < dmin:
                    dmin = ld[t]
                    vmin = t
            out_seed[m] = -1
            out_fail[m] = 8
            if not (dmin <= max_distance + r):
                out_kind[m] = 0
                continue
            c0 = origin[0] + size * (b0 + cx + 0.5)
            c1 = origin[1] + size * (b1 + cy + 0.5)
            c2 = origin[2] + size * (b2 + cz + 0.5)
            seed, _, _ = walk(c0, c1, c2, li[vmin], rf, ri, rh, rs, 64)
            out_seed[m] = seed
            out_kind[m] = 1
            nq = 0  # the vertices to walk to (a walk from the exact nearest point stays there)
            for o in range(8):
                t = (cx + _CX[o]) + 3 * (cy + _CY[o]) + 9 * (cz + _CZ[o])
                if li[t] == seed:
                    continue
                qv[nq, 0] = origin[0] + size * (b0 + cx + _CX[o])
                qv[nq, 1] = origin[1] + size * (b1 + cy + _CY[o])
                qv[nq, 2] = origin[2] + size * (b2 + cz + _CZ[o])
                qo[nq] = o
                qt[nq] = t
                nq += 1
            # walked WALK_GROUP at a time (a group's walks overlap), up to the group of the
            # first failing vertex in octant order
            for g in range(0, nq, WALK_GROUP):
                ng = min(WALK_GROUP, nq - g)
                walk_many(qv[g:], ng, seed, rf, ri, rh, rs, max_moves + 1, wb, wd, wm, live)
                for k in range(ng):
                    if (wm[k] > max_moves
                            or np.sqrt(wd[k]) > ld[qt[g + k]] * (1.0 + 1e-12) + tol):
                        out_kind[m] = 2
                        out_fail[m] = qo[g + k]
                        break
                if out_kind[m] == 2:
                    break


@njit(cache=True, nogil=True)
def _walks_ok(q0, q1, q2, seeds, n0, cnt, cache_d, cache_m, rf, ri, rh, rs, max_moves,
              i_exact, d_exact, tol, cur, live):
    """_classify_kernels._seeded_ok with the walks of seeds[:n0] taken from the cache and those of
    seeds[n0:cnt] added to it.  Returns (ok, number of cached walks).

    A walk from the exact nearest point ``i_exact`` stays there (no point is strictly closer):
    it is not walked.  The new walks are advanced in turn, one move each per round (their
    chains of dependent loads overlap; each is exactly :func:`._kernels.walk`'s); a walk
    longer than ``max_moves`` makes the answer False, now and whenever asked again.
    ``cur``, ``live``: scratch as long as ``seeds``.
    """
    for s in range(n0):
        if cache_m[s] > max_moves:
            return False, n0
    left = 0
    for s in range(n0, cnt):
        b = np.int64(seeds[s])
        cache_d[s] = _d2(q0, q1, q2, rf, b)
        cache_m[s] = 0
        cur[s] = b
        live[s] = b != i_exact
        if live[s]:
            left += 1
    moves = 0
    while moves < max_moves + 1 and left > 0:
        for s in range(n0, cnt):
            if not live[s]:
                continue
            j, dj = step(q0, q1, q2, cur[s], cache_d[s], rf, ri, rh, rs)
            if j < 0:
                live[s] = False
                left -= 1
                continue
            cur[s] = j
            cache_d[s] = dj
            cache_m[s] += 1
        moves += 1
    bd = np.inf
    for s in range(cnt):
        if cache_m[s] > max_moves:
            return False, cnt
        bd = min(bd, cache_d[s])
    return np.sqrt(bd) <= d_exact * (1.0 + 1e-12) + tol, cnt


@njit(cache=True, nogil=True)
def multi_children(ids, parents, off, lst, lat, pts, origin, size, first_seed, first_fail, rf,
                   ri, rh, rs, max_moves, max_seeds, last_level, out_kind, out_seeds,
                   out_nseeds):
    """:func:`shapeverify.nearest._classify_kernels.classify_multi` for the failed children ``ids``
    (child numbers 8 p + octant), the samples' nearest points found in the parent's list.

    Same result as ``classify_multi``; the walks from each seed to each vertex are done once
    (the second round reuses them), and above the last level a cell stops as soon as it is
    certain to be refined (its seeds are then not needed).  On the last level only the seeds
    matter: the second round (which only decides ``ok``) is skipped, and the vertices that
    :func:`classify_children` already walked from the first seed (``first_fail`` (8 R,): all
    before the first failing one pass, that one fails) are not walked again.
    """
    tol = 1e-12 * size
    h = 0.5 * size
    cap = out_seeds.shape[1]
    vi = np.empty(8, dtype=np.int64)
    vd = np.empty(8)
    cd = np.empty((8, cap))
    cm = np.empty((8, cap), dtype=np.int64)
    nc = np.zeros(8, dtype=np.int64)
    ed = np.empty(cap)
    em = np.empty(cap, dtype=np.int64)
    cur = np.empty(cap, dtype=np.int64)
    live = np.empty(cap, dtype=np.bool_)
    c = np.empty(3, dtype=np.int64)
    qx = np.empty(3)
    qy = np.empty(3)
    qz = np.empty(3)
    sq = np.empty(SCRATCH)
    xi = np.empty(7, dtype=np.int64)
    xd = np.empty(7)
    for f in range(ids.shape[0]):
        m = ids[f]
        p = _child_cell(m, parents, lat, origin, size, pts, c, vi, vd)
        a = off[p]
        b = off[p + 1]
        seeds = out_seeds[f]
        seeds[0] = first_seed[m]
        cnt = 1
        ok = True
        stop = False
        nc[:] = 0
        # the second round only decides ``ok``, which the last level does not need
        for rnd in range(1 if last_level else 2):
            for o in range(8):
                if last_level and o < first_fail[m]:
                    continue  # right with the first seed alone (classify_children walked it)
                q0 = origin[0] + size * (c[0] + _CX[o])
                q1 = origin[1] + size * (c[1] + _CY[o])
                q2 = origin[2] + size * (c[2] + _CZ[o])
                if last_level and o == first_fail[m]:
                    good = False  # wrong with the first seed alone, the only one so far
                else:
                    good, nc[o] = _walks_ok(q0, q1, q2, seeds, nc[o], cnt, cd[o], cm[o], rf,
                                            ri, rh, rs, max_moves, vi[o], vd[o], tol, cur,
                                            live)
                if not good:
                    if rnd == 0 and cnt < cap:
                        seeds[cnt] = vi[o]
                        cnt += 1
                    else:
                        ok = False
                if not last_level and (not ok or cnt > max_seeds):
                    stop = True
                    break
            if stop:
                break
        if not stop:
            for i in range(3):  # the extra samples' nearest points, all 7 in one pass
                qx[i] = origin[0] + h * (2 * c[0] + i)
                qy[i] = origin[1] + h * (2 * c[1] + i)
                qz[i] = origin[2] + h * (2 * c[2] + i)
            nn_extra(qx, qy, qz, EXTRA, pts, lst, a, b, sq, xi, xd)
            for e in range(7):
                q0 = qx[EXTRA[e, 0]]
                q1 = qy[EXTRA[e, 1]]
                q2 = qz[EXTRA[e, 2]]
                if not _walks_ok(q0, q1, q2, seeds, 0, cnt, ed, em, rf, ri, rh, rs, max_moves,
                                 xi[e], xd[e], tol, cur, live)[0]:
                    ok = False
                    if last_level and cnt < cap:
                        seeds[cnt] = xi[e]
                        cnt += 1
                    elif not last_level:
                        break
        out_nseeds[f] = cnt
        out_kind[f] = 1 if (not stop and ok and cnt <= max_seeds) or last_level else 2


@njit(cache=True, nogil=True)
def child_lists(ids, parents, off, lst, lat, pts, origin, size):
    """Candidate lists of the refined children ``ids`` (child numbers 8 p + octant) from their
    parents' lists and lattice nearest points ``lat`` (:func:`classify_children`).  Returns
    (counts (len(ids),) int64, concatenated lists int32: the front of a larger buffer, to be
    copied out)."""
    n = ids.shape[0]
    counts = np.zeros(n, dtype=np.int64)
    cap = 0  # a child's list is part of its parent's: room for those, never grown (pages
    for f in range(n):  # never written are never resident)
        p = ids[f] // 8
        cap += off[p + 1] - off[p]
    longest = 0
    for f in range(n):
        p = ids[f] // 8
        longest = max(longest, off[p + 1] - off[p])
    buf = np.empty(max(1024, cap + 8), dtype=np.int32)
    pos = 0
    half = 0.5 * size
    vi = np.empty(8, dtype=np.int64)
    vd = np.empty(8)
    wv = np.empty(40)
    c = np.empty(3, dtype=np.int64)
    # the parent's list gathered (coordinates and indices, 8 of padding), once for its children
    gx = np.zeros(longest + 8)
    gy = np.zeros(longest + 8)
    gz = np.zeros(longest + 8)
    gi = np.zeros(longest + 8, dtype=np.int32)
    gp = -1
    for f in range(n):
        m = ids[f]
        p = _child_cell(m, parents, lat, origin, size, pts, c, vi, vd)
        a = off[p]
        b = off[p + 1]
        if p != gp:
            for s in range(a, b):
                j = lst[s]
                gx[s - a] = pts[j, 0]
                gy[s - a] = pts[j, 1]
                gz[s - a] = pts[j, 2]
                gi[s - a] = j
            gp = p
        c0 = origin[0] + size * (c[0] + 0.5)
        c1 = origin[1] + size * (c[1] + 0.5)
        c2 = origin[2] + size * (c[2] + 0.5)
        U = _bound(vd, vi, pts, c0, c1, c2, half) * (1.0 + 1e-9)
        nw = _witnesses(vi, pts, c0, c1, c2, wv)
        n0 = pos
        pos = _append_kept8(gx, gy, gz, gi, 0, b - a, buf, pos, c0, c1, c2, half, wv, nw,
                            U * U)
        counts[f] = pos - n0
    return counts, buf[:pos]  # a view: _chunked copies it out (no second copy here)


@njit(cache=True, nogil=True)
def fill_neighbours(points, graph, nbr, off_col, qstep, ri, rh, rs):
    """The graph part of the model point records (see :func:`.dvg.make_records`), without
    (N, K, 3) temporaries: neighbours (the point itself where missing), their offsets
    quantised to int16 and the quantisation step (float32)."""
    n = points.shape[0]
    kk = graph.shape[1]
    g = np.empty(kk, dtype=np.int64)
    for i in range(n):
        m = 0.0
        for k in range(kk):
            j = graph[i, k]
            j = i if j < 0 else j
            g[k] = j
            ri[i, nbr + k] = j
            for c in range(3):
                m = max(m, abs(points[j, c] - points[i, c]))
        step = m / 32767.0
        if step == 0.0:
            step = 1.0
        rs[i, qstep] = step
        s = np.float64(rs[i, qstep])  # the float32 actually stored
        for k in range(kk):
            for c in range(3):
                v = np.rint((points[g[k], c] - points[i, c]) / s)
                rh[i, off_col + 3 * k + c] = np.int16(min(max(v, -32767.0), 32767.0))
