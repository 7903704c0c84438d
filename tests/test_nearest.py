"""prepare / Prepared.closest / save + load: analytic shapes, brute force and OCP as oracles."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.spatial import cKDTree

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, cylinder, sphere
from shapeverify.nearest import Closest, Prepared, load_prepared, prepare
from shapeverify.nearest.prepared import default_reach, default_spacing

RECT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _plane(p00, pu, pv) -> NurbsSurface:
    """Bilinear patch S(u, v) = p00 + u pu + v pv on [0, 1]^2 (Su x Sv = pu x pv)."""
    p00, pu, pv = (np.asarray(a, float) for a in (p00, pu, pv))
    ctrl = np.array([[p00, p00 + pv], [p00 + pu, p00 + pu + pv]])
    return NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)


def _shell(rng, n, center, r_lo, r_hi):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    r = rng.uniform(r_lo, r_hi, n)
    return center + d * r[:, None], d, r


# ------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def sphere_model():
    face = Face(sphere(10.0), (RECT,), (np.zeros(4, bool),))
    return Model(faces=(face,), source="sphere R=10")


@pytest.fixture(scope="module")
def sphere_prep(sphere_model):
    return prepare(sphere_model, spacing=0.5, reach=3.0)


@pytest.fixture(scope="module")
def cylinder_prep():
    # lateral face of a cylinder r = 5, z in [0, 20]; the rims (v = 0, v = 1) are free edges,
    # the seam (u = 0 = 1) is shared with itself
    face = Face(cylinder(5.0, 20.0), (RECT,), (np.array([True, False, True, False]),))
    return prepare(Model(faces=(face,), source="cylinder"), spacing=0.4, reach=2.0)


# --------------------------------------------------------------------- analytic shapes
def test_sphere_exact_distance_foot_normal_and_sign(sphere_prep):
    rng = np.random.default_rng(0)
    q, d, r = _shell(rng, 4000, 0.0, 7.5, 12.5)
    near = sphere_prep.closest(q, exact=True)
    np.testing.assert_allclose(near.distances, r - 10.0, atol=1e-9)
    np.testing.assert_allclose(near.points, 10.0 * d, atol=1e-8)
    np.testing.assert_allclose(near.normals, d, atol=1e-8)
    assert np.all(near.distances[r > 10.0] > 0) and np.all(near.distances[r < 10.0] < 0)
    assert not near.on_boundary.any()
    # the (u, v) are where the foot is
    np.testing.assert_allclose(sphere(10.0).evaluate(near.uv[:, 0], near.uv[:, 1]),
                               near.points, atol=1e-8)


def test_fast_mode_error_falls_with_spacing_squared(sphere_model):
    rng = np.random.default_rng(1)
    q, d, r = _shell(rng, 4000, 0.0, 8.5, 11.5)
    errs = []
    for h in (0.8, 0.4):
        prep = prepare(sphere_model, spacing=h, reach=2.0)
        near = prep.closest(q)
        clear = np.abs(r - 10.0) > 0.1  # farther than the fast mode's error
        assert np.all(np.sign(near.distances[clear]) == np.sign(r[clear] - 10.0))
        errs.append(np.abs(near.distances - (r - 10.0)).max())
        # the nearest model point is the true nearest one (brute force)
        _, true_idx = cKDTree(prep.points.points).query(q)
        assert np.mean(near.index == true_idx) >= 0.999
    assert errs[0] < 0.1 and errs[1] < 0.03
    assert errs[0] / errs[1] > 2.5, errs  # ~h^2: halving h divides the error by ~4


def test_cylinder_rims_are_free_edges_and_seam_wraps(cylinder_prep):
    rng = np.random.default_rng(2)
    n = 3000
    phi = rng.uniform(0, 2 * np.pi, n)
    rho = rng.uniform(3.5, 6.5, n)
    z = rng.uniform(-1.5, 21.5, n)
    q = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])
    near = cylinder_prep.closest(q, exact=True)
    dz = np.where(z > 20.0, z - 20.0, np.where(z < 0.0, -z, 0.0))
    expect = np.hypot(rho - 5.0, dz)
    np.testing.assert_allclose(np.abs(near.distances), expect, atol=1e-9)
    inside = dz == 0
    np.testing.assert_allclose(near.distances[inside], rho[inside] - 5.0, atol=1e-9)
    np.testing.assert_array_equal(near.on_boundary, ~inside)
    foot_z = np.clip(z, 0.0, 20.0)
    np.testing.assert_allclose(near.points[:, 2], foot_z, atol=1e-9)
    np.testing.assert_allclose(np.hypot(near.points[:, 0], near.points[:, 1]), 5.0, atol=1e-9)
    # points right at the seam (phi = 0, i.e. u = 0 = 1)
    qs = np.column_stack([np.full(50, 6.0), rng.uniform(-1e-3, 1e-3, 50), rng.uniform(1, 19, 50)])
    seam = cylinder_prep.closest(qs, exact=True)
    np.testing.assert_allclose(seam.distances, np.hypot(6.0, qs[:, 1]) - 5.0, atol=1e-9)


def test_point_above_a_hole_projects_onto_the_hole_edge():
    hole = 0.5 + 0.1 * np.array([[-1, -1], [-1, 1], [1, 1], [1, -1]], float)  # x, y in [4, 6]
    face = Face(_plane([0, 0, 0], [10, 0, 0], [0, 10, 0]), (RECT, hole),
                (np.zeros(4, bool), np.ones(4, bool)))
    prep = prepare(Model(faces=(face,), source="plate with hole"), spacing=0.2,
                   reach=2.0)
    q = np.array([[5.3, 5.1, 1.0],     # above the hole: nearest is the edge x = 6
                  [4.5, 5.9, -0.5],    # below it: nearest is the edge y = 6
                  [5.0, 5.0, 0.3],     # over the centre: 1 mm to every edge
                  [12.0, 5.0, 0.5],    # beyond the outer boundary (not a free edge here)
                  [2.0, 3.0, 0.7]])    # over the plate
    near = prep.closest(q, exact=True)
    foot = np.array([[6.0, 5.1, 0.0], [4.5, 6.0, 0.0], [np.nan] * 3, [10.0, 5.0, 0.0],
                     [2.0, 3.0, 0.0]])
    expect = np.array([np.hypot(0.7, 1.0), np.hypot(0.1, 0.5), np.hypot(1.0, 0.3),
                       np.hypot(2.0, 0.5), 0.7])
    np.testing.assert_allclose(np.abs(near.distances), expect, atol=1e-9)
    np.testing.assert_allclose(near.points[[0, 1, 3, 4]], foot[[0, 1, 3, 4]], atol=1e-9)
    assert near.on_boundary.tolist() == [True, True, True, False, False]
    assert np.sign(near.distances).tolist() == [1, -1, 1, 1, 1]
    # on the hole's edge, the foot lies on the square x, y in [4, 6]
    p = near.points[2]
    assert max(abs(p[0] - 5.0), abs(p[1] - 5.0)) == pytest.approx(1.0, abs=1e-9)


def test_shared_edge_between_two_faces():
    """A convex 90-degree edge: top z = 0 (normal +z) and side x = 10 (normal +x)."""
    top = Face(_plane([0, 0, 0], [10, 0, 0], [0, 10, 0]), (RECT,),
               (np.array([True, False, True, True]),))          # x = 10 edge shared
    side = Face(_plane([10, 0, -10], [0, 10, 0], [0, 0, 10]), (RECT,),
                (np.array([True, True, False, True]),))         # z = 0 edge shared
    prep = prepare(Model(faces=(top, side), source="edge"), spacing=0.2, reach=2.0)
    rng = np.random.default_rng(3)
    n = 3000
    q = np.column_stack([rng.uniform(8.0, 11.5, n), rng.uniform(1.0, 9.0, n),
                         rng.uniform(-2.0, 1.5, n)])
    near = prep.closest(q, exact=True)
    fa = np.column_stack([np.clip(q[:, 0], 0, 10), q[:, 1], np.zeros(n)])
    fb = np.column_stack([np.full(n, 10.0), q[:, 1], np.clip(q[:, 2], -10, 0)])
    da = np.linalg.norm(q - fa, axis=1)
    db = np.linalg.norm(q - fb, axis=1)
    expect = np.minimum(da, db)
    np.testing.assert_allclose(np.abs(near.distances), expect, atol=1e-9)
    solid = (q[:, 0] < 10.0) & (q[:, 2] < 0.0)
    clear = np.abs(da - db) > 1e-6
    assert np.all(np.sign(near.distances[clear]) == np.where(solid[clear], -1, 1))
    assert not near.on_boundary.any()  # the feet are on faces or on the shared edge
    np.testing.assert_array_equal(near.face[clear], np.where(da < db, 0, 1)[clear])


# ------------------------------------------------------------------ meshes and clouds
def _uv_sphere_mesh(r=5.0, nu=24, nv=12):
    th = np.linspace(0, np.pi, nv + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    V = [[0, 0, -r]]
    for t in th:  # rings from the south pole up
        for p in ph:
            V.append([r * np.sin(t) * np.cos(p), r * np.sin(t) * np.sin(p), -r * np.cos(t)])
    V.append([0, 0, r])
    V = np.array(V)
    T = []
    for k in range(nu):  # bottom cap, outward (counter-clockwise seen from outside)
        T.append([0, 1 + (k + 1) % nu, 1 + k])
    for ring in range(nv - 2):
        a, b = 1 + ring * nu, 1 + (ring + 1) * nu
        for k in range(nu):
            k1 = (k + 1) % nu
            T += [[a + k, a + k1, b + k1], [a + k, b + k1, b + k]]
    top = V.shape[0] - 1
    a = 1 + (nv - 2) * nu
    for k in range(nu):
        T.append([a + k, a + (k + 1) % nu, top])
    T = np.array(T)
    # orient every triangle outwards (the mesh is star-shaped around the origin)
    n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    inward = np.einsum("ij,ij->i", n, V[T].mean(axis=1)) < 0
    T[inward] = T[inward][:, ::-1]
    return V, T


def _brute_triangles(q, V, T):
    """Distance from each query to the closest triangle (plane, else the three edges)."""
    A, B, C = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    n = np.cross(B - A, C - A)
    n /= np.linalg.norm(n, axis=1)[:, None]
    out = np.empty(q.shape[0])
    for i, p in enumerate(q):
        h = np.einsum("ij,ij->i", p - A, n)
        f = p - h[:, None] * n
        inside = np.ones(T.shape[0], bool)
        for X, Y in ((A, B), (B, C), (C, A)):
            inside &= np.einsum("ij,ij->i", np.cross(Y - X, f - X), n) >= 0
        best = np.where(inside, np.abs(h), np.inf)
        for X, Y in ((A, B), (B, C), (C, A)):
            e = Y - X
            t = np.clip(np.einsum("ij,ij->i", p - X, e) / np.einsum("ij,ij->i", e, e), 0, 1)
            best = np.minimum(best, np.linalg.norm(p - (X + t[:, None] * e), axis=1))
        out[i] = best.min()
    return out


@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
def test_mesh_exact_against_brute_force():
    V, T = _uv_sphere_mesh()
    model = Model(kind="mesh", vertices=V, triangles=T.astype(np.int32), source="uv sphere")
    prep = prepare(model, spacing=0.3, reach=1.5)
    rng = np.random.default_rng(4)
    q, _, r = _shell(rng, 600, 0.0, 4.0, 6.2)
    near = prep.closest(q, exact=True)
    expect = _brute_triangles(q, V, T)
    np.testing.assert_allclose(np.abs(near.distances), expect, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(near.points - q, axis=1), expect, atol=1e-9)
    # signs: the mesh is closed and outward; its inscribed radius is about 4.9
    assert np.all(near.distances[r > 5.0] > 0) and np.all(near.distances[r < 4.8] < 0)
    # the barycentric (u, v) reproduce the foot
    tri = T[near.face]
    A, B, C = V[tri[:, 0]], V[tri[:, 1]], V[tri[:, 2]]
    rebuilt = A + near.uv[:, :1] * (B - A) + near.uv[:, 1:] * (C - A)
    np.testing.assert_allclose(rebuilt, near.points, atol=1e-9)


def test_point_cloud_exact_measures_to_the_surface_not_the_nearest_point():
    """Issue 29 item 3: a cloud reference is measured to a quadric through its neighbours (the
    nearest cloud point alone is off by up to half the cloud's spacing)."""
    rng = np.random.default_rng(5)
    P = rng.normal(size=(3000, 3))
    P = 8.0 * P / np.linalg.norm(P, axis=1)[:, None]       # spacing about 0.5 mm
    for normals in (P / 8.0, None):                          # given, and PCA normals
        model = Model(kind="points", vertices=P, cloud_normals=normals, source="cloud")
        prep = prepare(model, spacing=0.6, reach=2.0)
        q, _, r = _shell(rng, 1000, 0.0, 6.5, 9.5)
        near = prep.closest(q, exact=True)
        truth = r - 8.0                                     # signed distance to the sphere
        np.testing.assert_allclose(near.distances, truth, atol=3e-3)
        d_point = cKDTree(P).query(q)[0]
        assert np.percentile(np.abs(d_point - np.abs(truth)), 95) > 0.05   # the old answer
        np.testing.assert_allclose(np.linalg.norm(near.points, axis=1), 8.0, atol=3e-3)
        radial = q / r[:, None]
        assert np.einsum("ij,ij->i", near.normals, radial).min() > 0.999
        assert np.all(near.face == -1) and not near.on_boundary.any()


# ----------------------------------------------------------------- real CAD vs OCP
def _against_ocp(model, prep, n, reach, rng, tol):
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.gp import gp_Pnt

    from shapeverify.cad.occ_write import to_occ

    mp = prep.points
    i = rng.integers(0, prep.n_points, n)
    h = prep.spacing
    q = mp.points[i] + mp.normals[i] * rng.uniform(-reach, reach, n)[:, None] \
        + rng.normal(size=(n, 3)) * 0.3 * h
    near = prep.closest(q, exact=True)
    occ = {}
    checked = 0
    for k in range(n):
        f = int(near.face[k])
        if near.on_boundary[k]:
            continue
        occ.setdefault(f, to_occ(model.faces[f].surface))
        proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, q[k])), occ[f])
        if proj.NbPoints() == 0:
            continue
        u, v = proj.LowerDistanceParameters()
        if not model.faces[f].contains([[u, v]])[0]:
            continue  # OCP ignores trims: compare interior feet only
        p = proj.NearestPoint()
        assert abs(abs(near.distances[k]) - proj.LowerDistance()) < tol
        assert np.abs(near.points[k] - [p.X(), p.Y(), p.Z()]).max() < tol
        checked += 1
    assert checked > 0.8 * n
    return near


@pytest.mark.shared
def test_wavy_cube_exact_against_ocp(shared_data):
    from shapeverify.cad.load import load_model

    model = load_model(shared_data / "cad" / "wavy-cube.stp")
    prep = prepare(model, spacing=0.02, reach=0.06)
    near = _against_ocp(model, prep, 400, 0.05, np.random.default_rng(6), 1e-8)
    assert np.all(np.isfinite(near.distances))


@pytest.mark.shared
@pytest.mark.slow
def test_impeller_exact_against_ocp(shared_data):
    from model_cache import cached_prepared

    # the same preparation as test_nearest_exact's impeller_prep: built once per run
    # (tests/model_cache.py; bitwise what prepare(load_model(path), ...) gives)
    prep = cached_prepared(shared_data / "cad" / "impeller.igs", spacing=0.5, reach=3.0)
    model = prep.model
    _against_ocp(model, prep, 300, 1.5, np.random.default_rng(7), 1e-8)


# ----------------------------------------------------------------- file and object
def test_save_load_round_trip(cylinder_prep, tmp_path):
    path = tmp_path / "cyl.svm"
    cylinder_prep.save(path)
    t0 = time.perf_counter()
    back = load_prepared(path)
    assert time.perf_counter() - t0 < 0.5
    assert isinstance(back, Prepared)
    assert back.spacing == cylinder_prep.spacing
    assert back.reach == cylinder_prep.reach
    rng = np.random.default_rng(8)
    q = np.column_stack([rng.uniform(-8, 8, 2000), rng.uniform(-8, 8, 2000),
                         rng.uniform(-3, 23, 2000)])
    for exact in (False, True):
        a = cylinder_prep.closest(q, exact=exact)
        b = back.closest(q, exact=exact)
        for name in ("points", "normals", "distances", "face", "uv", "index", "on_boundary"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert back.nbytes == cylinder_prep.nbytes


def test_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_prepared(tmp_path / "missing.svm")
    bad = tmp_path / "bad.svm"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match="not a prepared-model"):
        load_prepared(bad)
    other = tmp_path / "other.svm"
    with open(other, "wb") as fh:
        np.savez(fh, meta=np.frombuffer(b'{"format": "something-else"}', dtype=np.uint8))
    with pytest.raises(ValueError, match="format"):
        load_prepared(other)


def test_closest_validates_input_and_reports(sphere_prep):
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        sphere_prep.closest(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="NaN"):
        sphere_prep.closest([[np.nan, 0.0, 0.0]])
    empty = sphere_prep.closest(np.zeros((0, 3)))
    assert isinstance(empty, Closest) and len(empty) == 0
    one = sphere_prep.closest([0.0, 0.0, 11.0], exact=True)   # a single (3,) point
    assert one.distances.shape == (1,) and one.distances[0] == pytest.approx(1.0, abs=1e-9)
    assert "Closest(n=1" in repr(one) and "Prepared(" in repr(sphere_prep)
    assert 0 < sphere_prep.memory_per_point <= 200
    mp = sphere_prep.points
    assert len(mp) == sphere_prep.n_points
    np.testing.assert_allclose(np.einsum("ij,ij->i", mp.normals, mp.tangent_u), 0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(mp.tangent_v, axis=1), 1, atol=1e-6)


def test_prepare_arguments(sphere_model):
    for bad in (0.0, -1.0, np.nan, "x"):
        with pytest.raises(ValueError, match="spacing"):
            prepare(sphere_model, spacing=bad)
        with pytest.raises(ValueError, match="reach"):
            prepare(sphere_model, spacing=1.0, reach=bad)
    assert default_spacing(100.0) == pytest.approx(0.2)
    assert default_spacing(4e4) == pytest.approx(80.0) and default_spacing(0.0) == 1.0
    assert default_reach(100.0, 0.2) == pytest.approx(3.0)
    assert default_reach(1.0, 0.1) == pytest.approx(0.2)


@pytest.mark.slow
def test_prepare_with_defaults():
    face = Face(_plane([0, 0, 0], [10, 0, 0], [0, 10, 0]), (RECT,), (np.ones(4, bool),))
    model = Model(faces=(face,), source="plate")
    prep = prepare(model)
    assert prep.spacing == pytest.approx(default_spacing(model.size))
    assert prep.reach == pytest.approx(default_reach(model.size, prep.spacing))
    q = np.array([[5.0, 5.0, 0.3], [5.0, 5.0, -50.0], [12.0, 5.0, 0.0]])  # near, far, beyond
    near = prep.closest(q, exact=True)
    np.testing.assert_allclose(near.distances, [0.3, -50.0, 2.0], atol=1e-9)
    assert near.on_boundary.tolist() == [False, False, True]
    fast = prep.closest(q)
    np.testing.assert_allclose(fast.distances[:2], [0.3, -50.0], atol=1e-6)
    assert fast.on_boundary[2]


def test_patch_tables_match_nurbs_evaluation():
    """The polynomial patch tables of exact mode reproduce NurbsSurface.derivatives."""
    from shapeverify.nearest.exact import ExactCAD

    rng = np.random.default_rng(9)
    ctrl = np.stack(np.meshgrid(np.arange(6.0), np.arange(5.0), indexing="ij"), axis=-1)
    ctrl = np.concatenate([ctrl, rng.normal(size=(6, 5, 1))], axis=-1)
    ku = [0, 0, 0, 0, 0.3, 0.6, 1, 1, 1, 1]
    kv = [0, 0, 0, 0.2, 0.2, 1, 1, 1]  # a double knot
    surfaces = [sphere(3.0), cylinder(2.0, 5.0),
                NurbsSurface(3, 2, ku, kv, ctrl, rng.uniform(0.5, 2.0, (6, 5)))]
    faces = tuple(Face(s, (RECT,), (np.zeros(4, bool),)) for s in surfaces)
    ex = ExactCAD(Model(faces=faces, source="tables"), spacing=0.1)
    for f, s in enumerate(surfaces):
        (u0, u1), (v0, v1) = s.domain
        uv = np.column_stack([rng.uniform(u0, u1, 200), rng.uniform(v0, v1, 200)])
        got = ex.derivatives(np.full(200, f), uv)
        ref = s.derivatives(uv[:, 0], uv[:, 1], order=2)
        for k, l in [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]:
            scale = np.abs(ref[:, k, l]).max() + 1.0
            np.testing.assert_allclose(got[:, k, l], ref[:, k, l], atol=1e-10 * scale,
                                       err_msg=f"surface {f}, derivative ({k}, {l})")
