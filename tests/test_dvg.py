"""The DVG tree on plain arrays, against brute force (scipy cKDTree)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from shapeverify.nearest import dvg

H = 0.25  # model point spacing of the synthetic models


def _wavy_sheet(n=160, jitter=0.3, seed=0):
    """Jittered samples of a curved sheet z = f(x, y), ~n^2 points, spacing H."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.arange(n) * H, np.arange(n) * H)
    u = u + rng.uniform(-jitter, jitter, u.shape) * H
    v = v + rng.uniform(-jitter, jitter, v.shape) * H
    z = 2.0 * np.sin(u / 4.0) * np.cos(v / 6.0) + 0.8 * np.sin(u / 2.0 + v / 3.0)
    return np.column_stack([u.ravel(), v.ravel(), z.ravel()])


def _thin_plate(n=120, gap=1.2, seed=1):
    """Two parallel sheets ``gap`` apart (a thin wall: the medial surface lies between)."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.arange(n) * H, np.arange(n) * H)
    u = u.ravel() + rng.uniform(-0.2, 0.2, u.size) * H
    v = v.ravel() + rng.uniform(-0.2, 0.2, v.size) * H
    bot = np.column_stack([u, v, 0.1 * np.sin(u)])
    top = np.column_stack([v, u, gap + 0.1 * np.sin(v)])
    return np.concatenate([bot, top])


def _build(points, max_distance):
    pts = points[dvg.morton_order(points, H)]
    return dvg.DVG.build(pts, H, max_distance), np.ascontiguousarray(pts)


def _near_queries(pts, n, max_distance, rng):
    i = rng.integers(0, pts.shape[0], n)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return pts[i] + d * rng.uniform(0.0, max_distance, n)[:, None]


def _check(tree, pts, q, exact_share=0.999):
    idx, dist = tree.nearest(q)
    d_true, _ = cKDTree(pts).query(q)
    np.testing.assert_allclose(dist, np.linalg.norm(pts[idx] - q, axis=1), rtol=1e-12,
                               atol=1e-12)
    right = dist <= d_true * (1 + 1e-12) + 1e-12
    assert right.mean() >= exact_share, f"only {right.mean():.5f} exact"
    assert np.all(dist - d_true <= H), f"excess up to {np.max(dist - d_true)}"
    return right.mean()


@pytest.fixture(scope="module")
def sheet():
    return _build(_wavy_sheet(), 2.0)


@pytest.fixture(scope="module")
def plate():
    return _build(_thin_plate(), 1.5)


def test_sheet_near_queries_match_brute_force(sheet):
    tree, pts = sheet
    rng = np.random.default_rng(2)
    _check(tree, pts, _near_queries(pts, 40_000, 2.0, rng))


def test_thin_plate_medial_surface(plate):
    """Queries between two sheets (the medial surface is inside max_distance)."""
    tree, pts = plate
    rng = np.random.default_rng(3)
    q = _near_queries(pts, 30_000, 1.5, rng)
    mid = np.column_stack([rng.uniform(2, 28, 5000), rng.uniform(2, 28, 5000),
                           rng.uniform(0.4, 0.8, 5000)])
    _check(tree, pts, np.concatenate([q, mid]))
    assert tree.tree.lists.size > 0  # multi-seed leaves were needed near the medial surface


def test_far_queries_fall_back_to_exact(sheet):
    tree, pts = sheet
    rng = np.random.default_rng(4)
    q = _near_queries(pts, 3000, 40.0, rng)
    q = q[cKDTree(pts).query(q)[0] > 2.5]
    assert q.shape[0] > 1000
    assert (tree.tree.locate(q) == -1).mean() > 0.5  # mostly answered by the kd fallback
    idx, dist = tree.nearest(q)
    d_true, _ = cKDTree(pts).query(q)
    np.testing.assert_allclose(dist, d_true, rtol=1e-12, atol=1e-12)
    outside = pts.max(axis=0) + 100.0  # outside the top grid altogether
    i, d = tree.nearest(outside[None, :])
    assert d[0] == pytest.approx(np.linalg.norm(pts - outside, axis=1).min(), rel=1e-12)


def test_query_kernel_counts_the_far_queries_it_leaves_to_the_kd_tree(sheet):
    """query_block returns how many queries the tree calls FAR (DVG.query skips its pass over
    the answers when there are none)."""
    from shapeverify.nearest import _kernels as K

    tree, pts = sheet
    rng = np.random.default_rng(5)
    q = np.ascontiguousarray(_near_queries(pts, 2000, 40.0, rng))
    n = q.shape[0]
    A = K.Answers(np.empty(n, np.int64), np.empty(n), *(np.empty((0, 3)), np.empty(0),
                  np.empty(0, np.bool_), np.empty((0, 3)), np.empty(0, np.int32),
                  np.empty((0, 2)), np.empty(0, np.bool_)))
    n_far = K.query_block(q, tree._arrays, A, 0, n, 256, False)
    far = tree.tree.locate(q) == -1
    assert 0 < n_far == int(far.sum()) < n
    np.testing.assert_array_equal(A.index < 0, far)
    assert K.query_block(q[~far].copy(), tree._arrays, A, 0, int((~far).sum()), 256, False) == 0


def test_queries_on_grid_vertices_and_cell_faces(sheet):
    tree, pts = sheet
    t = tree.tree
    rng = np.random.default_rng(5)
    q = _near_queries(pts, 20_000, 2.0, rng)
    out = []
    for level in range(t.depth + 1):
        step = t.cell / 2.0 ** level
        g = np.round((q - t.origin) / step)
        on_vertex = t.origin + g * step                      # on a vertex of this level
        on_face = q.copy()
        on_face[:, 0] = on_vertex[:, 0]                      # on a cell face (x = const)
        on_edge = q.copy()
        on_edge[:, :2] = on_vertex[:, :2]                    # on a cell edge
        out += [on_vertex, on_face, on_edge]
    q = np.concatenate(out)
    q = q[cKDTree(pts).query(q)[0] <= 2.0]
    _check(tree, pts, q)


def test_patch_projection_on_a_plane():
    """On a plane the tangent patches are exact: distance = height, foot = vertical drop."""
    g = np.arange(0, 40) * H
    x, y = np.meshgrid(g, g)
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    frames = np.zeros((pts.shape[0], 8), np.float32)
    frames[:, 2] = 1.0
    frames[:, 3] = 1.0
    frames[:, 6:8] = 0.5 * H
    tree = dvg.DVG.build(pts, H, 1.0, frames)
    rng = np.random.default_rng(6)
    q = np.column_stack([rng.uniform(1, 8, 500), rng.uniform(1, 8, 500),
                         rng.uniform(-0.9, 0.9, 500)])
    idx, foot, dist, clamped, normal = tree.closest_on_patches(q)
    np.testing.assert_allclose(dist, q[:, 2], atol=1e-6)  # float32 frames
    np.testing.assert_allclose(foot[:, :2], q[:, :2], atol=1e-6)
    assert not clamped.any()
    np.testing.assert_allclose(normal, np.tile([0.0, 0.0, 1.0], (500, 1)), atol=1e-7)


def test_input_validation(sheet):
    tree, _ = sheet
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        tree.nearest(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="NaN"):
        tree.nearest(np.array([[0.0, np.nan, 1.0]]))
    with pytest.raises(ValueError, match="empty"):
        dvg.DVG.build(np.zeros((0, 3)), H, 1.0)
    with pytest.raises(ValueError, match="inf"):
        dvg.DVG.build(np.array([[0.0, 0.0, np.inf]]), H, 1.0)
    with pytest.raises(ValueError, match="spacing"):
        dvg.DVG.build(np.zeros((3, 3)), 0.0, 1.0)
    with pytest.raises(ValueError, match="reach"):
        dvg.DVG.build(np.zeros((3, 3)), 1.0, np.nan)
    idx, dist = tree.nearest(np.zeros((0, 3)))
    assert idx.shape == (0,) and dist.shape == (0,)


def test_tiny_models():
    one = np.array([[1.0, 2.0, 3.0]])
    t = dvg.DVG.build(one, 1.0, 2.0)
    idx, d = t.nearest([[1.0, 2.0, 4.5], [50.0, 0.0, 0.0]])
    assert idx.tolist() == [0, 0]
    assert d[0] == pytest.approx(1.5)
    dup = np.repeat(np.array([[0.0, 0, 0], [1.0, 0, 0]]), 5, axis=0)  # duplicated points
    t = dvg.DVG.build(dup, 0.5, 1.0)
    idx, d = t.nearest([[0.9, 0.1, 0.0]])
    assert np.allclose(dup[idx[0]], [1.0, 0, 0])


def test_build_is_identical_on_one_and_two_threads(sheet):
    from shapeverify.nearest import get_workers, set_workers
    from shapeverify.nearest.dvg import DVG

    pts = sheet[1]
    before = get_workers()
    try:
        set_workers(1)
        one = DVG.build(pts, H, 2.0)
        set_workers(2)
        two = DVG.build(pts, H, 2.0)
    finally:
        set_workers(None if before == get_workers() else before)
    for name, a in one.tree.arrays().items():
        np.testing.assert_array_equal(np.asarray(a), np.asarray(two.tree.arrays()[name]))
    np.testing.assert_array_equal(one.rec, two.rec)


def test_queries_are_identical_on_one_and_two_threads(sheet):
    """Queries split into chunks over two threads give the answers of one thread, bit for bit,
    with FAR queries (kd-tree fallback) in the mix and in scan-like (row) order."""
    from shapeverify.nearest import get_workers, set_workers
    from shapeverify.nearest._threads import MIN_CHUNK

    tree, pts = sheet
    rng = np.random.default_rng(7)
    near = _near_queries(pts, 5 * MIN_CHUNK, 2.0, rng)
    far = pts[rng.integers(0, pts.shape[0], 2000)] + [0.0, 0.0, 9.0]
    q = np.concatenate([near, far])
    q = np.ascontiguousarray(q[np.lexsort((q[:, 0], np.floor(q[:, 1] / H)))])  # rows of y
    before = get_workers()
    try:
        out = {}
        for w in (1, 2):
            set_workers(w)
            out[w] = tree.query(q, True)
    finally:
        set_workers(None if before == get_workers() else before)
    for name in ("index", "d2", "foot", "distance", "clamped", "normal", "face", "uv",
                 "on_boundary"):
        np.testing.assert_array_equal(getattr(out[1], name), getattr(out[2], name))
    d_true, _ = cKDTree(pts).query(q)
    assert np.mean(np.sqrt(out[1].d2) <= d_true * (1 + 1e-12) + 1e-12) >= 0.999
