"""numba kernels of the Distance Varying Grid tree: queries (private; the build's classification of
cells is in :mod:`._classify_kernels`).

Model point records
-------------------
One 128-byte record per model point, 64-byte aligned (two cache lines), everything a fast
query reads.  The record array ``rec`` is (N + 1, 16) float64; the kernels get four views of
the same memory: ``rf`` float64 (N+1, 16), ``ri`` int32 (N+1, 32), ``rh`` int16 (N+1, 64),
``rs`` float32 (N+1, 32).

===========  ==========================  ==============================================
bytes        view [columns]              content
===========  ==========================  ==============================================
0-24         rf[0:3]                     x, y, z
24-56        ri[6:14]                    the 8 graph neighbours (the point itself where
                                         there are fewer)
56-104       rh[28:52]                   neighbour k's offset from the point, quantised:
                                         ``rh[28 + 3k + c] * rs[26]``
104-108      rs[26]                      that quantisation step
108-116      rs[27:29]                   unit normal, octahedral code
116-120      rh[58:60]                   tangent_u, octahedral code / 32767
120-128      rs[30:32]                   patch half extents along tangent_u, tangent_v
===========  ==========================  ==============================================

Row N is a sentinel far away (1e30).  With the offsets a walk step (which neighbour is
closest?) reads only the current record; the record of the chosen neighbour is then read to
confirm with exact coordinates, so every move strictly decreases the exact distance.

Tree layout
-----------
One int32 array ``nodes``.  The first ``nx * ny * nz`` entries are the top grid, cell
(ix, iy, iz) at ``(ix * ny + iy) * nz + iz``.  A node code ``c``:

* ``c >= 0``   internal cell; its 8 children are ``nodes[c + octant]``,
  ``octant = bx | by << 1 | bz << 2`` (b = 1 for the upper half along that axis);
* ``c == -1``  FAR: farther than the maximum distance (the caller falls back to a kd-tree);
* ``c <= -2``  leaf, ``m = -c - 2``: if ``m < N`` the single seed model point ``m``, else a seed
  list at ``lists[m - N]`` = count, then the indices.

A query descends from the top grid by doubling its fractional cell coordinate (exact in binary
floating point), walks greedily from the leaf's seed (from each seed of a multi-seed leaf) to a
local minimum of the distance.  :func:`query_block` runs blocks of queries stage by stage and
prefetches the next stage's cache lines, so the memory latencies of different queries overlap;
the stages do not branch on values just loaded (a tree code, a ring's verdict): such a branch
waits for its load and kept the cache misses of different queries apart.
Its inputs and outputs are two named tuples (:class:`TreeArrays`, :class:`Answers`) of
C-contiguous writable arrays, so each kernel is compiled once.  A walk step's ring (which of
the 8 neighbours looks closest) runs in 8-wide vectors (:func:`._intrinsics._ring8`), bit-identical to the
scalar loop.  Scratch space is allocated once per call, never per query point.  All kernels
trust their input.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, types

from ._intrinsics import _ring8, prefetch  # noqa: F401 - prefetch: also _exact_kernels'

FAR = -1
K = 8          # neighbours per model point
BLOCK = 32     # queries in flight in query_block
SENTINEL = 1e30
# record layout (see the module docstring)
NBR = 6        # ri column of the first neighbour
OFF = 28       # rh column of the first offset
QSTEP = 26     # rs column of the offset step
NRM = 27       # rs columns of the octahedral normal
TAN = 58       # rh columns of the octahedral tangent
EXT = 30       # rs columns of the half extents
_I16 = 1.0 / 32767.0


@njit(cache=True, nogil=True, inline="always")
def _fetch(rf, j):
    """Prefetch both cache lines of record j."""
    prefetch(rf, j * 16)
    prefetch(rf, j * 16 + 8)


@njit(cache=True, nogil=True, inline="always")
def _d2(q0, q1, q2, rf, j):
    a = rf[j, 0] - q0
    b = rf[j, 1] - q1
    c = rf[j, 2] - q2
    return a * a + b * b + c * c


@njit(cache=True, nogil=True, inline="always")
def _ring(q0, q1, q2, b, rf, rh, rs):
    """Neighbour slot k of b that looks closest to q (from the quantised offsets) and its
    estimated squared distance ``|q - p_b - s * offset_k|^2``."""
    return _ring8(rh, b * rh.shape[1] + OFF, q0 - rf[b, 0], q1 - rf[b, 1], q2 - rf[b, 2],
                  np.float64(rs[b, QSTEP]))


# one compiled version for every caller: int32 start points (seed lists), int64 ones and
# literal budgets are converted to int64 at the call
_F8 = types.float64
_WALK_SIG = types.Tuple((types.int64, _F8, types.int64))(
    _F8, _F8, _F8, types.int64, types.Array(_F8, 2, "C"), types.Array(types.int32, 2, "C"),
    types.Array(types.int16, 2, "C"), types.Array(types.float32, 2, "C"), types.int64)


@njit(cache=True, nogil=True, inline="always")
def step(q0, q1, q2, b, db, rf, ri, rh, rs):
    """One move of a walk at model point ``b`` (squared distance ``db``): the neighbour that
    looks closest (the ring), confirmed with its exact coordinates.  Returns (j, dj), or
    (-1, db) where ``b`` is a local minimum (no move).  Every walk of the tree takes its moves
    here (:func:`walk`, :func:`walk_many`, the build's ``_walks_ok``)."""
    k, de = _ring(q0, q1, q2, b, rf, rh, rs)
    if not de < db:
        return np.int64(-1), db
    j = np.int64(ri[b, NBR + k])
    dj = _d2(q0, q1, q2, rf, j)
    if not dj < db:
        return np.int64(-1), db
    return j, dj


@njit(cache=True, nogil=True, inline="always")
def walk_inline(q0, q1, q2, b, rf, ri, rh, rs, max_moves):
    """:func:`walk`, inlined into the caller (the build's kernels walk tens of millions of
    times: a call passes four array structs and costs about as much as the walk itself)."""
    b = np.int64(b)
    db = _d2(q0, q1, q2, rf, b)
    moves = 0
    while moves < max_moves:
        j, dj = step(q0, q1, q2, b, db, rf, ri, rh, rs)
        if j < 0:
            break
        b = j
        db = dj
        moves += 1
    return b, db, moves


@njit(cache=True, nogil=True, inline="always")
def walk_many(qv, nq, b0, rf, ri, rh, rs, max_moves, out_b, out_d, out_m, live):
    """:func:`walk` from model point ``b0`` to each of the ``nq`` points ``qv[:nq]`` (rows
    x, y, z), the walks advanced in turn, one move each per round: their chains of dependent
    loads and comparisons overlap in the processor.  Each walk is exactly :func:`walk`'s
    (same moves, same end): results into ``out_b``, ``out_d`` (squared distance), ``out_m``
    (moves); ``live`` (>= nq,) bool scratch."""
    b0 = np.int64(b0)
    for i in range(nq):
        out_b[i] = b0
        out_d[i] = _d2(qv[i, 0], qv[i, 1], qv[i, 2], rf, b0)
        out_m[i] = 0
        live[i] = True
    left = nq
    moves = 0
    while moves < max_moves and left > 0:
        for i in range(nq):
            if not live[i]:
                continue
            j, dj = step(qv[i, 0], qv[i, 1], qv[i, 2], out_b[i], out_d[i], rf, ri, rh, rs)
            if j < 0:
                live[i] = False
                left -= 1
                continue
            out_b[i] = j
            out_d[i] = dj
            out_m[i] += 1
        moves += 1


@njit(_WALK_SIG, cache=True, nogil=True)
def walk(q0, q1, q2, b, rf, ri, rh, rs, max_moves):
    """Greedy descent on the neighbour graph from model point ``b``.

    Each round picks the neighbour that looks closest (quantised offsets) and moves there if it
    is strictly closer in exact coordinates.  Returns (index, squared distance, moves).
    """
    return walk_inline(q0, q1, q2, b, rf, ri, rh, rs, max_moves)


@njit(cache=True, nogil=True)
def locate(q0, q1, q2, origin, s0, dims, nodes):
    """Leaf code of the cell holding (q0, q1, q2); FAR outside the top grid."""
    fx = (q0 - origin[0]) / s0
    fy = (q1 - origin[1]) / s0
    fz = (q2 - origin[2]) / s0
    if not (fx >= 0.0 and fy >= 0.0 and fz >= 0.0):
        return FAR
    ix = int(fx)
    iy = int(fy)
    iz = int(fz)
    if ix >= dims[0] or iy >= dims[1] or iz >= dims[2]:
        return FAR
    c = nodes[(ix * dims[1] + iy) * dims[2] + iz]
    fx -= ix
    fy -= iy
    fz -= iz
    while c >= 0:
        fx += fx
        fy += fy
        fz += fz
        bx = 1 if fx >= 1.0 else 0
        by = 1 if fy >= 1.0 else 0
        bz = 1 if fz >= 1.0 else 0
        fx -= bx
        fy -= by
        fz -= bz
        c = nodes[c + (bx | (by << 1) | (bz << 2))]
    return c


@njit(cache=True, nogil=True)
def leaf_nearest(q0, q1, q2, code, n_points, lists, rf, ri, rh, rs, max_moves):
    """Nearest model point from a leaf code (not FAR): walk from each seed, keep the closest.

    Returns (index, squared distance, largest number of moves of a walk).
    """
    m = -code - 2
    if m < n_points:
        return walk(q0, q1, q2, m, rf, ri, rh, rs, max_moves)
    off = m - n_points
    best = -1
    bd = np.inf
    mv = 0
    for s in range(1, lists[off] + 1):
        b, d, k = walk(q0, q1, q2, lists[off + s], rf, ri, rh, rs, max_moves)
        mv = max(mv, k)
        if d < bd:
            bd = d
            best = b
    return best, bd, mv


# ------------------------------------------------------------------------ tangent patches
@njit(cache=True, nogil=True, inline="always")
def oct_decode(x, y):
    """Unit vector from its octahedral code (x, y) in [-1, 1]^2."""
    z = 1.0 - abs(x) - abs(y)
    if z < 0.0:
        x, y = (1.0 - abs(y)) * (1.0 if x >= 0.0 else -1.0), \
               (1.0 - abs(x)) * (1.0 if y >= 0.0 else -1.0)
    inv = 1.0 / np.sqrt(x * x + y * y + z * z)
    return x * inv, y * inv, z * inv


@njit(cache=True, nogil=True, inline="always")
def frame(b, rs, rh):
    """(normal, tangent_u, tangent_v, half_u, half_v) of model point b (tangent_u made
    orthogonal to the normal after decoding)."""
    n0, n1, n2 = oct_decode(np.float64(rs[b, NRM]), np.float64(rs[b, NRM + 1]))
    u0, u1, u2 = oct_decode(rh[b, TAN] * _I16, rh[b, TAN + 1] * _I16)
    c = u0 * n0 + u1 * n1 + u2 * n2
    u0 -= c * n0
    u1 -= c * n1
    u2 -= c * n2
    lu = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    if lu > 0.0:
        u0 /= lu
        u1 /= lu
        u2 /= lu
    v0 = n1 * u2 - n2 * u1
    v1 = n2 * u0 - n0 * u2
    v2 = n0 * u1 - n1 * u0
    return (n0, n1, n2, u0, u1, u2, v0, v1, v2, np.float64(rs[b, EXT]),
            np.float64(rs[b, EXT + 1]))


@njit(cache=True, nogil=True)
def decode_frames(rs, rh, out):
    """out (N, 11): normal, tangent_u, tangent_v, half_u, half_v of every model point."""
    for b in range(out.shape[0]):
        f = frame(b, rs, rh)
        for c in range(11):
            out[b, c] = f[c]


@njit(cache=True, nogil=True)
def decode_normals(idx, rs, rh, out):
    """out (M, 3): unit normals of model points idx (M,)."""
    for i in range(idx.shape[0]):
        n0, n1, n2 = oct_decode(np.float64(rs[idx[i], NRM]), np.float64(rs[idx[i], NRM + 1]))
        out[i, 0] = n0
        out[i, 1] = n1
        out[i, 2] = n2


@njit(cache=True, nogil=True, inline="always")
def _project_one(q0, q1, q2, b, rf, rh, rs):
    """Project q onto the tangent patch of model point b, clamped to its half extents.

    Returns (foot x, y, z, signed distance, clamped, normal x, y, z): the distance is
    (q - p) . n inside the patch, else |q - foot| with the sign of (q - p) . n.
    """
    p0 = rf[b, 0]
    p1 = rf[b, 1]
    p2 = rf[b, 2]
    r0 = q0 - p0
    r1 = q1 - p1
    r2 = q2 - p2
    n0, n1, n2 = oct_decode(np.float64(rs[b, NRM]), np.float64(rs[b, NRM + 1]))
    u0, u1, u2 = oct_decode(rh[b, TAN] * _I16, rh[b, TAN + 1] * _I16)
    # tangent_u off the tangent plane by the quantisation (~1e-4): remove that part; the
    # length changes by ~1e-8, no need to renormalise
    k = u0 * n0 + u1 * n1 + u2 * n2
    u0 -= k * n0
    u1 -= k * n1
    u2 -= k * n2
    v0 = n1 * u2 - n2 * u1
    v1 = n2 * u0 - n0 * u2
    v2 = n0 * u1 - n1 * u0
    hu = np.float64(rs[b, EXT])
    hv = np.float64(rs[b, EXT + 1])
    a = r0 * u0 + r1 * u1 + r2 * u2
    c = r0 * v0 + r1 * v1 + r2 * v2
    h = r0 * n0 + r1 * n1 + r2 * n2
    ac = min(max(a, -hu), hu)
    cc = min(max(c, -hv), hv)
    clamped = ac != a or cc != c
    a = ac
    c = cc
    f0 = p0 + a * u0 + c * v0
    f1 = p1 + a * u1 + c * v1
    f2 = p2 + a * u2 + c * v2
    d = h
    if clamped:
        e0 = q0 - f0
        e1 = q1 - f1
        e2 = q2 - f2
        d = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if h < 0.0:
            d = -d
    return f0, f1, f2, d, clamped, n0, n1, n2


class TreeArrays(NamedTuple):
    """What a fast query reads (one numba type: C-contiguous, writable arrays).

    origin (3,) float64, cell float, dims (3,) int64, nodes (T,) int32, lists (L,) int32: the
    tree; rf, ri, rh, rs: the four views of the records; rows (N, 4) int32 (face, u, v as
    float32 bits, other) and boundary (N,) bool, or (0, 4) / (0,) when the caller wants no
    face, uv and on_boundary.
    """

    origin: np.ndarray
    cell: float
    dims: np.ndarray
    nodes: np.ndarray
    lists: np.ndarray
    rf: np.ndarray
    ri: np.ndarray
    rh: np.ndarray
    rs: np.ndarray
    rows: np.ndarray
    boundary: np.ndarray


class Answers(NamedTuple):
    """Output arrays of :func:`query_block` (see :class:`shapeverify.nearest.dvg.QueryAnswer`):
    index (N,) int64, d2 (N,) float64, foot (M, 3), distance (M,), clamped (M,) bool,
    normal (M, 3), face (R,) int32, uv (R, 2) float64, on_boundary (R,) bool."""

    index: np.ndarray
    d2: np.ndarray
    foot: np.ndarray
    distance: np.ndarray
    clamped: np.ndarray
    normal: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    on_boundary: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def _answer(q0, q1, q2, i, b, rf, rh, rs, rows, uv, boundary, foot, dist, clamped, normal,
            face, out_uv, onb, with_rows):
    """Write query i's patch projection and (with_rows) face, uv, on_boundary for model
    point b.  (Plain arrays, not the named tuples: every array taken out of a tuple in a
    per-query callee costs a reference count pair.)"""
    f0, f1, f2, d, cl, n0, n1, n2 = _project_one(q0, q1, q2, b, rf, rh, rs)
    foot[i, 0] = f0
    foot[i, 1] = f1
    foot[i, 2] = f2
    dist[i] = d
    clamped[i] = cl
    normal[i, 0] = n0
    normal[i, 1] = n1
    normal[i, 2] = n2
    if with_rows:
        face[i] = rows[b, 0]
        out_uv[i, 0] = uv[b, 1]
        out_uv[i, 1] = uv[b, 2]
        onb[i] = cl and boundary[b]


@njit(cache=True, nogil=True)
def answer_known(Q, sel, T, A, patches):
    """Fast-mode answer (patch projection, face, uv, on_boundary) of the queries ``sel``
    (int64) whose nearest model point ``A.index[sel]`` is already known (the kd-tree
    fallback of FAR queries)."""
    rf, rh, rs, rows, boundary = T.rf, T.rh, T.rs, T.rows, T.boundary
    index, foot, dist, clamped, normal = A.index, A.foot, A.distance, A.clamped, A.normal
    face, out_uv, onb = A.face, A.uv, A.on_boundary
    with_rows = patches and rows.shape[0] > 0
    uv = rows.view(np.float32)
    if patches:
        for s in range(sel.shape[0]):
            i = sel[s]
            _answer(Q[i, 0], Q[i, 1], Q[i, 2], i, index[i], rf, rh, rs, rows, uv, boundary,
                    foot, dist, clamped, normal, face, out_uv, onb, with_rows)


@njit(cache=True, nogil=True)
def query_block(Q, T, A, lo, hi, max_moves, patches):
    """Nearest model point of queries ``lo:hi`` (``A.index = -1`` where the tree says FAR);
    returns the number of FAR queries.

    With ``patches`` also the tangent-patch projection (foot, signed distance, clamped,
    normal) for the answered queries, and when ``T.rows`` is not empty the nearest point's
    face, (u, v) and on_boundary (the boundary flag is read only for clamped projections).
    Queries run in blocks of BLOCK, one stage at a time (top grid, one tree level, seed, each
    walk round: confirm a move and ring the new point), prefetching what the next stage reads;
    the queries still walking are kept in a list compacted without branches.
    """
    # every array taken out of the tuples once (not per query: reference counts)
    rf, ri, rh, rs, rows, boundary = T.rf, T.ri, T.rh, T.rs, T.rows, T.boundary
    nodes, lists, origin, dims = T.nodes, T.lists, T.origin, T.dims
    index, d2, foot, dist, clamped, normal = A.index, A.d2, A.foot, A.distance, A.clamped, A.normal
    face, out_uv, onb = A.face, A.uv, A.on_boundary
    n = rf.shape[0] - 1
    fx = np.empty(BLOCK)
    fy = np.empty(BLOCK)
    fz = np.empty(BLOCK)
    code = np.empty(BLOCK, dtype=np.int64)
    best = np.empty(BLOCK, dtype=np.int64)
    cand = np.empty(BLOCK, dtype=np.int64)
    live = np.empty(BLOCK, dtype=np.int64)
    bd = np.empty(BLOCK)
    act = np.empty(BLOCK, dtype=np.bool_)
    inv = 1.0 / T.cell
    with_rows = patches and rows.shape[0] > 0
    uv = rows.view(np.float32)
    n_far = 0
    for s in range(lo, hi, BLOCK):
        m = min(BLOCK, hi - s)
        # top grid
        for t in range(m):
            i = s + t
            x = (Q[i, 0] - origin[0]) * inv
            y = (Q[i, 1] - origin[1]) * inv
            z = (Q[i, 2] - origin[2]) * inv
            code[t] = FAR
            if x >= 0.0 and y >= 0.0 and z >= 0.0:
                ix = int(x)
                iy = int(y)
                iz = int(z)
                if ix < dims[0] and iy < dims[1] and iz < dims[2]:
                    fx[t] = x - ix
                    fy[t] = y - iy
                    fz[t] = z - iz
                    code[t] = nodes[(ix * dims[1] + iy) * dims[2] + iz]
        # descend one level per sweep, without branches on the codes just read (a branch on
        # a loaded code waits for the load: it kept random-order queries' cache misses apart)
        more = 1
        while more:
            more = 0
            for t in range(m):
                c = code[t]
                go = c >= 0
                x = fx[t] + fx[t]
                y = fy[t] + fy[t]
                z = fz[t] + fz[t]
                bx = 1 if x >= 1.0 else 0
                by = 1 if y >= 1.0 else 0
                bz = 1 if z >= 1.0 else 0
                fx[t] = x - bx
                fy[t] = y - by
                fz[t] = z - bz
                child = nodes[c + (bx | (by << 1) | (bz << 2)) if go else 0]
                c = child if go else c
                code[t] = c
                more |= c >= 0
        # seeds; the rare multi-seed leaves are answered at once
        for t in range(m):
            c = code[t]
            act[t] = False
            best[t] = -1
            if c == FAR:
                continue
            mm = -c - 2
            if mm < n:
                best[t] = mm
                act[t] = True
                _fetch(rf, mm)
            else:
                i = s + t
                b, d, _ = leaf_nearest(Q[i, 0], Q[i, 1], Q[i, 2], c, n, lists, rf, ri, rh, rs,
                                       max_moves)
                best[t] = b
                bd[t] = d
        # walk: the neighbour that looks closest (ring), then confirm with its exact
        # coordinates; a confirmed move computes the next round's ring at once.  The queries
        # still walking are listed in live[:k] (compacted without branches).  Round 1: the
        # seed's distance and ring.
        k = 0
        for t in range(m):
            i = s + t
            q0 = Q[i, 0]
            q1 = Q[i, 1]
            q2 = Q[i, 2]
            b = best[t] if act[t] else n  # (the sentinel: harmless reads, never live)
            db = _d2(q0, q1, q2, rf, b)
            kk, de = _ring(q0, q1, q2, b, rf, rh, rs)
            j = np.int64(ri[b, NBR + kk])
            cand[t] = j
            _fetch(rf, j)
            if act[t]:
                bd[t] = db
            live[k] = t
            k += act[t] & (de < db)
        if max_moves < 1:
            k = 0
        moves = 1
        while k > 0:
            k2 = 0
            for u in range(k):
                t = live[u]
                i = s + t
                q0 = Q[i, 0]
                q1 = Q[i, 1]
                q2 = Q[i, 2]
                j = cand[t]
                d = _d2(q0, q1, q2, rf, j)
                ok = d < bd[t]
                if ok:
                    best[t] = j
                    bd[t] = d
                    # the next round's ring (not used after the last allowed round)
                    kk, de = _ring(q0, q1, q2, j, rf, rh, rs)
                    jn = np.int64(ri[j, NBR + kk])
                    cand[t] = jn
                    _fetch(rf, jn)
                    ok = de < d
                live[k2] = t
                k2 += ok
            k = k2
            moves += 1
            if moves > max_moves:
                break
        if with_rows:
            for t in range(m):
                if best[t] >= 0:
                    prefetch(rows, best[t] * 4)
        for t in range(m):
            b = best[t]
            i = s + t
            index[i] = b
            if b < 0:
                d2[i] = np.inf
                n_far += 1
                continue
            d2[i] = bd[t]
            if patches:
                # _answer's body, written out: calling it here (inline='always') made the
                # demo panel's 652k queries 2.5x slower (85 -> 155-239 ms, one thread)
                f0, f1, f2, d, cl, n0, n1, n2 = _project_one(Q[i, 0], Q[i, 1], Q[i, 2], b,
                                                             rf, rh, rs)
                foot[i, 0] = f0
                foot[i, 1] = f1
                foot[i, 2] = f2
                dist[i] = d
                clamped[i] = cl
                normal[i, 0] = n0
                normal[i, 1] = n1
                normal[i, 2] = n2
                if with_rows:
                    face[i] = rows[b, 0]
                    out_uv[i, 0] = uv[b, 1]
                    out_uv[i, 1] = uv[b, 2]
                    onb[i] = cl and boundary[b]
    return n_far
