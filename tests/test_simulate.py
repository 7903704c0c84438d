"""The virtual scanner (simulate/): geometry of the rays, defects, truth labels, motion."""
import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, sphere
from shapeverify.registration.rigid import apply_transform, rotation_vector
from shapeverify.simulate import BLOB, DENT, INLIER, OUTLIER, ScanEffects, virtual_scan

UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _face(surface, free=True):
    return Face(surface, (UNIT,), (np.full(4, free),), reversed=False)


@pytest.fixture(scope="module")
def plane():
    """Flat 200 x 100 mm plate at z = 0, normal +z."""
    ctrl = np.array([[[-100, -50, 0], [-100, 50, 0]], [[100, -50, 0], [100, 50, 0]]], float)
    s = NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)
    return Model(faces=(_face(s),), source="plate")


@pytest.fixture(scope="module")
def ball():
    return Model(faces=(_face(sphere(50.0), free=False),), source="sphere r=50")


def test_clean_scan_lies_on_the_plate(plane):
    vs = virtual_scan(plane, view=(0, 0, 1), pixel=2.0, noise=0.0, rng=0)
    # ~ area / pixel^2 points (the footprint grows slightly off-centre: perspective)
    assert 0.85 * 5000 < len(vs) < 1.15 * 5000
    assert np.all(vs.labels == INLIER)
    np.testing.assert_allclose(vs.scan[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(vs.scan, vs.points, atol=1e-9)
    np.testing.assert_allclose(vs.normals, np.tile([0, 0, 1.0], (len(vs), 1)), atol=1e-12)
    # every point is on its pixel's ray from the camera centre
    v = vs.points - vs.camera.center
    np.testing.assert_allclose(v / np.linalg.norm(v, axis=1, keepdims=True), vs.rays, atol=1e-9)
    np.testing.assert_allclose(vs.T_model_scan, np.eye(4))


def test_depth_noise_is_along_the_rays(plane):
    vs = virtual_scan(plane, view=(0.3, 0.0, 1.0), pixel=2.0, noise=0.05, rng=1)
    off = vs.scan - vs.points
    along = np.einsum("ij,ij->i", off, vs.rays)
    np.testing.assert_allclose(off, along[:, None] * vs.rays, atol=1e-9)
    assert abs(np.std(along) - 0.05) < 0.005 and abs(np.mean(along)) < 0.005


def test_sphere_occlusion_and_grazing(ball):
    """Only the front cap within max_incidence of the rays is seen; points are on the sphere."""
    vs = virtual_scan(ball, view=(0, 0, 1), distance=400, pixel=1.5, noise=0.0,
                      effects=ScanEffects(max_incidence=60.0), rng=2)
    r = np.linalg.norm(vs.scan, axis=1)
    np.testing.assert_allclose(r, 50.0, atol=1e-7)
    np.testing.assert_allclose(vs.normals, vs.scan / 50.0, atol=1e-7)
    cos_inc = -np.einsum("ij,ij->i", vs.normals, vs.rays)
    assert cos_inc.min() >= np.cos(np.radians(60.0)) - 1e-12
    assert vs.scan[:, 2].min() > 0  # nothing from the back half
    # the cap is nearly complete up to the grazing limit (perspective: slightly less than 60 deg)
    polar = np.degrees(np.arccos(vs.scan[:, 2] / 50.0))
    assert 50.0 < polar.max() <= 60.0


def test_zbuffer_agrees_with_exact_ray_casting(ball):
    exact = virtual_scan(ball, view=(0, 0, 1), distance=400, pixel=2.0, noise=0.0, rng=3)
    zbuf = virtual_scan(ball, view=(0, 0, 1), distance=400, pixel=2.0, noise=0.0, rng=3,
                        zbuffer=True)
    assert abs(len(zbuf) - len(exact)) < 0.05 * len(exact)
    # tangent plane of a sample within ~pixel/3 of the hit: error ~ d^2 / (2 R)
    r = np.linalg.norm(zbuf.scan, axis=1)
    assert np.max(np.abs(r - 50.0)) < 0.02
    assert zbuf.scan[:, 2].min() > 0


def test_defects_and_labels(plane):
    vs = virtual_scan(plane, view=(0, 0, 1), pixel=1.0, noise=0.0,
                      effects=ScanEffects(shadows=1, shadow_radius=15, blobs=1, blob_radius=10,
                                          blob_height=2.0, outlier_fraction=0.1,
                                          outlier_range=5.0, dents=[(0.4, 12.0)]), rng=4)
    c = vs.counts()
    n = len(vs)
    assert c["outlier"] == round(0.1 * n)
    assert abs(c["blob"] - np.pi * 10 ** 2) < 0.15 * np.pi * 10 ** 2
    assert abs(c["dent"] - np.pi * 12 ** 2) < 0.15 * np.pi * 12 ** 2
    # a 15 mm disc without data
    n0 = len(virtual_scan(plane, view=(0, 0, 1), pixel=1.0, noise=0.0, rng=4))
    assert abs((n0 - n) - np.pi * 15 ** 2) < 0.15 * np.pi * 15 ** 2
    z = vs.scan[:, 2]
    np.testing.assert_allclose(z[vs.labels == INLIER], 0.0, atol=1e-9)
    # blob: pushed towards the camera by h/2..h along the ray (rays nearly vertical here)
    zb = z[vs.labels == BLOB]
    assert zb.min() > 0.95 and zb.max() < 2.0 + 1e-9
    # dent: z = -0.4 (1 - s^2)^2 along the inward normal (here -z)
    d = vs.labels == DENT
    centre = vs.points[d][np.argmin(z[d])]
    s = np.linalg.norm(vs.points[d][:, :2] - centre[:2], axis=1) / 12.0
    np.testing.assert_allclose(z[d], -0.4 * (1 - s ** 2) ** 2, atol=0.003)
    assert z[d].min() < -0.39
    # outliers: 0.5..5 mm off along the ray, either side
    zo = np.abs(z[vs.labels == OUTLIER])
    assert zo.min() >= 0.49 and zo.max() <= 5.01
    assert 0.3 < np.mean(z[vs.labels == OUTLIER] > 0) < 0.7


def test_rigid_motion_and_truth(plane):
    vs = virtual_scan(plane, view=(0.2, -0.1, 1), pixel=3.0, noise=0.01, motion=(6.0, 12.0),
                      rng=5)
    T = vs.T_model_scan
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert np.degrees(np.linalg.norm(rotation_vector(R))) == pytest.approx(6.0)
    back = apply_transform(T, vs.scan)
    assert np.max(np.abs(back[:, 2])) < 0.1  # noise only
    # rotation about the centroid of the scanned points: the centroid moves by exactly 12 mm
    c = vs.points.mean(axis=0)
    assert np.linalg.norm(apply_transform(np.linalg.inv(T), c[None])[0] - c) == pytest.approx(12.0)
    acc = vs.accuracy(T)
    assert acc.crb < 1e-9 and acc.normal_rms < 1e-12 and acc.rotation_deg < 1e-12
    F = vs.fisher()
    assert np.all(np.linalg.eigvalsh(F)[:3] >= -1e-6)  # a plate: 3 directions without information


def test_reproducible_and_bad_input(plane):
    a = virtual_scan(plane, view=(0, 0, 1), pixel=4.0,
                     effects=ScanEffects(outlier_fraction=0.2), motion=(3, 3), rng=7)
    b = virtual_scan(plane, view=(0, 0, 1), pixel=4.0,
                     effects=ScanEffects(outlier_fraction=0.2), motion=(3, 3), rng=7)
    np.testing.assert_array_equal(a.scan, b.scan)
    np.testing.assert_array_equal(a.labels, b.labels)
    with pytest.raises(ValueError, match="noise"):
        virtual_scan(plane, noise=-1)
    with pytest.raises(ValueError, match="outlier_fraction"):
        virtual_scan(plane, effects=ScanEffects(outlier_fraction=1.0))
    with pytest.raises(ValueError, match="motion"):
        virtual_scan(plane, motion=(1, 2, 3))
    with pytest.raises(ValueError, match="no camera ray"):
        virtual_scan(plane, view=(0, 0, -1))  # looking at the back of the plate


def test_mesh_model_uses_the_zbuffer():
    """A triangle-mesh reference (no NURBS to ray-cast): tangent planes of triangles are exact."""
    v = np.array([[-100, -50, 0], [100, -50, 0], [100, 50, 0], [-100, 50, 0],
                  [-100, -50, -30], [100, -50, -30]], float)
    tri = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 1], [4, 1, 0]])  # plate + a skirt below
    mesh = Model(kind="mesh", vertices=v, triangles=tri, source="plate mesh")
    vs = virtual_scan(mesh, view=(0, 0, 1), pixel=2.0, noise=0.0, rng=8)
    assert 0.85 * 5000 < len(vs) < 1.15 * 5000
    np.testing.assert_allclose(vs.scan[:, 2], 0.0, atol=1e-9)   # the skirt is hidden / grazing
    np.testing.assert_allclose(np.abs(vs.normals[:, 2]), 1.0, atol=1e-12)
    with pytest.raises(ValueError, match="CAD model"):
        virtual_scan(mesh, zbuffer=False)
