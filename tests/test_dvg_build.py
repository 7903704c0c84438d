"""The DVG build's candidate lists: every point of a refined cell finds its exact nearest model
point (scipy cKDTree) among the cell's candidates, on the top grid and one level down."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from shapeverify.nearest import _build_kernels as bk
from shapeverify.nearest import dvg, dvg_build

H = 0.25


def _two_sheets(n=60, gap=1.0, seed=0):
    """A wavy sheet and a second one ``gap`` above it (a medial surface between), jittered."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.arange(n) * H, np.arange(n) * H)
    u = u.ravel() + rng.uniform(-0.3, 0.3, u.size) * H
    v = v.ravel() + rng.uniform(-0.3, 0.3, v.size) * H
    z = 0.6 * np.sin(u / 2.0) * np.cos(v / 3.0)
    pts = np.concatenate([np.column_stack([u, v, z]), np.column_stack([v, u, gap + z])])
    return np.ascontiguousarray(pts[dvg.morton_order(pts, H)])


def _in_cells(cells, origin, size, k, rng):
    """k random points in each cell (R, 3) plus its corners: ((R, k + 8, 3) points)."""
    corner = np.array([[o & 1, (o >> 1) & 1, (o >> 2) & 1] for o in range(8)], dtype=float)
    f = np.concatenate([rng.uniform(0, 1, (cells.shape[0], k, 3)),
                        np.broadcast_to(corner, (cells.shape[0], 8, 3))], axis=1)
    return origin + size * (cells[:, None, :] + f)


def _check_lists(cells, off, lst, origin, size, pts, kd, rng):
    q = _in_cells(cells, origin, size, 24, rng)
    d_true, _ = kd.query(q.reshape(-1, 3))
    d_true = d_true.reshape(q.shape[:2])
    for c in range(cells.shape[0]):
        cand = lst[off[c]:off[c + 1]]
        assert cand.size > 0
        d = np.sqrt(((q[c][:, None, :] - pts[cand][None, :, :]) ** 2).sum(axis=2)).min(axis=1)
        np.testing.assert_allclose(d, d_true[c], rtol=1e-12, atol=1e-12)
    return (off[1:] - off[:-1]).mean()


def _top_level_of_two_sheets(md):
    """The two sheets' points, kd-tree, record views and top grid classified at reach ``md``."""
    pts = _two_sheets()
    kd = cKDTree(pts)
    rv = dvg.views(dvg.make_records(pts, dvg.neighbor_graph(pts, tree=kd)))
    pad = 1e-9 * (1.0 + float(np.abs(pts).max()))
    origin = pts.min(axis=0) - md - pad
    cell, dims = dvg_build._top_grid(origin, pts.max(axis=0) + md + pad, H, 1 << 22)
    ii, jj, kk = np.meshgrid(*(np.arange(d) for d in dims), indexing="ij")
    cells = np.stack([ii.ravel(), jj.ravel(), kk.ravel()], axis=1).astype(np.int64)
    bins = dvg_build._bin_points(pts, origin, cell, dims)
    top = dvg_build._top_level(cells, origin, cell, dims, bins, pts, rv, md, 2)
    return pts, kd, rv, origin, cell, dims, cells, top


@pytest.mark.parametrize("md", [0.5, 2.0])
def test_candidate_lists_hold_the_nearest_point_of_every_point_of_the_cell(md):
    pts, kd, rv, origin, cell, dims, cells, top = _top_level_of_two_sheets(md)
    kind, first, samples, nn_i, nn_d = top
    ref = np.flatnonzero(kind == 2)
    assert ref.size > 20
    rng = np.random.default_rng(1)
    parents, [(_, _, off, lst, _)] = dvg_build._top_candidates(
        ref, cells, samples, nn_i, nn_d, pts, origin, cell, dims,
        dvg_build._bin_points(pts, origin, cell, dims))
    mean_top = _check_lists(parents, off, lst, origin, cell, pts, kd, rng)
    # the lists are short: witnesses prune far more than the distance bound alone
    assert mean_top < 0.25 * pts.shape[0]
    # one level down: every child of the first 40 refined top cells
    sel = np.arange(8 * min(40, parents.shape[0]), dtype=np.int64)
    m = 8 * parents.shape[0]
    kind1, seed1 = np.empty(m, np.int8), np.empty(m, np.int64)
    lat = np.empty((parents.shape[0], 27), np.int32)
    bk.classify_children(parents, off, lst, pts, origin, 0.5 * cell, *rv, md, 2, kind1, seed1,
                         lat, np.empty(m, np.int8))
    counts, clst = bk.child_lists(sel, parents, off, lst, lat, pts, origin, 0.5 * cell)
    coff = np.concatenate([[0], np.cumsum(counts)])
    children = 2 * parents[sel // 8] + np.array(
        [[o & 1, (o >> 1) & 1, (o >> 2) & 1] for o in range(8)])[sel % 8]
    _check_lists(children, coff, clst, origin, 0.5 * cell, pts, kd, rng)
    assert counts.mean() < (off[1:] - off[:-1])[:40].mean()  # children prune their parent's


def test_built_tree_answers_near_queries_like_a_kd_tree_on_two_sheets():
    """Queries inside the reach, between and around the sheets: the exact share of the tree's
    documented guarantee (verified at every vertex and sample), excess below a spacing."""
    pts = _two_sheets()
    t = dvg.DVG.build(pts, H, 1.0)
    rng = np.random.default_rng(2)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    q = rng.uniform(lo - 0.5, hi + 0.5, (40_000, 3))
    d_true, _ = cKDTree(pts).query(q)
    q, d_true = q[d_true <= 1.0], d_true[d_true <= 1.0]
    idx, d = t.nearest(q)
    right = d <= d_true * (1 + 1e-12) + 1e-12
    assert right.mean() >= 0.999
    assert np.all(d - d_true <= H)


def _pack_with_unique(seeds, count):
    """The seed-list packing as np.unique(axis=0) gave it (the reference order)."""
    big = np.iinfo(np.int32).max
    col = np.arange(seeds.shape[1])[None, :] < count[:, None]
    key = np.sort(np.where(col, seeds, big), axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    ucnt = (uniq != big).sum(axis=1)
    pos = np.concatenate([[0], np.cumsum(ucnt + 1)[:-1]])
    buf = np.empty(int((ucnt + 1).sum()), dtype=np.int32)
    buf[pos] = ucnt
    ucol = np.arange(uniq.shape[1])[None, :] < ucnt[:, None]
    buf[(pos[:, None] + 1 + np.arange(uniq.shape[1])[None, :])[ucol]] = uniq[ucol]
    return buf, pos[inv.ravel()]


@pytest.mark.parametrize("seed", range(4))
def test_seed_list_packing_equals_the_np_unique_packing(seed):
    """Repeated lists in any order, duplicates inside a list, 1-16 seeds: the same buffer and
    offsets as np.unique(axis=0) of the sorted, padded rows; every row reads back its set."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 2000))
    seeds = rng.integers(0, int(rng.integers(2, 60)), (m, 16)).astype(np.int32)
    count = rng.integers(1, 17, m).astype(np.int32)
    want = _pack_with_unique(seeds, count)
    buf, where = dvg_build._pack_lists(seeds.copy(), count)
    assert np.array_equal(buf, want[0]) and np.array_equal(where, want[1])
    for i in range(m):
        got = buf[where[i] + 1:where[i] + 1 + buf[where[i]]]
        assert np.array_equal(got, np.sort(seeds[i, :count[i]]))


@pytest.mark.parametrize("seed", range(3))
def test_lattice_searches_equal_one_search_per_point(seed):
    """The 27 lattice points' (and 7 extra samples') nearest points found in one pass over a
    list are those of one linear scan per point, distances bit for bit, ties to the lower
    index (a coarse integer grid of points makes many exact ties)."""
    from shapeverify.nearest import _classify_kernels as ck
    from shapeverify.nearest import _lattice_kernels as lk

    rng = np.random.default_rng(seed)
    pts = np.ascontiguousarray(rng.integers(-4, 5, (400, 3)).astype(np.float64)
                               * rng.choice([0.5, 0.1]))
    pts[::2] += rng.normal(0.0, 0.05, (200, 3))
    lst = rng.permutation(400).astype(np.int32)
    origin = rng.normal(0.0, 0.1, 3) if seed else np.zeros(3)
    size = 0.5
    sq = np.empty(lk.SCRATCH)
    for a, b in ((0, 400), (17, 90), (5, 5)):
        base = rng.integers(-3, 3, 3)
        qx, qy, qz = (origin[k] + size * (base[k] + np.arange(3)) for k in range(3))
        li, ld = np.empty(27, np.int64), np.empty(27)
        lk.nn_lattice(qx, qy, qz, pts, lst, a, b, sq, li, ld)
        for t in range(27):
            want = lk.nn_one(qx[t % 3], qy[t // 3 % 3], qz[t // 9], pts, lst, a, b)
            assert (li[t], ld[t]) == want
        xi, xd = np.empty(7, np.int64), np.empty(7)
        lk.nn_extra(qx, qy, qz, ck.EXTRA, pts, lst, a, b, sq, xi, xd)
        for e, (i, j, k) in enumerate(ck.EXTRA):
            assert (xi[e], xd[e]) == lk.nn_one(qx[i], qy[j], qz[k], pts, lst, a, b)


@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
@pytest.mark.parametrize("last", [False, True])
def test_children_classification_and_multi_seed_pass_equal_the_kd_tree_kernels(last):
    """One level below the top grid of the two sheets: ``classify_children`` and
    ``multi_children`` (candidate lists, lattice reuse, the last level's skipped re-walks)
    give the kinds, first seeds and seed lists of ``_classify_kernels.classify`` /
    ``classify_multi`` fed with a kd-tree's exact nearest points."""
    from shapeverify.nearest import _classify_kernels as _kernels

    md = 1.0
    pts, kd, rv, origin, cell, dims, cells, top = _top_level_of_two_sheets(md)
    n = pts.shape[0]
    kind, first, samples, nn_i, nn_d = top
    ref = np.flatnonzero(kind == 2)
    parents, [(_, _, off, lst, _)] = dvg_build._top_candidates(
        ref, cells, samples, nn_i, nn_d, pts, origin, cell, dims,
        dvg_build._bin_points(pts, origin, cell, dims))
    size = 0.5 * cell
    m = 8 * parents.shape[0]
    kind1, first1 = np.empty(m, np.int8), np.empty(m, np.int64)
    lat, ffail = np.empty((parents.shape[0], 27), np.int32), np.empty(m, np.int8)
    bk.classify_children(parents, off, lst, pts, origin, size, *rv, md, 2, kind1, first1, lat,
                         ffail)
    # the reference: the same cells with kd-tree nearest points at vertices and extra samples
    child = (2 * parents[:, None, :] + dvg_build._CORNER[None, :, :]).reshape(-1, 3)
    vert = (child[:, None, :] + dvg_build._CORNER[None, :, :]).reshape(-1, 3)
    vd, vi = kd.query(origin + size * vert)
    kind0, first0 = np.empty(m, np.int8), np.empty(m, np.int64)
    smp = np.arange(8 * m, dtype=np.int64).reshape(m, 8)
    _kernels.classify(child, origin, size, smp, vi.astype(np.int64), vd, *rv, md, 2, kind0,
                      first0)
    assert np.array_equal(kind1, kind0)
    assert np.array_equal(first1[kind0 > 0], first0[kind0 > 0])
    fail = np.flatnonzero(kind1 == 2)
    assert fail.size > 50
    fk, fs, fn = (np.empty(fail.size, np.int8), np.zeros((fail.size, 16), np.int32),
                  np.empty(fail.size, np.int32))
    bk.multi_children(fail, parents, off, lst, lat, pts, origin, size, first1, ffail, *rv, 2, 4,
                      last, fk, fs, fn)
    ext = (2 * child[fail][:, None, :] + _kernels.EXTRA[None, :, :]).reshape(-1, 3)
    xd, xi = kd.query(origin + 0.5 * size * ext)
    gk, gs, gn = (np.empty(fail.size, np.int8), np.zeros((fail.size, 16), np.int32),
                  np.empty(fail.size, np.int32))
    _kernels.classify_multi(child[fail], origin, size, smp[fail], vi.astype(np.int64), vd,
                            np.arange(7 * fail.size, dtype=np.int64).reshape(-1, 7),
                            xi.astype(np.int64), xd, first1[fail], *rv, 2, 4, last, gk, gs, gn)
    if last:  # every cell a leaf, with all its seeds
        assert np.all(fk == 1) and np.array_equal(fn, gn)
        col = np.arange(16)[None, :] < gn[:, None]
        assert np.array_equal(np.where(col, fs, 0), np.where(col, gs, 0))
    else:  # refined cells stop early (seeds not needed); the leaves' seeds are the same
        assert np.array_equal(fk, gk)
        leaf = gk == 1
        assert np.array_equal(fn[leaf], gn[leaf])
        col = np.arange(16)[None, :] < gn[leaf, None]
        assert np.array_equal(np.where(col, fs[leaf], 0), np.where(col, gs[leaf], 0))


@pytest.mark.parametrize("seed", range(3))
def test_grid_neighbour_graph_equals_the_kd_tree_graph(seed):
    """The grid search (with the kd-tree asked about points with near ties) gives the kd-tree's
    graph, order included: a jittered sheet, an exact lattice full of equal distances,
    duplicated points, a sparse outlier."""
    rng = np.random.default_rng(seed)
    a = np.stack(np.meshgrid(np.arange(40.0), np.arange(30.0), [0.0], indexing="ij"),
                 -1).reshape(-1, 3) * 0.5
    b = a + np.array([0.1, 0.2, 3.0]) + rng.normal(0.0, 0.05, a.shape)
    pts = np.concatenate([a, b, b[:50], [[100.0, 100.0, 100.0]]])
    pts = np.ascontiguousarray(pts[rng.permutation(len(pts))])
    kd = cKDTree(pts)
    want = dvg.neighbor_graph(pts, tree=kd)
    got = dvg.neighbor_graph(pts, tree=kd, spacing=0.5 * rng.uniform(0.5, 2.0))
    assert np.array_equal(got, want)


def test_morton_order_equals_the_bitwise_numpy_codes():
    """The Morton codes of the kernel are those of the numpy bit loop it replaced."""
    rng = np.random.default_rng(3)
    p = rng.normal(0.0, 50.0, (5000, 3))
    for cell in (0.1, 1e-7, 10.0):
        g = np.floor((p - p.min(axis=0)) / cell).astype(np.int64)
        g >>= max(0, int(g.max()).bit_length() - 21)
        code = np.zeros(p.shape[0], dtype=np.int64)
        for bit in range(21):
            for ax in range(3):
                code |= ((g[:, ax] >> bit) & 1) << (3 * bit + ax)
        assert np.array_equal(dvg.morton_order(p, cell), np.argsort(code, kind="stable"))


def test_grid_neighbour_graph_falls_back_for_a_tiny_spacing_and_checks_it():
    """A spacing so small that the grid's cell keys would overflow: the kd-tree's graph; a
    spacing that is not a number > 0: ValueError."""
    pts = np.random.default_rng(0).uniform(-1e6, 1e6, (500, 3))
    kd = cKDTree(pts)
    assert np.array_equal(dvg.neighbor_graph(pts, tree=kd, spacing=1e-9),
                          dvg.neighbor_graph(pts, tree=kd))
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="spacing"):
            dvg.neighbor_graph(pts, tree=kd, spacing=bad)


def _other_face_by_kd_tree(points, face, spacing, radius=3.0, k=32):
    """The other-face links as the kd-tree alone gave them (the first point of another face
    among the k nearest within radius * spacing)."""
    n = points.shape[0]
    d, j = cKDTree(points).query(points, k=k, distance_upper_bound=radius * spacing)
    valid = j < n
    jj = np.where(valid, j, 0)
    diff = valid & (face[jj] != face[:, None])
    first = np.argmax(diff, axis=1)
    has = diff[np.arange(n), first]
    return np.where(has, jj[np.arange(n), first], -1).astype(np.int32)


@pytest.mark.parametrize("seed", [0, 1])
def test_other_face_links_on_the_grid_equal_the_kd_tree_links(seed):
    """prepare's other-face links, searched on a grid, are the kd-tree's: an exact lattice full
    of equal distances (points exactly at the search radius too) split into faces, a second
    jittered sheet, duplicates on another face, a dense cluster (more than k points within
    the radius) and a lone point."""
    from shapeverify.nearest.prepared import _other_face_points

    rng = np.random.default_rng(seed)
    h = 0.5
    a = np.stack(np.meshgrid(np.arange(30.0), np.arange(20.0), [0.0], indexing="ij"),
                 -1).reshape(-1, 3) * h
    fa = (a[:, 0] > 7.0).astype(np.int32) + 2 * (a[:, 1] > 4.0)
    b = a[::2] + np.array([0.1, 0.2, 0.6]) + rng.normal(0.0, 0.05, a[::2].shape)
    fb = np.full(len(b), 4, np.int32)
    dup = a[:40]
    fd = np.full(40, 5, np.int32)
    cl = np.array([5.0, 5.0, -0.3]) + rng.normal(0.0, 0.05, (60, 3))
    fc = rng.integers(0, 6, 60).astype(np.int32)
    pts = np.concatenate([a, b, dup, cl, [[100.0, 100.0, 100.0]]])
    face = np.concatenate([fa, fb, fd, fc, [0]]).astype(np.int32)
    perm = rng.permutation(len(pts))
    pts, face = np.ascontiguousarray(pts[perm]), face[perm]
    want = _other_face_by_kd_tree(pts, face, h)
    got = _other_face_points(pts, face, h, cKDTree(pts))
    assert (want >= 0).sum() > 300
    assert np.array_equal(got, want)


@pytest.mark.parametrize("seed", range(3))
def test_vector_witness_test_equals_the_scalar_one(seed):
    """``_intrinsics.beaten8`` (8 witnesses in one vector test, the last repeated in unused
    lanes, the point itself skipped) decides as the scalar loop it replaced, on points whose
    margin is near zero (coarse integer coordinates: many exact ties)."""
    from numba import njit

    from shapeverify.nearest._intrinsics import beaten8

    @njit
    def vector(w, x, dp, h2, p):
        return beaten8(w, x[0], x[1], x[2], dp, h2, p)

    rng = np.random.default_rng(seed)
    seen = set()
    for _ in range(300):
        nw = int(rng.integers(1, 9))
        y = rng.integers(-3, 4, (nw, 3)) * 0.25
        c = rng.integers(-2, 3, 3) * 0.125
        half = float(rng.choice([0.125, 0.25]))
        x = rng.integers(-3, 4, 3) * 0.25 + (rng.normal(0, 1e-3, 3) if rng.random() < 0.5 else 0)
        ids = rng.permutation(20)[:nw].astype(float)
        p = float(ids[0] if rng.random() < 0.3 else 99)
        da = ((y - c) ** 2).sum(axis=1)
        dp = float(((x - c) ** 2).sum())
        w = np.empty(40)
        for k, col in enumerate((y[:, 0], y[:, 1], y[:, 2], da, ids)):
            w[8 * k:8 * k + nw] = col
            w[8 * k + nw:8 * k + 8] = col[-1]
        want = False
        for i in range(nw):
            if ids[i] == p:
                continue
            worst = da[i] - dp + 2.0 * half * (abs(x[0] - y[i, 0]) + abs(x[1] - y[i, 1])
                                               + abs(x[2] - y[i, 2]))
            want |= worst < -1e-9 * (da[i] + dp)
        assert vector(w, x, dp, 2.0 * half, p) == want
        seen.add(bool(want))
    assert seen == {True, False}


def test_walks_advanced_together_equal_single_walks():
    """``_kernels.walk_many`` (walks advanced in turn) ends every walk where ``walk`` does,
    with the same squared distance and number of moves, for every budget."""
    from shapeverify.nearest import _kernels as K

    pts = _two_sheets(30)
    rv = dvg.views(dvg.make_records(pts, dvg.neighbor_graph(pts)))
    rng = np.random.default_rng(3)
    q = pts[rng.integers(0, pts.shape[0], 64)] + rng.normal(0, 0.4, (64, 3))
    starts = rng.integers(0, pts.shape[0], 64)
    ob, od, om = np.empty(8, np.int64), np.empty(8), np.empty(8, np.int64)
    live = np.empty(8, np.bool_)
    for budget in (0, 1, 3, 64):
        for g in range(0, 64, 8):
            K.walk_many(np.ascontiguousarray(q[g:g + 8]), 8, int(starts[g]), *rv, budget, ob,
                        od, om, live)
            for i in range(8):
                assert (ob[i], od[i], om[i]) == K.walk(*q[g + i], int(starts[g]), *rv, budget)


@pytest.mark.parametrize("seed", range(3))
def test_eight_candidate_test_equals_the_scalar_one(seed):
    """``_intrinsics.kept8`` (8 candidates against a cell's box bound and witnesses at once,
    lanes beyond the count dropped) keeps exactly the points ``_build_kernels._keep`` keeps,
    on coarse integer grids (many exact ties: zero margins, points on the box bound,
    witnesses that are the point itself)."""
    from numba import njit

    from shapeverify.nearest._intrinsics import kept8

    @njit
    def both(pts, ids, nv, wit, c, half, U):
        wv = np.empty(40)
        nw = bk._witnesses(wit, pts, c[0], c[1], c[2], wv)
        xs = np.zeros(16)
        ys = np.zeros(16)
        zs = np.zeros(16)
        gi = np.zeros(16, dtype=np.int32)
        for k in range(nv):
            xs[k], ys[k], zs[k], gi[k] = pts[ids[k], 0], pts[ids[k], 1], pts[ids[k], 2], ids[k]
        m = kept8(xs, ys, zs, gi, 0, nv, wv, nw, c[0], c[1], c[2], half, U * U, 2.0 * half)
        want = 0
        for k in range(nv):
            if bk._keep(ids[k], c[0], c[1], c[2], half, pts, wv, U):
                want |= 1 << k
        return m, want

    rng = np.random.default_rng(seed)
    pts = np.ascontiguousarray(rng.integers(-4, 5, (60, 3)) * 0.25)
    pts[30:] += rng.normal(0, 1e-3, (30, 3)) * (rng.random((30, 1)) < 0.5)
    seen = set()
    for _ in range(400):
        wit = rng.integers(0, 60, 8).astype(np.int64)
        wit[rng.integers(0, 2, 8) == 0] = wit[0]  # repeated witnesses
        ids = rng.integers(0, 60, 8).astype(np.int32)
        ids[:2] = wit[:2]
        c = rng.integers(-2, 3, 3) * 0.125
        half = float(rng.choice([0.125, 0.25]))
        U = float(rng.choice([0.25, 0.5, 0.75, 1.0]))
        nv = int(rng.integers(1, 9))
        m, want = both(pts, ids, nv, wit, c, half, U)
        assert m == want
        seen.add(bin(m).count("1"))
    assert len(seen) > 4


@pytest.mark.parametrize("coarse", [False, True])
def test_grid_search_of_the_top_vertices_equals_a_bounded_scan(coarse):
    """``_lattice_kernels.grid_nearest`` (shells of bins) gives each grid vertex the nearest
    point of a linear scan (lowest index on ties, distance formed as the kd-tree forms it), or
    (0, inf) beyond the bound; on integer coordinates (ties everywhere) too."""
    from shapeverify.nearest._lattice_kernels import grid_nearest

    rng = np.random.default_rng(4)
    if coarse:
        pts = rng.integers(0, 12, (400, 3)) * 0.5 + 0.25
    else:
        pts = _two_sheets(30)
    pts = np.ascontiguousarray(pts, dtype=np.float64)
    origin = pts.min(axis=0) - 1.5
    cell, dims = 1.0, np.ceil((pts.max(axis=0) + 1.5 - origin) / 1.0).astype(np.int64)
    order, start = dvg_build._bin_points(pts, origin, cell, dims)
    vx = np.stack(np.meshgrid(*(np.arange(d + 1) for d in dims), indexing="ij"),
                  axis=-1).reshape(-1, 3).astype(np.int64)
    for bound in (0.6, 1.3, 50.0):
        oi, od = np.empty(vx.shape[0], np.int64), np.empty(vx.shape[0])
        grid_nearest(vx, pts, order, start, dims, origin, cell, bound, oi, od)
        q = origin + cell * vx
        e = pts[None, :, :] - q[:, None, :]
        d2 = (e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1]) + e[..., 2] * e[..., 2]
        i = d2.argmin(axis=1)  # the first (lowest index) of the smallest
        d = np.sqrt(d2[np.arange(q.shape[0]), i])
        inside = d < bound
        assert 0 < inside.sum() <= q.shape[0]
        assert np.array_equal(oi, np.where(inside, i, 0))
        assert np.array_equal(od, np.where(inside, d, np.inf))
    if coarse:
        assert (d2 == d2.min(axis=1, keepdims=True)).sum(axis=1).max() > 1  # ties seen


def test_tree_is_the_same_for_any_number_of_segments(monkeypatch):
    """The refined cells of a level handled in segments (each one's lists freed once its
    children's are built) give the tree of one segment, node for node."""
    pts = _two_sheets()
    rec = dvg.make_records(pts, dvg.neighbor_graph(pts))
    trees = []
    for k in (1, 3, 8):
        monkeypatch.setattr(dvg_build, "SEGMENTS", k)
        trees.append(dvg_build.build_tree(rec, H, 1.0))
    assert trees[0].depth >= 2
    for t in trees[1:]:
        assert np.array_equal(t.nodes, trees[0].nodes)
        assert np.array_equal(t.lists, trees[0].lists)
