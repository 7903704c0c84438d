"""Model-point sampling (shapeverify.cad.sampling): exact, uniform in 3D, trims respected."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, sphere
from shapeverify.cad.sampling import (CAD_MAX_COARSENING, CAD_TARGET_POINTS, MAX_POINTS,
                                      sample_model)

UNIT_SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)


def cad(*faces):
    return Model(faces=tuple(faces), unit="mm", scale_to_mm=1.0, source="test", kind="cad")


def square_face(surface, free=False, reversed=False, holes=()):
    (u0, u1), (v0, v1) = surface.domain
    outer = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
    loops = (outer,) + tuple(holes)
    return Face(surface, loops, tuple(np.full(len(lp), free) for lp in loops), reversed)


def plane(x0, x1, y0, y1, z=0.0):
    ctrl = np.array([[[x0, y0, z], [x0, y1, z]], [[x1, y0, z], [x1, y1, z]]], float)
    return NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)


def clustered_patch():
    """Bicubic wavy patch over [0, 10]^2 whose u knots are crammed into [0, 0.04]: half of the
    surface lies in 4% of the u range (strongly nonuniform parametrisation)."""
    n = 8
    x = np.linspace(0, 10, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    Z = 1.5 * np.sin(X / 2.0) * np.cos(Y / 3.0)
    ku = [0, 0, 0, 0, 0.01, 0.02, 0.03, 0.04, 1, 1, 1, 1]
    kv = [0, 0, 0, 0, 0.2, 0.4, 0.6, 0.8, 1, 1, 1, 1]
    return NurbsSurface(3, 3, ku, kv, np.stack([X, Y, Z], axis=-1))


def fine_grid(surface, per_span=60):
    """Dense parameter grid: per_span samples in every knot span (fine in 3D everywhere)."""
    def axis(knots):
        k = np.unique(knots)
        return np.unique(np.concatenate([np.linspace(a, b, per_span) for a, b in zip(k, k[1:])]))
    return axis(surface.knots_u), axis(surface.knots_v)


def grid_area(surface, u, v):
    P = surface.evaluate(*[a.ravel() for a in np.meshgrid(u, v, indexing="ij")])
    P = P.reshape(len(u), len(v), 3)
    a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
    return 0.5 * (np.linalg.norm(np.cross(b - a, c - a), axis=-1)
                  + np.linalg.norm(np.cross(c - a, d - a), axis=-1)).sum(), P.reshape(-1, 3)


def nn_dist(P):
    return cKDTree(P).query(P, k=2)[0][:, 1]


def check_frames(mp):
    for name in ("normals", "tangent_u", "tangent_v"):
        np.testing.assert_allclose(np.linalg.norm(getattr(mp, name), axis=1), 1.0, atol=1e-12)
    for a, b in (("normals", "tangent_u"), ("normals", "tangent_v"), ("tangent_u", "tangent_v")):
        assert np.abs(np.einsum("ij,ij->i", getattr(mp, a), getattr(mp, b))).max() < 1e-12
    # right-handed: t_u x t_v = n
    np.testing.assert_allclose(np.cross(mp.tangent_u, mp.tangent_v), mp.normals, atol=1e-12)
    assert np.all(mp.half_extent >= 0.5 * mp.spacing - 1e-12)
    assert np.all(mp.half_extent <= 1.5 * mp.spacing + 1e-12)


def on_surface_error(model, mp):
    err = 0.0
    for f in np.unique(mp.face):
        sel = mp.face == f
        q = model.faces[f].surface.evaluate(mp.uv[sel, 0], mp.uv[sel, 1])
        err = max(err, np.abs(q - mp.points[sel]).max())
    return err


# ----------------------------------------------------------------------------- CAD faces
def test_sphere_exact_outward_uniform():
    R, s = 10.0, 0.5
    m = cad(square_face(sphere(R)))
    mp = sample_model(m, s)
    assert on_surface_error(m, mp) < 1e-12
    np.testing.assert_allclose(np.linalg.norm(mp.points, axis=1), R, rtol=1e-14)
    # outward unit normals, orthonormal frames
    assert np.einsum("ij,ij->i", mp.normals, mp.points / R).min() > 1 - 1e-12
    check_frames(mp)
    # uniform in 3D although u, v cluster at both poles
    nn = nn_dist(mp.points)
    assert 0.85 * s * (1 - 1e-12) <= nn.min()
    assert 0.8 * s < np.median(nn) < 1.2 * s
    assert nn.max() < 1.5 * s
    area = 4 * np.pi * R * R
    assert 0.7 < len(mp) * s * s / area < 1.4
    # coverage: every point of the sphere is near a model point (no holes, poles included)
    q = np.random.default_rng(3).normal(size=(100_000, 3))
    q = R * q / np.linalg.norm(q, axis=1)[:, None]
    q = np.vstack([q, [[0, 0, R], [0, 0, -R]]])
    assert cKDTree(mp.points).query(q)[0].max() < 1.2 * s
    assert mp.face.dtype == np.int32 and np.all(mp.face == 0)
    assert not mp.boundary.any()  # no free edges on a closed sphere


def test_clustered_knots_uniform_in_3d():
    surf = clustered_patch()
    s = 0.25
    m = cad(square_face(surf, free=True))
    mp = sample_model(m, s)
    assert on_surface_error(m, mp) < 1e-12
    check_frames(mp)
    nn = nn_dist(mp.points)
    assert 0.8 * s < np.median(nn) < 1.2 * s
    assert np.mean(nn > 2 * s) == 0
    u, v = fine_grid(surf)
    area, dense = grid_area(surf, u, v)
    assert 0.7 < len(mp) * s * s / area < 1.4
    assert cKDTree(mp.points).query(dense)[0].max() < 1.3 * s
    # half of the points have u < 0.04 (half the surface), as in 3D, not 4% as in (u, v)
    assert 0.35 < np.mean(mp.uv[:, 0] < 0.04) < 0.65
    # the normal is Su x Sv (not reversed)
    d = surf.derivatives(mp.uv[:, 0], mp.uv[:, 1], 1)
    n = np.cross(d[:, 1, 0], d[:, 0, 1])
    assert np.einsum("ij,ij->i", n, mp.normals).min() > 0


def circle_loop(c, r, k=256):
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)[::-1]  # clockwise hole
    return np.column_stack([c[0] + r * np.cos(t), c[1] + r * np.sin(t)])


def test_trims_respected_and_boundary_flags():
    s = 0.25
    surf = plane(0, 20, 0, 10)
    holes = [circle_loop((0.25, 0.5), 0.1), circle_loop((0.7, 0.5), 0.15)]
    face = square_face(surf, free=True, holes=holes)
    mp = sample_model(cad(face), s)
    # no point in a hole (loops are inscribed polygons: sagitta < 1e-5 in uv)
    for (cu, cv), r in (((0.25, 0.5), 0.1), ((0.7, 0.5), 0.15)):
        assert np.hypot(mp.uv[:, 0] - cu, mp.uv[:, 1] - cv).min() > r - 1e-4
    assert face.contains(mp.uv).all()
    np.testing.assert_allclose(mp.points[:, :2], mp.uv * [20, 10], atol=1e-12)
    np.testing.assert_array_equal(mp.points[:, 2], 0.0)
    # but the surface around the holes is covered
    g = np.stack(np.meshgrid(np.linspace(0, 1, 400), np.linspace(0, 1, 200)), -1).reshape(-1, 2)
    g = g[face.contains(g)]
    assert cKDTree(mp.uv * [20, 10]).query(g * [20, 10])[0].max() < 1.3 * s
    area = 200 - np.pi * (0.1 * 20 * 0.1 * 10 + 0.15 * 20 * 0.15 * 10)
    assert 0.7 < len(mp) * s * s / area < 1.4
    # boundary flag <=> within one spacing (3D) of the outer edge or a hole edge
    x, y = mp.points[:, 0], mp.points[:, 1]
    d = np.minimum.reduce([x, 20 - x, y, 10 - y])
    for (cu, cv), r in (((0.25, 0.5), 0.1), ((0.7, 0.5), 0.15)):
        t = np.linspace(0, 2 * np.pi, 20000)
        ell = np.column_stack([20 * (cu + r * np.cos(t)), 10 * (cv + r * np.sin(t))])
        d = np.minimum(d, cKDTree(ell).query(mp.points[:, :2])[0])
    assert np.all(d[mp.boundary] <= s + 1e-9)
    assert np.all(d[~mp.boundary] > 0.98 * s)
    assert mp.boundary.any() and not mp.boundary.all()


def test_reversed_face_flips_normals():
    s = 1.0
    up = sample_model(cad(square_face(plane(0, 10, 0, 10))), s)
    down = sample_model(cad(square_face(plane(0, 10, 0, 10), reversed=True)), s)
    np.testing.assert_array_equal(up.points, down.points)
    np.testing.assert_allclose(up.normals, [[0, 0, 1]] * len(up), atol=0)
    np.testing.assert_allclose(down.normals, [[0, 0, -1]] * len(down), atol=0)
    check_frames(down)


def test_shared_edge_not_doubled_and_covered():
    s = 0.5
    left = square_face(plane(0, 10, 0, 10))
    right = square_face(plane(10, 20, 0, 10))
    mp = sample_model(cad(left, right), s)
    assert set(np.unique(mp.face)) == {0, 1}
    nn = nn_dist(mp.points)
    assert nn.min() >= 0.85 * s * (1 - 1e-12)  # no pairs across the seam
    seam = np.column_stack([np.full(2000, 10.0), np.linspace(0, 10, 2000), np.zeros(2000)])
    assert cKDTree(mp.points).query(seam)[0].max() < 1.3 * s
    assert 0.7 < len(mp) * s * s / 200 < 1.4


def test_thin_wall_keeps_both_skins():
    s = 1.0
    top = square_face(plane(0, 10, 0, 10, z=0.2))            # normal +z
    bottom = square_face(plane(0, 10, 0, 10, z=0.0), reversed=True)  # normal -z
    mp = sample_model(cad(top, bottom), s)
    n_top, n_bot = np.sum(mp.face == 0), np.sum(mp.face == 1)
    assert 70 < n_top < 140 and 70 < n_bot < 140
    assert np.all(mp.normals[mp.face == 1, 2] == -1)


def test_repeatable_and_model_sample():
    m = cad(square_face(clustered_patch()))
    a = sample_model(m, 0.5)
    b = m.sample(0.5)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.uv, b.uv)
    assert a.spacing == 0.5


def test_half_extents_from_the_neighbour_graph_equal_the_sampling_own():
    """prepare measures the patches' half extents on its neighbour graph (sample_model's
    ``half_extents=False``): the same values wherever the 6 nearest points are not tied."""
    from shapeverify.cad.sampling import half_extents_from_graph
    from shapeverify.nearest.dvg import neighbor_graph

    s = 0.4
    m = cad(square_face(clustered_patch()), square_face(sphere(3.0)))
    ref = sample_model(m, s)
    mp = m.sample(s, half_extents=False)
    np.testing.assert_array_equal(mp.points, ref.points)
    np.testing.assert_array_equal(mp.half_extent, s)  # the placeholder
    order = np.random.default_rng(1).permutation(len(mp))  # as prepare reorders them
    pts = np.ascontiguousarray(mp.points[order])
    graph = neighbor_graph(pts, spacing=s)
    half = half_extents_from_graph(pts, mp.tangent_u[order], mp.tangent_v[order], s, graph)
    d = np.linalg.norm(pts[graph[:, 5:7]] - pts[:, None, :], axis=2)
    untied = d[:, 0] < d[:, 1]
    assert untied.mean() > 0.9
    np.testing.assert_array_equal(half[untied], ref.half_extent[order][untied])
    assert np.all((half >= 0.5 * s) & (half <= 1.5 * s))


@pytest.mark.parametrize("spacing", [0, -1.0, np.nan, np.inf, "abc", None])
def test_bad_spacing(spacing):
    with pytest.raises(ValueError, match="spacing"):
        sample_model(cad(square_face(plane(0, 1, 0, 1))), spacing)


def test_too_many_points_refused():
    m = cad(square_face(plane(0, 1000, 0, 1000)))
    with pytest.raises(ValueError, match=r"use spacing >= 0\.2\d"):
        sample_model(m, 0.01)  # 1e10 points
    assert MAX_POINTS == 20_000_000


# ----------------------------------------------------------------------------------- mesh
def uv_sphere_mesh(R=10.0, n=40):
    th = np.linspace(0, np.pi, n + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    V = np.column_stack([np.sin(T).ravel() * np.cos(P).ravel(),
                         np.sin(T).ravel() * np.sin(P).ravel(), np.cos(T).ravel()])
    V = R * np.vstack([V, [[0, 0, 1], [0, 0, -1]]])
    top, bot = len(V) - 2, len(V) - 1
    m = 2 * n
    tris = []
    for i in range(n - 2):
        for j in range(m):
            a, b = i * m + j, i * m + (j + 1) % m
            c, d = (i + 1) * m + j, (i + 1) * m + (j + 1) % m
            tris += [[a, c, b], [b, c, d]]
    for j in range(m):
        tris.append([top, j, (j + 1) % m])
        tris.append([bot, (n - 2) * m + (j + 1) % m, (n - 2) * m + j])
    return V, np.array(tris)


def test_mesh_points_on_triangles_outward_uniform():
    V, T = uv_sphere_mesh()
    m = Model(kind="mesh", source="uv sphere", vertices=V, triangles=T)
    s = 0.5
    mp = sample_model(m, s)
    A, B, C = V[T[mp.face, 0]], V[T[mp.face, 1]], V[T[mp.face, 2]]
    u, v = mp.uv[:, 0], mp.uv[:, 1]
    assert u.min() >= 0 and v.min() >= 0 and (u + v).max() <= 1
    np.testing.assert_allclose(A + u[:, None] * (B - A) + v[:, None] * (C - A), mp.points,
                               atol=1e-12, rtol=0)
    tn = np.cross(B - A, C - A)
    tn /= np.linalg.norm(tn, axis=1)[:, None]
    np.testing.assert_allclose(mp.normals, tn, atol=1e-12)
    assert np.einsum("ij,ij->i", mp.normals, mp.points).min() > 0  # outward (winding)
    check_frames(mp)
    nn = nn_dist(mp.points)
    assert nn.min() >= 0.85 * s * (1 - 1e-12)
    assert 0.8 * s < np.median(nn) < 1.25 * s
    area = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]),
                                axis=1).sum()
    assert 0.7 < len(mp) * s * s / area < 1.4
    q = np.random.default_rng(0).random((50_000, 2))
    t = np.random.default_rng(1).integers(0, len(T), 50_000)
    q = q[q.sum(1) <= 1]
    t = t[: len(q)]
    pts = V[T[t, 0]] + q[:, :1] * (V[T[t, 1]] - V[T[t, 0]]) + q[:, 1:] * (V[T[t, 2]] - V[T[t, 0]])
    assert cKDTree(mp.points).query(pts)[0].max() < 1.5 * s
    assert not mp.boundary.any()  # closed mesh


def test_open_mesh_boundary_flags():
    n = 11
    x = np.linspace(0, 10, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(n * n)])
    tris = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
            tris += [[a, b, c], [a, c, d]]
    m = Model(kind="mesh", vertices=V, triangles=np.array(tris))
    s = 0.5
    mp = sample_model(m, s)
    d = np.minimum.reduce([mp.points[:, 0], 10 - mp.points[:, 0], mp.points[:, 1],
                           10 - mp.points[:, 1]])
    assert np.all(d[mp.boundary] <= s + 1e-9)
    assert np.all(d[~mp.boundary] > 0.98 * s)
    assert np.allclose(mp.normals, [0, 0, 1])


# ---------------------------------------------------------------------------- point cloud
def sphere_cloud(R=10.0, n=40_000, seed=5):
    q = np.random.default_rng(seed).normal(size=(n, 3))
    return R * q / np.linalg.norm(q, axis=1)[:, None]


def test_point_cloud_thinned_with_outward_pca_normals():
    X = sphere_cloud()
    m = Model(kind="points", vertices=X)
    s = 1.0
    mp = sample_model(m, s)
    # the model points are cloud points
    d, _ = cKDTree(X).query(mp.points)
    assert d.max() == 0
    assert np.all(mp.face == -1) and np.all(mp.uv == 0) and not mp.boundary.any()
    radial = mp.points / np.linalg.norm(mp.points, axis=1)[:, None]
    assert np.einsum("ij,ij->i", mp.normals, radial).min() > 0.97
    check_frames(mp)
    nn = nn_dist(mp.points)
    assert nn.min() >= 0.85 * s * (1 - 1e-12)
    assert 0.8 * s < np.median(nn) < 1.3 * s
    assert cKDTree(mp.points).query(X)[0].max() < 1.3 * s


def test_point_cloud_given_normals_are_used():
    X = sphere_cloud(n=5000)
    N = -X / np.linalg.norm(X, axis=1)[:, None]  # deliberately inward
    mp = sample_model(Model(kind="points", vertices=X, cloud_normals=N), 2.0)
    idx = cKDTree(X).query(mp.points)[1]
    np.testing.assert_allclose(mp.normals, N[idx], atol=1e-12)


# ------------------------------------------------------------------------------ real CAD
@pytest.mark.shared
def test_wavy_cube_exact_and_outward(shared_data):
    from shapeverify.cad.load import load_model

    m = load_model(shared_data / "cad" / "wavy-cube.stp")
    s = 0.05
    mp = m.sample(s)
    assert set(np.unique(mp.face)) == set(range(len(m.faces)))
    assert on_surface_error(m, mp) < 1e-12
    for f in range(len(m.faces)):
        sel = mp.face == f
        assert m.faces[f].contains(mp.uv[sel]).all()
        # the oriented face normal (computed independently by the face) agrees
        np.testing.assert_allclose(m.faces[f].normal(mp.uv[sel]), mp.normals[sel], atol=1e-9)
    check_frames(mp)
    # outward on this (star-shaped) solid
    c = 0.5 * (m.bounds[0] + m.bounds[1])
    assert np.mean(np.einsum("ij,ij->i", mp.normals, mp.points - c) > 0) > 0.99
    nn = nn_dist(mp.points)
    assert 0.8 * s < np.median(nn) < 1.2 * s
    assert not mp.boundary.any()  # a closed solid has no free edges


def test_sheared_parametrisation():
    # a parallelogram whose u and v directions are 5 degrees apart: the (u, v) grid is very
    # skewed in 3D, the sampling must stay uniform (and not split the face forever)
    a = np.deg2rad(5.0)
    e1, e2 = np.array([10.0, 0, 0]), 10 * np.array([np.cos(a), np.sin(a), 0])
    ctrl = np.array([[[0, 0, 0], e2], [e1, e1 + e2]])
    s = 0.1
    mp = sample_model(cad(square_face(NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl))), s)
    area = 100 * np.sin(a)
    # the scan-line thinning of a skewed lattice packs almost hexagonally at the disk radius
    # (0.85 s): denser than on a sphere, at most the hexagonal density 1.155 / 0.85**2 = 1.6
    assert 0.7 < len(mp) * s * s / area < 1.6
    nn = nn_dist(mp.points)
    assert nn.min() >= 0.85 * s * (1 - 1e-12) and 0.8 * s < np.median(nn) < 1.25 * s
    assert nn.max() < 1.5 * s


# ----------------------------------------------------- the spacing a reference needs
def _icosahedron(r=50.0):
    t = (1 + 5 ** 0.5) / 2
    V = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1.]])
    V = r * V / np.linalg.norm(V, axis=1)[:, None]
    T = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                  [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                  [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                  [8, 6, 7], [9, 8, 1]])
    return V, T


def test_needed_spacing_follows_the_geometry():
    from shapeverify.cad.sampling import needed_spacing

    V, T = _icosahedron()
    mesh = Model(kind="mesh", vertices=V, triangles=T, source="icosahedron")
    A = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]),
                             axis=1).sum()
    assert needed_spacing(mesh) == pytest.approx(np.sqrt(A / 10_000))  # 20 triangles: floor
    # a cloud on a 0.7 mm grid: its own spacing
    g = np.arange(0, 70, 0.7)
    X = np.stack(np.meshgrid(g, g, [0.0]), axis=-1).reshape(-1, 3)
    cloud = Model(kind="points", vertices=X, source="grid")
    assert needed_spacing(cloud) == pytest.approx(0.7)
    # CAD: a sheet keeps size / 500 (about 1e5 points); a closed solid gets the spacing of
    # about CAD_TARGET_POINTS points (a sphere: area / size^2 = 1.05 -> 2.6e5 at size / 500)
    sheet = cad(square_face(plane(0, 100, 0, 60)))
    assert needed_spacing(sheet) == 0.0
    ball = cad(square_face(sphere(10.0)))
    h = needed_spacing(ball)
    assert ball.size / 500 * 1.2 < h <= ball.size / 500 * CAD_MAX_COARSENING
    assert 0.85 * CAD_TARGET_POINTS < len(sample_model(ball, h)) < 1.15 * CAD_TARGET_POINTS


def test_needed_spacing_of_cad_coarsens_at_most_twofold():
    """A solid whose size / 500 gives far more than CAD_TARGET_POINTS points is made at most
    2x coarser (the fast answers' tangent-patch error at most 4x), not down to the count."""
    from shapeverify.cad.sampling import needed_spacing

    onion = cad(*(square_face(sphere(r)) for r in (10.0, 9.0, 8.0, 7.0)))  # area 3.1 size^2
    assert needed_spacing(onion) == pytest.approx(onion.size / 500 * CAD_MAX_COARSENING)


def test_needed_spacing_of_cad_keeps_thin_walls_resolved():
    """A 0.1 mm shell (a ball and its inside skin) is not coarsened: at a spacing near the
    wall's thickness a query's nearest model point lies on the other skin (the impeller's
    blades at 0.49 mm spacing: registrations locked onto the wrong side of a blade)."""
    from shapeverify.cad.sampling import CAD_SPACINGS_PER_WALL, needed_spacing

    shell = cad(square_face(sphere(10.0)), square_face(sphere(9.9), reversed=True))
    assert needed_spacing(shell) == 0.0
    thick = cad(square_face(sphere(10.0)), square_face(sphere(9.0), reversed=True))
    h = needed_spacing(thick)          # 1 mm wall: coarser, but 2.5 spacings across the wall
    assert thick.size / 500 < h <= 1.0 / CAD_SPACINGS_PER_WALL + 1e-9


def test_prepare_of_a_coarse_mesh_costs_what_its_triangles_need():
    """20 triangles: about 10,000 model points (not size/500 -> ~80,000), exact answers."""
    import time

    from shapeverify.nearest import prepare

    V, T = _icosahedron()
    mesh = Model(kind="mesh", vertices=V, triangles=T, source="icosahedron")
    t0 = time.process_time()
    prep = prepare(mesh)
    assert time.process_time() - t0 < 3.0
    assert 5_000 < prep.n_points < 15_000
    rng = np.random.default_rng(2)
    q = rng.normal(size=(500, 3))
    q = rng.uniform(5, 38, (500, 1)) * q / np.linalg.norm(q, axis=1)[:, None]  # inside
    near = prep.closest(q, exact=True)
    # inside a convex solid the distance is that to the nearest face plane (signed -)
    n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    inside = np.einsum("ij,kj->ik", q, n)
    h = np.einsum("kj,kj->k", V[T[:, 0]], n)
    np.testing.assert_allclose(near.distances, (inside - h).max(axis=1), atol=1e-9)
