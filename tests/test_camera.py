"""Camera model, exact ray–CAD intersection and the small-motion update (issue 6)."""

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, cylinder, sphere
from shapeverify.camera import PinholeCamera, depth_map, intersect_rays, make_view, render


def _full_face(surface, holes=()):
    (u0, u1), (v0, v1) = surface.domain
    outer = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], float)
    loops = (outer, *holes)
    return Face(surface, loops, tuple(np.ones(len(l), bool) for l in loops), reversed=False)


def _model(*faces):
    return Model(faces=tuple(faces), unit="mm", scale_to_mm=1.0, source="test", kind="cad")


@pytest.fixture(scope="module")
def sphere_model():
    return _model(_full_face(sphere(10.0)))


def _circle_poly(center, r, n=400, reverse=False):
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    if reverse:
        a = a[::-1]
    return np.column_stack([center[0] + r * np.cos(a), center[1] + r * np.sin(a)])


def test_pinhole_project_unproject_roundtrip():
    cam = PinholeCamera.look_at([0, -100, 30], [0, 0, 0], fov_deg=50, width=64, height=48, k1=-0.1, k2=0.02)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-10, 10, (200, 3))
    pix, z = cam.project(pts)
    back = cam.unproject(pix, z)
    np.testing.assert_allclose(back, pts, atol=1e-9)
    o, d = cam.rays(pix)
    # each point lies on the ray of its pixel
    v = pts - o
    np.testing.assert_allclose(np.linalg.norm(np.cross(v, d), axis=1), 0, atol=1e-9)


def test_pinhole_rejects_bad_pose():
    with pytest.raises(ValueError, match="rotation"):
        PinholeCamera(100, 100, 50, 50, 100, 100, T_world_camera=np.diag([1.0, 1.0, -1.0, 1.0]))
    with pytest.raises(ValueError, match="focal"):
        PinholeCamera(0, 100, 50, 50, 100, 100)


def test_rays_hit_sphere_exactly(sphere_model):
    rng = np.random.default_rng(1)
    n = 2000
    origins = rng.normal(size=(n, 3))
    origins = 40 * origins / np.linalg.norm(origins, axis=1, keepdims=True)
    targets = rng.uniform(-6, 6, (n, 3))
    d = targets - origins
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = intersect_rays(sphere_model, origins, d)
    # analytic first intersection of the line with the sphere |x| = 10
    b = np.einsum("ij,ij->i", origins, d)
    c = np.einsum("ij,ij->i", origins, origins) - 100
    disc = b * b - c
    expect_hit = disc > 1e-6
    assert np.array_equal(hits.hit, expect_hit)
    t_exact = -b - np.sqrt(np.maximum(disc, 0))
    np.testing.assert_allclose(hits.distances[expect_hit], t_exact[expect_hit], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(hits.points[hits.hit], axis=1), 10.0, atol=1e-9)
    # outward normals are radial
    np.testing.assert_allclose(hits.normals[hits.hit], hits.points[hits.hit] / 10.0, atol=1e-9)


def test_rays_hit_cylinder_exactly():
    model = _model(_full_face(cylinder(5.0, 20.0)))
    n = 500
    rng = np.random.default_rng(2)
    z = rng.uniform(1, 19, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    origins = np.column_stack([30 * np.cos(ang), 30 * np.sin(ang), z])
    d = -origins.copy()
    d[:, 2] = 0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = intersect_rays(model, origins, d)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.distances, 25.0, atol=1e-9)
    np.testing.assert_allclose(hits.points[:, 2], z, atol=1e-9)


def test_ray_through_hole_misses_that_face():
    # a flat 100 x 100 plate (bilinear patch) with a round hole of radius 10 at the centre
    ctrl = np.array([[[0, 0, 0], [0, 100, 0]], [[100, 0, 0], [100, 100, 0]]], float)
    plate = NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)
    hole = _circle_poly((0.5, 0.5), 0.1, reverse=True)
    model = _model(_full_face(plate, holes=(hole,)))
    origins = np.array([[50.0, 50.0, 10.0], [50.0, 58.0, 10.0], [50.0, 62.0, 10.0], [20.0, 20.0, 10.0]])
    d = np.tile([0.0, 0.0, -1.0], (4, 1))
    hits = intersect_rays(model, origins, d)
    assert hits.hit.tolist() == [False, False, True, True]
    np.testing.assert_allclose(hits.distances[hits.hit], 10.0, atol=1e-12)


def test_first_hit_behind_hole_is_the_next_face():
    ctrl = np.array([[[0, 0, 0], [0, 100, 0]], [[100, 0, 0], [100, 100, 0]]], float)
    top = NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl + [0, 0, 5])
    bottom = NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)
    hole = _circle_poly((0.5, 0.5), 0.1, reverse=True)
    model = _model(_full_face(top, holes=(hole,)), _full_face(bottom))
    hits = intersect_rays(model, [[50.0, 50.0, 20.0], [30.0, 30.0, 20.0]], [[0, 0, -1.0], [0, 0, -1.0]])
    assert hits.face.tolist() == [1, 0]
    np.testing.assert_allclose(hits.distances, [20.0, 15.0], atol=1e-12)


def test_small_motion_update_equals_fresh(sphere_model):
    cam = PinholeCamera.look_at([0, -60, 20], [0, 0, 0], fov_deg=30, width=48, height=40)
    view = make_view(sphere_model, cam)
    assert view.hits.hit.sum() > 300
    ang = np.radians(0.5)
    T = np.eye(4)
    T[:3, :3] = [[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]]
    T[:3, 3] = [0.2, -0.1, 0.3]
    upd = depth_map(view, T)
    fresh = make_view(sphere_model, cam, T).hits
    assert np.array_equal(upd.hit, fresh.hit)
    np.testing.assert_allclose(upd.distances[upd.hit], fresh.distances[fresh.hit], atol=1e-9)
    np.testing.assert_allclose(upd.points[upd.hit], fresh.points[fresh.hit], atol=1e-9)


def test_render_images(sphere_model):
    cam = PinholeCamera.look_at([0, -60, 0], [0, 0, 0], up=(0, 0, 1), fov_deg=30, width=32, height=32)
    img = render(sphere_model, cam)
    assert img["depth"].shape == (32, 32) and img["normal"].shape == (32, 32, 3)
    assert img["mask"][16, 16] and not img["mask"][0, 0]
    # the centre pixel sees the sphere's front point at depth 50
    c = np.nanmin(img["depth"])
    assert abs(c - 50.0) < 0.05
    assert (img["face"][img["mask"]] == 0).all() and (img["face"][~img["mask"]] == -1).all()


def test_bad_rays_rejected(sphere_model):
    with pytest.raises(ValueError, match="shape"):
        intersect_rays(sphere_model, np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="finite"):
        intersect_rays(sphere_model, [[np.nan, 0, 0]], [[1.0, 0, 0]])
    with pytest.raises(ValueError, match="zero"):
        intersect_rays(sphere_model, [[0.0, 0, 0]], [[0.0, 0, 0]])
