"""Building the DVG cell tree (:func:`build_tree`; the tree itself: :mod:`.dvg`).

Levels are built one after the other, breadth first: the top grid (level 0), then the 8
children of every cell refined on the level above.  Each cell is classified (FAR, single-seed
leaf, multi-seed leaf or refined, see :mod:`.dvg`) from the exact nearest model point of its
vertices (and, for the cells that failed, of 7 more samples).  On the top grid those nearest
points come from a search of the model points binned on it
(:func:`._lattice_kernels.grid_nearest`); every refined cell then carries a candidate list (the
model points that can be nearest anywhere in it, :mod:`._build_kernels`) that its children
search by brute force and prune for their own children.  The tree is the one a kd-tree at
every vertex gave (same arrays), at a fraction of the cost: each level's cells search a few
dozen candidates instead of a kd-tree, and share them between their 27 lattice points.

The refined cells of a level are kept in ``SEGMENTS`` segments, each with its own candidate
lists: a segment's lists are freed as soon as its children's lists are built, so that two
levels' lists are never all held together.

Cells are independent, so every level is classified on all threads (``run_chunks``), with
results identical for any number of threads.
"""

from __future__ import annotations

import logging

import numpy as np
from shapeverify._lazy import cKDTree

from . import _build_kernels as _bk
from . import _classify_kernels, _kernels
from . import _lattice_kernels as _lk
from . import _seedlist_kernels as _sk
from ._threads import run_chunks
from dataclasses import dataclass
from shapeverify._renamed import grouped_keywords

logger = logging.getLogger(__name__)

__all__ = ["TreeLimits", "build_tree"]

SEGMENTS = 8  # the refined cells of a level are handled in this many segments
_CORNER = np.array([[o & 1, (o >> 1) & 1, (o >> 2) & 1] for o in range(8)], dtype=np.int64)


def _top_grid(lo, hi, spacing, max_top_cells):
    cell = 8.0 * spacing
    while True:
        dims = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1)
        if int(np.prod(dims)) <= max_top_cells:
            return cell, dims
        cell *= 2.0


def _views(rec):
    return (rec, rec.view(np.int32), rec.view(np.int16), rec.view(np.float32))


def _chunked(fn, n, min_chunk, part=1 << 14):
    """run_chunks over range(n) for a kernel returning (counts, buffer) per chunk; the chunks'
    outputs joined in order: (counts (n,) int64, buffer int32).  Each thread's chunk is run
    in parts of at most ``part`` cells, so that the join, which copies one part at a time
    into the result and frees it, holds little more than the lists themselves."""
    parts = {}

    def one(a, b):
        for c in range(a, b, part):
            parts[c] = fn(c, min(b, c + part))

    run_chunks(one, n, min_chunk)
    keys = sorted(parts)
    counts = np.concatenate([parts[k][0] for k in keys]) if keys else np.zeros(0, np.int64)
    # joined part by part, each freed once copied: the pages of ``buf`` are touched as the
    # parts go, so the lists are not resident twice (np.concatenate would hold both)
    buf = np.empty(sum(parts[k][1].shape[0] for k in keys), dtype=np.int32)
    pos = 0
    for k in keys:
        b = parts.pop(k)[1]
        buf[pos:pos + b.shape[0]] = b
        pos += b.shape[0]
        del b
    return counts, buf


def _offsets(counts):
    off = np.zeros(counts.shape[0] + 1, dtype=np.int64)
    np.cumsum(counts, out=off[1:])
    return off


def _top_level(cells, origin, size, dims, bins, pts, RV, reach, max_moves):
    """Level 0: exact nearest points of the top grid's vertices (a search of the points
    binned on the top grid, :func:`._lattice_kernels.grid_nearest`: what a kd-tree bounded at
    reach + 3.03 r gave for every vertex of a cell that is not FAR; inf for the
    others beyond reach + 1.01 r), classification.

    Returns (kind, first, samples, nn_i, nn_d)."""
    m = cells.shape[0]
    r = 0.5 * np.sqrt(3.0) * size
    vdims = dims + 1
    # the vertices of the whole grid (every one belongs to a cell of the full top grid),
    # numbered in raster order: a cell's samples are its vertices' numbers
    samples = np.empty((m, 8), dtype=np.int64)
    for o in range(8):
        samples[:, o] = (((cells[:, 0] + _CORNER[o, 0]) * vdims[1] + cells[:, 1]
                          + _CORNER[o, 1]) * vdims[2] + cells[:, 2] + _CORNER[o, 2])
    ukey = np.arange(int(np.prod(vdims)), dtype=np.int64)
    uvx = np.stack([ukey // (vdims[1] * vdims[2]), (ukey // vdims[2]) % vdims[1],
                    ukey % vdims[2]], axis=1)
    del ukey
    nn_i = np.empty(uvx.shape[0], dtype=np.int64)
    nn_d = np.empty(uvx.shape[0])

    def _search(vx, bound, out_i, out_d):
        def one(a, b):
            _lk.grid_nearest(vx[a:b], pts, bins[0], bins[1], dims, origin, size, bound,
                             out_i[a:b], out_d[a:b])
        run_chunks(one, vx.shape[0], 1 << 12)

    # first up to the FAR test's distance (reach + r): exact for every vertex that
    # makes a cell not FAR, so the FAR cells are known; then, up to reach + 3 r (a
    # cell that is not FAR has all its vertices within it), the other vertices of the cells
    # that are not FAR.  (The other vertices only take part in FAR tests.)
    _search(uvx, reach + 1.01 * r, nn_i, nn_d)
    near = samples[nn_d[samples].min(axis=1) <= reach + r]
    redo = np.unique(near[~np.isfinite(nn_d[near])])
    del near
    if redo.size:
        ri, rd = np.empty(redo.size, dtype=np.int64), np.empty(redo.size)
        _search(np.ascontiguousarray(uvx[redo]), reach + 3.03 * r, ri, rd)
        nn_i[redo] = ri
        nn_d[redo] = rd
    del uvx, redo
    kind = np.empty(m, dtype=np.int8)
    first = np.empty(m, dtype=np.int64)

    def _classify(a, b):
        _classify_kernels.classify(cells[a:b], origin, size, samples[a:b], nn_i, nn_d, *RV,
                          float(reach), int(max_moves), kind[a:b], first[a:b])

    run_chunks(_classify, m, 1 << 14)
    return kind, first, samples, nn_i, nn_d


def _top_multi(fail, cells, origin, size, dims, kd, n, RV, samples, nn_i, nn_d, first,
               reach, max_moves, max_seeds, last, workers):
    """Multi-seed classification of failed top cells (only when the top grid is the last
    level): extra samples from the kd-tree."""
    r = 0.5 * np.sqrt(3.0) * size
    fc = cells[fail]
    E = (2 * fc[:, None, :] + _classify_kernels.EXTRA[None, :, :]).reshape(-1, 3)
    edims = 2 * dims + 1
    ekey = (E[:, 0] * edims[1] + E[:, 1]) * edims[2] + E[:, 2]
    uek, einv = np.unique(ekey, return_inverse=True)
    exyz = np.stack([uek // (edims[1] * edims[2]), (uek // edims[2]) % edims[1],
                     uek % edims[2]], axis=1)
    xn_d, xn_i = kd.query(origin + 0.5 * size * exyz,
                          distance_upper_bound=reach + 4.04 * r, workers=workers)
    xn_i = np.where(xn_i >= n, 0, xn_i).astype(np.int64)
    fkind = np.empty(fail.size, dtype=np.int8)
    fseeds = np.empty((fail.size, 16), dtype=np.int32)
    fn = np.empty(fail.size, dtype=np.int32)
    fs = np.ascontiguousarray(samples[fail])
    ex = np.ascontiguousarray(einv.reshape(-1, 7), dtype=np.int64)
    f1 = np.ascontiguousarray(first[fail])
    _classify_kernels.classify_multi(fc, origin, size, fs, nn_i, nn_d, ex, xn_i, xn_d, f1, *RV,
                            int(max_moves), int(max_seeds), last, fkind, fseeds, fn)
    return fkind, fseeds, fn


def _bin_points(pts, origin, cell, dims):
    """The points binned on the top grid: (their order by bin, the start of each bin's run
    (dims.prod() + 1,))."""
    g = np.floor((pts - origin) / cell).astype(np.int64)
    np.clip(g, 0, dims - 1, out=g)
    bid = (g[:, 0] * dims[1] + g[:, 1]) * dims[2] + g[:, 2]
    del g
    order = np.argsort(bid, kind="stable")
    start = np.zeros(int(np.prod(dims)) + 1, dtype=np.int64)
    np.cumsum(np.bincount(bid, minlength=int(np.prod(dims))), out=start[1:])
    return order, start


def _top_candidates(ref, cells, samples, nn_i, nn_d, pts, origin, cell, dims, bins,
                    segments=1):
    """Candidate lists of the refined top cells (``bins``: :func:`_bin_points`), in
    ``segments`` segments (:func:`_classify_level`): (their coordinates, segments)."""
    order, start = bins
    # the points' coordinates and indices in bin order (8 entries of padding): read 8 at a
    # time by the tests
    sx, sy, sz = (np.concatenate([pts[order, k], np.zeros(8)]) for k in range(3))
    sid = np.concatenate([order.astype(np.int32), np.zeros(8, dtype=np.int32)])
    rc = np.ascontiguousarray(cells[ref])
    vi = np.ascontiguousarray(nn_i[samples[ref]])
    vd = np.ascontiguousarray(nn_d[samples[ref]])
    segs = []
    cuts = np.linspace(0, ref.size, segments + 1).astype(np.int64)
    for s0, s1 in zip(cuts[:-1].tolist(), cuts[1:].tolist()):
        if s1 > s0:
            counts, lst = _chunked(lambda a, b: _bk.top_lists(
                rc[s0 + a:s0 + b], vi[s0 + a:s0 + b], vd[s0 + a:s0 + b], pts, sx, sy, sz, sid,
                start, dims, origin, cell), s1 - s0, 1 << 10)
            segs.append([s0, s1, _offsets(counts), lst, None])
    return rc, segs


def _classify_level(segs, parents, m, pts, origin, size, RV, md, max_moves):
    """:func:`._build_kernels.classify_children` for the children of every segment of the
    refined cells of the level above.  A segment ``[p0, p1, off, lst, lat]`` holds the
    candidate lists of parents p0..p1 (``off`` local); the lattice nearest points ``lat``
    are stored into it.  (Segments let each one's lists be freed as soon as its children's
    lists are built, :func:`_child_segments`.)  Returns (kind, first seed, first failing
    vertex) of the m children."""
    kind = np.empty(m, dtype=np.int8)
    first = np.empty(m, dtype=np.int32)  # point indices (n < 2**31)
    ffail = np.empty(m, dtype=np.int8)
    for sg in segs:
        p0, p1, so, sl, _ = sg
        lat = sg[4] = np.empty((p1 - p0, 27), dtype=np.int32)

        def _classify(a, b):
            q0, q1 = p0 + a, p0 + b
            _bk.classify_children(parents[q0:q1], so[a:b + 1], sl, pts, origin, size, *RV,
                                  md, int(max_moves), kind[8 * q0:8 * q1],
                                  first[8 * q0:8 * q1], lat[a:b], ffail[8 * q0:8 * q1])

        run_chunks(_classify, p1 - p0, 1 << 11)
    return kind, first, ffail


def _multi_level(segs, fail, parents, first, ffail, pts, origin, size, RV, max_moves,
                 max_seeds, last, cols):
    """:func:`._build_kernels.multi_children` for the failed children ``fail`` (sorted),
    segment by segment: (kind, seeds (F, cols), seed counts)."""
    fkind = np.empty(fail.size, dtype=np.int8)
    fseeds = np.empty((fail.size, cols), dtype=np.int32)
    fn = np.empty(fail.size, dtype=np.int32)
    for p0, p1, so, sl, lat in segs:
        f0, f1 = np.searchsorted(fail, (8 * p0, 8 * p1)).tolist()
        ids = fail[f0:f1] - 8 * p0
        pl, fs, ff = parents[p0:p1], first[8 * p0:8 * p1], ffail[8 * p0:8 * p1]

        def _multi(a, b):
            _bk.multi_children(ids[a:b], pl, so, sl, lat, pts, origin, size, fs, ff, *RV,
                               int(max_moves), int(max_seeds), last, fkind[f0 + a:f0 + b],
                               fseeds[f0 + a:f0 + b], fn[f0 + a:f0 + b])

        if f1 > f0:
            run_chunks(_multi, f1 - f0, 1 << 10)
    return fkind, fseeds, fn


def _child_segments(segs, ref, parents, pts, origin, size):
    """The candidate lists of the refined children ``ref`` (sorted child numbers), as the
    next level's segments; each segment of ``segs`` is freed (the list emptied) once its
    children's lists are built."""
    new = []
    for i in range(len(segs)):
        p0, p1, so, sl, lat = segs[i]
        segs[i] = None
        r0, r1 = np.searchsorted(ref, (8 * p0, 8 * p1)).tolist()
        ids = ref[r0:r1] - 8 * p0
        pl = parents[p0:p1]
        if r1 > r0:
            counts, cl = _chunked(lambda a, b: _bk.child_lists(ids[a:b], pl, so, sl, lat, pts,
                                                               origin, size), r1 - r0, 1 << 11)
            new.append([r0, r1, _offsets(counts), cl, None])
        del so, sl, lat  # this segment's lists, before the next segment's children
    return new


@dataclass(frozen=True)
class TreeLimits:
    """Limits of :func:`build_tree` (its ``limits=``; the loose keywords of these names still
    work, with a DeprecationWarning); the fields are described in the Parameters of
    :func:`build_tree`."""

    max_moves: int = 2
    max_seeds: int = 4
    tree_budget: float = 52.0
    max_top_cells: int = 1 << 22


@grouped_keywords("limits", TreeLimits)
def build_tree(rec: np.ndarray, spacing: float, reach: float, *, kd: cKDTree | None = None,
               multi_size: float | None = None, finest: float | None = None, workers: int = -1,
               limits: TreeLimits = TreeLimits()):
    """Build the DVG tree over model point records (:func:`.dvg.make_records`).

    Parameters
    ----------
    rec : (N + 1, 16) float64 model point records, N >= 1
    spacing : float > 0
        Model point spacing h (mm); sets the top cell size (8 h, doubled while the top grid
        would exceed ``max_top_cells`` cells) and the finest cell size (``finest``, default
        h / 2).
    reach : float > 0
        Queries within this distance of the model are answered by the tree.
    kd : cKDTree over the points, optional (spares a copy of the points; built when not
        given and needed: only when the top grid is the last level)
    limits : TreeLimits
        Groups ``max_moves``, ``max_seeds``, ``tree_budget``, ``max_top_cells`` (described
        below); the loose keywords still work, with a DeprecationWarning.
    max_moves : int
        Greedy walk budget a leaf may need at its vertices (larger: fewer, bigger leaves and
        slower queries).
    max_seeds : int
        Most seeds of a multi-seed leaf above the last level.
    multi_size : float, optional
        Largest cell that may become a multi-seed leaf (default 2 h).
    tree_budget : float
        Bytes per model point the tree may take: when refining the failed cells of a level
        would exceed it, they become multi-seed leaves instead (as on the last level; the
        answers stay verified at their samples, the queries get a little slower).
    workers : int
        Threads for the kd-tree queries at the top grid's extra samples (only when the top
        grid is the last level).

    Returns
    -------
    DVGTree
    """
    max_moves = limits.max_moves
    max_seeds = limits.max_seeds
    tree_budget = limits.tree_budget
    max_top_cells = limits.max_top_cells
    from .dvg import DVGTree

    points = rec[:-1, :3]
    RV = _views(rec)
    n = points.shape[0]
    if (kd is not None and kd.data.shape == points.shape and kd.data.dtype == np.float64
            and kd.data.flags.c_contiguous and np.array_equal(kd.data, points)):
        pts = kd.data  # the kd-tree's points (cKDTree keeps the caller's array): no copy
    else:
        pts = np.ascontiguousarray(points)
    pad = 1e-9 * (1.0 + float(np.abs(pts).max()))
    lo = pts.min(axis=0) - reach - pad
    hi = pts.max(axis=0) + reach + pad
    cell, dims = _top_grid(lo, hi, spacing, max_top_cells)
    finest = 0.5 * spacing if finest is None else finest
    multi_size = 2.0 * spacing if multi_size is None else multi_size
    max_level = max(0, int(np.ceil(np.log2(cell / finest))))
    origin = np.ascontiguousarray(lo, dtype=np.float64)
    md = float(reach)

    n_top = int(np.prod(dims))
    ii, jj, kk = np.meshgrid(*(np.arange(d, dtype=np.int64) for d in dims), indexing="ij")
    cells = np.stack([ii.ravel(), jj.ravel(), kk.ravel()], axis=1)
    del ii, jj, kk
    blocks = [np.full(n_top, _kernels.FAR, dtype=np.int32)]
    n_nodes = n_top
    lists: list[np.ndarray] = []
    n_list = 0
    depth = 0
    parents = segs = None  # refined cells of the level above, their candidate lists
    m = n_top
    for level in range(max_level + 1):
        if m == 0:
            break
        depth = level
        size = cell / 2.0 ** level
        if level == 0:
            bins = _bin_points(pts, origin, cell, dims)
            kind, first, samples, nn_i, nn_d = _top_level(cells, origin, size, dims, bins, pts,
                                                          RV, md, max_moves)
        else:
            kind, first, ffail = _classify_level(segs, parents, m, pts, origin, size, RV, md,
                                                 max_moves)
            logger.debug("DVG level %d: %d cells classified", level, m)
        # the node codes go straight into the level's int32 block (FAR already), each kind's
        # range checked before it is written
        code = blocks[-1]
        single = kind == 1
        sel = first[single]  # -(seed + 2) fits in int32 (see _check_codes): no int64 copies
        sel += 2
        code[single] = np.negative(sel, out=sel)
        del sel
        fail = np.flatnonzero(kind == 2)
        n_multi = 0
        # refining the failed cells adds 8 nodes each and, on the next level, seed lists
        # (about 8 more int32 per refined cell); beyond the budget this level is the last
        last = level == max_level or (
            level > 0 and 4 * (n_nodes + n_list + 16 * fail.size) > tree_budget * n)
        if last and level < max_level - 1 and fail.size:
            logger.warning("DVG tree: memory budget reached at level %d of %d (%d cells left "
                           "unrefined): near-surface queries will be slower; give a smaller "
                           "reach or a coarser spacing", level, max_level, fail.size)
        if fail.size and (size <= multi_size or last):
            if level == 0:
                kd = cKDTree(pts) if kd is None else kd  # (only here)
                fkind, fseeds, fn = _top_multi(fail, cells, origin, size, dims, kd, n, RV,
                                               samples, nn_i, nn_d, first, md, max_moves,
                                               max_seeds, last, workers)
            else:
                # above the last level a cell stops as soon as it has more than max_seeds
                # seeds, so max_seeds + 1 columns hold them (16 on the last level)
                fkind, fseeds, fn = _multi_level(segs, fail, parents, first, ffail, pts,
                                                 origin, size, RV, max_moves, max_seeds, last,
                                                 16 if last else max_seeds + 1)
            logger.debug("DVG level %d: multi-seed pass over %d failed cells", level, fail.size)
            kind[fail] = fkind
            ok = fkind == 1
            mi = fail[ok]
            n_multi = mi.size
            if mi.size:
                if mi.size == fail.size:  # all of them (always on the last level): no copy
                    buf, where = _pack_lists(fseeds, fn)
                else:
                    buf, where = _pack_lists(fseeds[ok], fn[ok])
                _check_codes(n + n_list + buf.shape[0] + 2)
                code[mi] = -(n + n_list + where + 2)
                lists.append(buf)
                n_list += buf.shape[0]
                logger.debug("DVG level %d: %d seed lists packed", level, mi.size)
            del fkind, fseeds, fn
        ref = np.flatnonzero(kind == 2)
        _check_codes(n_nodes + 8 * ref.size)
        code[ref] = n_nodes + 8 * np.arange(ref.size, dtype=np.int64)
        logger.debug("DVG level %d: %d cells (size %.4g): %d far, %d leaves (%d multi-seed), "
                     "%d refined%s", level, m, size, int((kind == 0).sum()),
                     int((kind == 1).sum()), n_multi, ref.size, " (last level)" if last else "")
        del code, kind, single, first  # (the first seeds are in the codes now)
        ffail = None
        if ref.size:
            if level == 0:
                parents, segs = _top_candidates(ref, cells, samples, nn_i, nn_d, pts, origin,
                                                cell, dims, bins, SEGMENTS)
                del cells, samples, nn_i, nn_d, bins
            else:
                nxt = 2 * parents[ref // 8] + _CORNER[ref % 8]
                segs = _child_segments(segs, ref, parents, pts, origin, size)
                parents = nxt
                del nxt
            logger.debug("DVG level %d: candidate lists of the refined cells: %.1f points "
                         "each", level, sum(sg[3].size for sg in segs) / max(1, ref.size))
            blocks.append(np.full(8 * ref.size, _kernels.FAR, dtype=np.int32))
            n_nodes += 8 * ref.size
            m = 8 * ref.size
        else:
            m = 0
        _check_codes(n_nodes + n + n_list)
    nodes = np.concatenate(blocks)  # int32 blocks
    lst_out = (np.concatenate(lists).astype(np.int32) if lists
               else np.zeros(0, dtype=np.int32))
    return DVGTree(origin, float(cell), dims.astype(np.int64), nodes, lst_out, n, md, depth)


def _check_codes(largest: int) -> None:
    """ValueError if a node code (a child index, or -(point or seed-list index + 2)) as
    large as ``largest`` would not fit in int32."""
    if largest >= 2**31 - 2:
        raise ValueError("the DVG tree is too large for int32 codes; increase the spacing "
                         "or decrease reach")


def _pack_lists(seeds: np.ndarray, count: np.ndarray):
    """Seed lists (M, 16) with counts (M,) -> (buffer of count, seeds..., offset of each list).

    Identical lists (same seeds in any order) are stored once, in lexicographic order of their
    sorted seeds (the order ``np.unique(axis=0)`` gave; :mod:`._seedlist_kernels`, without
    (M, 16) temporaries).  ``seeds`` is sorted in place.
    """
    cnt = count.astype(np.int64)
    key = _sk.sort_rows(seeds, cnt)
    return _sk.pack_sorted(seeds, cnt, key, np.argsort(key, kind="stable"))
