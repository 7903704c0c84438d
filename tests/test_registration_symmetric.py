"""Symmetric parts (issue 14 item 3): a turned part's free spin is named, does not block
convergence, and a good turned part passes inspection."""

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, _CIRCLE_KNOTS, _CIRCLE_W, _CIRCLE_XY
from shapeverify.nearest import prepare
from shapeverify.registration import DegenerateGeometryWarning, _irls, register
from shapeverify.simulate import ScanEffects, random_motion, virtual_scan

#: (r, z) profile of a turned part (mm): bore 10, flange 40 x 30, shaft 25, chamfer to 20
PROFILE = np.array([[10, 0], [40, 0], [40, 30], [25, 30], [25, 70], [20, 75], [10, 75]], float)


def turned_part(profile=PROFILE) -> Model:
    """One exact NURBS face: the closed (r, z) polyline revolved about the z axis."""
    prof = np.vstack([profile, profile[:1]])
    m = len(prof)
    P = np.empty((9, m, 3))
    P[:, :, 0] = _CIRCLE_XY[:, 0, None] * prof[None, :, 0]
    P[:, :, 1] = _CIRCLE_XY[:, 1, None] * prof[None, :, 0]
    P[:, :, 2] = prof[None, :, 1]
    W = np.repeat(_CIRCLE_W[:, None], m, axis=1)
    seg = np.r_[0, np.cumsum(np.linalg.norm(np.diff(prof, axis=0), axis=1))]
    s = NurbsSurface(2, 1, _CIRCLE_KNOTS, np.r_[0, seg / seg[-1], 1], P, W)
    t = np.linspace(0, 1, 64, endpoint=False)
    loop = np.concatenate([np.c_[t, 0 * t], np.c_[1 + 0 * t, t], np.c_[1 - t, 1 + 0 * t],
                           np.c_[0 * t, 1 - t]])
    return Model(faces=(Face(s, (loop,), (np.zeros(len(loop), bool),)),), source="turned part")


@pytest.fixture(scope="module")
def turned():
    model = turned_part()
    return model, prepare(model, spacing=1.0)


def _two_views(model, motion, seed):
    """Front and back views of the part in one scan (one rigid motion), ~60 % of its area."""
    motion = random_motion(*motion, center=(0.0, 0.0, 40.0), rng=seed)
    a = virtual_scan(model, view=(1.0, 0.2, 0.5), pixel=1.0, noise=0.02, motion=motion, rng=seed)
    b = virtual_scan(model, view=(-1.0, -0.3, 0.5), pixel=1.0, noise=0.02, motion=motion,
                     rng=seed + 1)
    return a, b, np.vstack([a.scan, b.scan])


@pytest.mark.slow   # preparing the part: 5-30 s
@pytest.mark.parametrize("seed", [0, 1])
def test_turned_part_converges_with_its_spin_named(turned, seed):
    model, prep = turned
    a, _, _ = _two_views(model, (4.0, 4.0), seed)
    with pytest.warns(DegenerateGeometryWarning, match="1 pose direction"):
        reg = register(a.scan, prep)
    assert reg.converged, reg.message
    assert len(reg.undetermined) == 1 and reg.undetermined[0].startswith("rotation about axis")
    assert "[0.000, 0.000, 1.000]" in reg.undetermined[0].replace("-0.000", "0.000") or \
        "[0.000, 0.000, -1.000]" in reg.undetermined[0].replace("-0.000", "0.000")
    np.testing.assert_allclose(np.abs(reg.undetermined_directions[0, :3]), [0, 0, 1], atol=1e-6)
    assert reg.warnings == ()
    # the determined directions are right: every point lies on the part (the spin moves
    # points along the surface only)
    X = a.scan[a.inliers] @ reg.R.T + reg.t
    d = prep.closest(X, exact=True).distances
    assert np.sqrt(np.mean(d ** 2)) < 0.03
    # the axis itself is recovered: the truth's axis point and direction
    Tt = a.T_model_scan
    axis_scan = np.linalg.inv(Tt)[:3, :3] @ [0, 0, 1.0]
    np.testing.assert_allclose(reg.R @ axis_scan, [0, 0, 1.0], atol=2e-4)


@pytest.mark.slow
def test_good_turned_part_passes_inspection(turned):
    import shapeverify as sv

    model, prep = turned
    a, b, scan = _two_views(model, (3.0, 3.0), 5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sv.inspect(prep, scan, tolerance=0.5)
    assert res.registration.converged and len(res.registration.undetermined) == 1
    assert res.verdict == "pass", res.reasons


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_turned_part_in_the_sensor_frame_lands_in_the_right_basin(turned, seed):
    """A single view of the turned part in a sensor frame far from the model, at any rotation,
    no start: before the scan's own axis was read from its normals, the principal-axes and
    FPFH hypotheses left a side view 15-20 deg tilted and 13-20 mm shifted, and 3-4 of 8 such
    scans of a stepped shaft ended 1.7-3.8 mm off the surface."""
    from scipy.spatial.transform import Rotation

    model, prep = turned
    rng = np.random.default_rng(seed)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    T[:3, 3] = rng.uniform(-800.0, 800.0, 3)
    view = rng.normal(size=3)
    a = virtual_scan(model, view=view, pixel=1.0, noise=0.02, motion=T,
                     effects=ScanEffects(outlier_fraction=0.02),
                     rng=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = register(a.scan, prep)
    X = a.scan[a.inliers] @ reg.R.T + reg.t
    d = prep.closest(X, exact=True).distances
    assert np.sqrt(np.mean(d ** 2)) < 0.03, reg.message
    axis_scan = np.linalg.inv(a.T_model_scan)[:3, :3] @ [0, 0, 1.0]
    np.testing.assert_allclose(reg.R @ axis_scan, [0, 0, 1.0], atol=1e-3)
    # its spin copies are one answer, not "another start that fits as well"
    assert reg.converged and reg.warnings == (), reg.warnings


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_turned_part_with_many_outliers_still_shows_its_axis(turned, seed):
    """10 % outliers, 0.05 mm noise: each isolated outlier had a voxel of the subsample to
    itself, so half the normals the scan's axis was read from were the outliers', too few met
    the axis (10-21 %), and 5 of 8 such views of a stepped shaft ended 2-3 mm off (flagged,
    but wrong); the voxels where the scan is sparse are now left out."""
    from scipy.spatial.transform import Rotation

    from shapeverify.registration import _revolution
    from shapeverify.registration.global_search import _normals

    model, prep = turned
    rng = np.random.default_rng(seed)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    T[:3, 3] = rng.uniform(-800.0, 800.0, 3)
    a = virtual_scan(model, view=rng.normal(size=3), pixel=0.5, noise=0.05, motion=T,
                     effects=ScanEffects(outlier_fraction=0.10), rng=seed)
    X = a.scan[_revolution._dense_voxels(a.scan, 120.0 / _revolution.VOXELS)]
    axis, _, miss = _revolution.axis_of_normals(
        X, _normals(X, cKDTree(X), _revolution.NEIGHBOURS), _revolution.NEAR * 120.0)
    assert _revolution._agree(miss) >= 0.6
    true_axis = a.T_model_scan[:3, :3].T @ [0, 0, 1.0]
    assert abs(axis @ true_axis) > np.cos(np.radians(1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = register(a.scan, prep)
    np.testing.assert_allclose(reg.R @ true_axis, [0, 0, 1.0], atol=1e-3)
    X = a.scan[a.inliers] @ reg.R.T + reg.t
    assert np.median(np.abs(prep.closest(X, exact=True).distances)) < 0.06, reg.message


def test_axis_of_a_turned_part_from_its_normals():
    """The model's axis of revolution is read from its normal lines (a saddle and a flat plate
    have none; a gently bent sheet would have its osculating cylinder's)."""
    from types import SimpleNamespace

    from shapeverify.registration import _revolution

    mp = turned_part().sample(2.0)
    side = SimpleNamespace(axes_points=mp.points, axes_normals=mp.normals, size=120.0)
    a, c, lohi = _revolution.model_axis(side)
    np.testing.assert_allclose(np.abs(a), [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(c[:2], [0, 0], atol=1e-5)
    assert lohi[1] - lohi[0] == pytest.approx(75.0, abs=1.0)
    g = np.linspace(0, 100, 40)
    X = np.stack(np.meshgrid(g, g, [0.0]), axis=-1).reshape(-1, 3)
    X[:, 2] = 0.004 * ((X[:, 0] - 50) ** 2 - (X[:, 1] - 50) ** 2)     # a saddle
    Nrm = np.c_[-0.008 * (X[:, 0] - 50), 0.008 * (X[:, 1] - 50), np.ones(len(X))]
    Nrm /= np.linalg.norm(Nrm, axis=1)[:, None]
    sheet = SimpleNamespace(axes_points=X, axes_normals=Nrm, size=141.0)
    assert _revolution.model_axis(sheet) is None
    flat = SimpleNamespace(axes_points=X * [1, 1, 0], axes_normals=0 * X + [0, 0, 1.0],
                           size=141.0)
    assert _revolution.model_axis(flat) is None


@pytest.mark.slow
def test_mesh_of_a_turned_part_converges_with_its_spin_named():
    """An STL-like mesh of the turned part (facets of about 2 mm) and a noisy depth-camera-like
    scan from the sensor frame: the facets gave the spin a weak, spurious information (relative
    1e-4), the pose drifted along it between re-matchings and 5 of 8 right poses of such scans
    said converged=False, the spin not named."""
    from scipy.spatial.transform import Rotation

    from shapeverify.cad.tessellate import tessellate_model

    tess = tessellate_model(turned_part(), max_edge=2.0)
    V, inv = np.unique(np.round(tess.vertices, 6), axis=0, return_inverse=True)
    T = inv.reshape(-1)[tess.triangles]
    T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2])]
    mesh = Model(kind="mesh", vertices=V, triangles=T, source="turned part mesh")
    prep = prepare(mesh)
    M = np.eye(4)
    M[:3, :3] = Rotation.random(random_state=7).as_matrix()
    M[:3, 3] = [300.0, -600.0, 450.0]
    a = virtual_scan(turned_part(), view=(1.0, 0.3, 0.4), pixel=1.0, noise=0.2, motion=M,
                     effects=ScanEffects(outlier_fraction=0.05), rng=7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = register(a.scan, prep)
    assert reg.converged, reg.message
    assert len(reg.undetermined) == 1 and reg.undetermined[0].startswith("rotation about axis")
    assert reg.warnings == (), reg.warnings
    axis_scan = np.linalg.inv(a.T_model_scan)[:3, :3] @ [0, 0, 1.0]
    np.testing.assert_allclose(np.abs(reg.R @ axis_scan), [0, 0, 1.0], atol=2e-3)


@pytest.fixture(scope="module")
def keyway_part(tmp_path_factory):
    from shapeverify.cad.examples import turned_part_step
    from shapeverify.cad.load import load_model

    return load_model(turned_part_step(tmp_path_factory.mktemp("keyway") / "k.step",
                                       keyway=True))


def _keyway_view(model, seed):
    """A view of the keyway side from a random sensor pose (the keyway is about 4 % of it)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    view = (1.0, rng.uniform(-0.4, 0.4), rng.uniform(-0.3, 0.5))
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    T[:3, 3] = rng.uniform(-600.0, 600.0, 3)
    return virtual_scan(model, view=view, pixel=0.5, noise=0.05, motion=T,
                        effects=ScanEffects(outlier_fraction=0.03),
                        rng=seed)


def _rotation_error_deg(reg, scan):
    from scipy.spatial.transform import Rotation

    E = reg.T_model_scan @ np.linalg.inv(scan.T_model_scan)
    return float(np.degrees(np.linalg.norm(Rotation.from_matrix(E[:3, :3]).as_rotvec())))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_a_keyway_fixes_the_spin_of_a_turned_part(keyway_part, seed):
    """A turned part with a keyway (6 x 3 x 25 mm): the spins were tried 30 deg apart and judged
    by point-to-point fits, whose sampling noise hid the keyway (a few % of the points); view 0
    ended 131 deg off with the keyway's points dropped as outliers and the spin called free."""
    prep = prepare(keyway_part)
    a = _keyway_view(keyway_part, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = register(a.scan, prep)
    assert _rotation_error_deg(reg, a) < 0.5, reg.message
    assert reg.converged and reg.undetermined == (), reg.undetermined


@pytest.mark.slow
def test_a_keyway_mesh_does_not_call_the_spin_free(keyway_part):
    """A mesh of the part with the keyway: its spin is fixed by the keyway, not free (the rule
    for a mesh's facets of a solid of revolution had called it undetermined, and one view
    ended 4.3 deg off, converged, without a warning).  Each pose is right or flagged."""
    from shapeverify.cad.tessellate import tessellate_model
    from shapeverify.registration._model_arrays import spin_direction

    tess = tessellate_model(keyway_part, max_edge=2.0)
    V, inv = np.unique(np.round(tess.vertices, 6), axis=0, return_inverse=True)
    T = inv.reshape(-1)[tess.triangles]
    T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2])]
    prep = prepare(Model(kind="mesh", vertices=V, triangles=T, source="keyway mesh"))
    mp = _irls.model_points(prep)
    assert spin_direction(mp, np.zeros(3), 60.0) is None
    for seed in range(4):
        a = _keyway_view(keyway_part, seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reg = register(a.scan, prep)
        assert not any(u.startswith("rotation about axis") for u in reg.undetermined)
        right = _rotation_error_deg(reg, a) < 0.5
        assert right or not reg.converged or reg.warnings, (seed, _rotation_error_deg(reg, a))
