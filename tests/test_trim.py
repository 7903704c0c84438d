"""Point-in-trimmed-domain test (cad/trim.py) and the Face / Model containers (cad/model.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path as MplPath

from shapeverify.cad.model import Face, Model, ModelPoints
from shapeverify.cad.nurbs import NurbsSurface
from shapeverify.cad.trim import TrimDomain


def circle_loop(cx, cy, r, n, clockwise=False):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    if clockwise:
        t = -t
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def star_loop(n_points=7, r_out=1.0, r_in=0.35, phase=0.1):
    t = phase + np.pi * np.arange(2 * n_points) / n_points
    r = np.where(np.arange(2 * n_points) % 2 == 0, r_out, r_in)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def unit_plane():
    ctrl = np.array([[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]], float)
    return NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)


def test_square_with_round_hole_matches_geometry():
    rng = np.random.default_rng(0)
    square = np.array([[0, 0], [2, 0], [2, 1], [0, 1]], float)
    hole = circle_loop(1.4, 0.5, 0.3, 4000, clockwise=True)
    dom = TrimDomain((square, hole))
    p = rng.uniform([-0.5, -0.5], [2.5, 1.5], size=(100_000, 2))
    d_hole = np.hypot(p[:, 0] - 1.4, p[:, 1] - 0.5)
    in_square = (p[:, 0] > 0) & (p[:, 0] < 2) & (p[:, 1] > 0) & (p[:, 1] < 1)
    expected = in_square & (d_hole > 0.3)
    # away from the polygonised circle (its chordal error is < 1e-6)
    clear = np.abs(d_hole - 0.3) > 1e-6
    got = dom.contains(p)
    np.testing.assert_array_equal(got[clear], expected[clear])
    assert clear.mean() > 0.999


def test_concave_star_agrees_with_matplotlib():
    rng = np.random.default_rng(1)
    star = star_loop()
    p = rng.uniform(-1.1, 1.1, size=(50_000, 2))
    expected = MplPath(np.vstack([star, star[:1]]), closed=True).contains_points(p)
    np.testing.assert_array_equal(TrimDomain((star,)).contains(p), expected)


def test_even_odd_nesting_island_inside_hole():
    outer = circle_loop(0, 0, 3.0, 400)
    hole = circle_loop(0, 0, 2.0, 300)
    island = circle_loop(0, 0, 1.0, 200)
    dom = TrimDomain((outer, hole, island))
    r = np.array([0.5, 1.5, 2.5, 3.5])
    got = dom.contains(np.column_stack([r, np.zeros(4)]))
    assert got.tolist() == [True, False, True, False]


def test_vertices_on_the_ray_are_counted_once():
    # the ray from (0.5, 1) passes exactly through vertices (1, 1) of a diamond chain
    diamond = np.array([[1, 0], [2, 1], [1, 2], [0, 1]], float)
    dom = TrimDomain((diamond,))
    p = np.array([[0.5, 1.0], [1.0, 1.0], [1.5, 1.0], [-0.5, 1.0], [2.5, 1.0], [1.0, 0.5]])
    assert dom.contains(p).tolist() == [True, True, True, False, False, True]
    # horizontal edges: a rectangle whose top and bottom are horizontal
    rect = TrimDomain((np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float),))
    assert rect.contains([[0.5, 0.5], [0.5, 1.5], [0.5, -0.5]]).tolist() == [True, False, False]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_bins=st.integers(1, 5000))
def test_result_does_not_depend_on_the_bins(seed, n_bins):
    rng = np.random.default_rng(seed)
    k = int(rng.integers(3, 60))
    loop = rng.normal(size=(k, 2))  # self-intersecting polygons too: even-odd is still defined
    hole = 0.3 * rng.normal(size=(int(rng.integers(3, 20)), 2))
    p = rng.normal(size=(2000, 2))
    a = TrimDomain((loop, hole), n_bins=1).contains(p)
    b = TrimDomain((loop, hole), n_bins=n_bins).contains(p)
    c = MplPath(np.vstack([loop, loop[:1]]), closed=True)
    np.testing.assert_array_equal(a, b)
    # a single simple-or-not polygon: matplotlib's even-odd test is the oracle
    only = TrimDomain((loop,), n_bins=n_bins).contains(p)
    ref = c.contains_points(p)
    # matplotlib uses the same crossing rule; points exactly on edges do not occur here
    assert np.mean(only == ref) > 0.999


def test_points_outside_the_v_range_and_empty_input():
    dom = TrimDomain((np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float),))
    assert dom.contains([[0.5, 2.0], [0.5, -1.0]]).tolist() == [False, False]
    assert dom.contains(np.zeros((0, 2))).shape == (0,)
    assert dom.contains([0.5, 0.5]).tolist() == [True]
    assert dom.bounds == ((0.0, 1.0), (0.0, 1.0))
    assert "segments=4" in repr(dom)


@pytest.mark.parametrize("bad, match", [
    (np.zeros((3, 3)), r"shape \(N, 2\)"),
    (np.array([[0.1, np.nan]]), "non-finite"),
    (np.zeros((2, 2, 2)), r"shape \(N, 2\)"),
])
def test_contains_rejects_bad_points(bad, match):
    dom = TrimDomain((np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float),))
    with pytest.raises(ValueError, match=match):
        dom.contains(bad)


@pytest.mark.parametrize("loops, match", [
    ((), "at least one loop"),
    ((np.zeros((1, 2)),), r"k >= 2"),
    ((np.zeros((4, 3)),), r"shape \(k, 2\)"),
    ((np.array([[0, 0], [1, np.inf], [0, 1]]),), "non-finite"),
    (np.zeros((4, 2)), "sequence"),
])
def test_loops_are_validated(loops, match):
    with pytest.raises(ValueError, match=match):
        TrimDomain(loops)


def test_face_contains_evaluate_and_oriented_normal():
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    hole = circle_loop(0.5, 0.5, 0.2, 100)
    free = (np.ones(4, bool), np.zeros(100, bool))
    face = Face(unit_plane(), (outer, hole), free, reversed=False)
    flipped = Face(unit_plane(), (outer, hole), free, reversed=True)
    uv = np.array([[0.1, 0.1], [0.5, 0.5], [0.9, 0.2]])
    assert face.contains(uv).tolist() == [True, False, True]
    np.testing.assert_allclose(face.evaluate(uv), np.column_stack([uv, np.zeros(3)]), atol=1e-15)
    np.testing.assert_allclose(face.normal(uv), [[0, 0, 1]] * 3, atol=1e-15)
    np.testing.assert_allclose(flipped.normal(uv), [[0, 0, -1]] * 3, atol=1e-15)
    assert face.uv_bounds == ((0.0, 1.0), (0.0, 1.0))
    assert "loops=2" in repr(face) and "free_segments=4" in repr(face)
    assert not face.loops[0].flags.writeable


def test_face_validation():
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    with pytest.raises(ValueError, match="NurbsSurface"):
        Face("plane", (outer,), (np.ones(4, bool),))
    with pytest.raises(ValueError, match=r"loop_free\[0\] must have shape \(4,\)"):
        Face(unit_plane(), (outer,), (np.ones(3, bool),))
    with pytest.raises(ValueError, match="1 entries for 2 loops"):
        Face(unit_plane(), (outer, outer * 0.5), (np.ones(4, bool),))


def test_model_bounds_size_and_validation():
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    face = Face(unit_plane(), (outer * 0.5,), (np.ones(4, bool),))
    m = Model(faces=(face,), unit="mm", scale_to_mm=1.0, source="test")
    np.testing.assert_allclose(m.bounds, [[0, 0, 0], [0.5, 0.5, 0]], atol=1e-15)
    assert m.size == pytest.approx(np.sqrt(0.5))
    assert "faces=1" in repr(m)
    pts = np.array([[0, 0, 0], [1, 2, 3]], float)
    cloud = Model(kind="points", vertices=pts, source="cloud")
    np.testing.assert_array_equal(cloud.bounds, pts)
    mesh = Model(kind="mesh", vertices=np.eye(3), triangles=[[0, 1, 2]])
    assert mesh.triangles.dtype == np.int32
    with pytest.raises(ValueError, match="kind"):
        Model(kind="brep")
    with pytest.raises(ValueError, match="needs triangles"):
        Model(kind="mesh", vertices=pts)
    with pytest.raises(ValueError, match="index outside"):
        Model(kind="mesh", vertices=pts, triangles=[[0, 1, 2]])
    with pytest.raises(ValueError, match=r"vertices must have shape \(n, 3\)"):
        Model(kind="points", vertices=np.zeros((3, 2)))


def test_model_points_shapes_are_checked():
    n = 5
    kw = dict(points=np.zeros((n, 3)), normals=np.zeros((n, 3)), face=np.zeros(n),
              uv=np.zeros((n, 2)), tangent_u=np.zeros((n, 3)), tangent_v=np.zeros((n, 3)),
              half_extent=np.zeros((n, 2)), boundary=np.zeros(n), spacing=1.5)
    mp = ModelPoints(**kw)
    assert len(mp) == n and mp.face.dtype == np.int32 and mp.boundary.dtype == np.bool_
    assert "n=5" in repr(mp)
    kw["uv"] = np.zeros((n, 3))
    with pytest.raises(ValueError, match=r"uv must have shape \(5, 2\)"):
        ModelPoints(**kw)
