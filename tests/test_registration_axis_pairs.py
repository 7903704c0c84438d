"""Axis-pair hypotheses of the global search for a near-axisymmetric part:
:mod:`shapeverify.registration._axis_pairs`.

An impeller seen in a sensor's frame ended 5-25 deg off on 6 of 8 views (benchmarks/
bench_global.py): its FPFH triples did not hold the true pose and the turned-part hypotheses
do not apply.  With the scan's axis direction on the model's, one point pair fixes the pose."""
import numpy as np
import pytest

from shapeverify.registration import _axis_pairs, _restart
from shapeverify.registration.global_search import _model_side, global_alignment
from shapeverify.registration.rigid import make_transform, rodrigues


def test_spins_are_rotations_about_the_axis_by_the_angles():
    axis = np.array([0.0, 0.6, 0.8])
    R = _axis_pairs._spins(axis, np.radians([0.0, 30.0, -120.0]))
    for Rk, deg in zip(R, (0.0, 30.0, -120.0)):
        np.testing.assert_allclose(Rk, rodrigues(axis * np.radians(deg)), atol=1e-12)


def test_a_true_point_pair_gives_the_true_pose():
    """A scan point and its own model point, with the scan's axis direction right, give the
    true pose exactly (the spin from the normals' parts across the axis)."""
    T_true = make_transform(rodrigues(np.array([0.4, -0.9, 0.3])), np.array([10.0, -4.0, 7.0]))
    am = np.array([0.0, 0.0, 1.0])
    M = np.array([[30.0, 0.0, 5.0], [0.0, 25.0, 2.0]])
    Nm = np.array([[0.8, 0.0, 0.6], [0.0, 1.0, 0.0]])
    Ti = np.linalg.inv(T_true)
    X = M @ Ti[:3, :3].T + Ti[:3, 3]           # the model points in the scan's frame
    Nx = Nm @ Ti[:3, :3].T
    side = type("Side", (), {})()
    side.points, side.normals, side.features = M, Nm, np.zeros((50, 33))
    side.ftree = type("FT", (), {"query": lambda self, F, k: (None, np.tile([[0], [1]], (1, k)))})()
    a = Ti[:3, :3] @ am                        # the scan's axis direction
    poses = _axis_pairs._pair_poses(X, Nx, np.zeros((2, 33)), side, a, am)
    right = [T for T in poses if np.abs(T - T_true).max() < 1e-9]
    # each point paired with itself (MATCHES times) the right way up; upside down only the
    # point whose normal is across the axis passes the angle test, and its pose is wrong
    assert len(right) == 2 * _axis_pairs.MATCHES
    assert len(poses) == 3 * _axis_pairs.MATCHES


@pytest.fixture(scope="module")
def impeller(shared_data):
    from model_cache import cached_prepared

    # (imported and prepared once per suite run: tests/model_cache.py)
    return cached_prepared(shared_data / "cad" / "impeller.igs", spacing=1.0)


@pytest.mark.slow
def test_oblique_impeller_view_in_a_sensor_frame_lands_on_a_blade_copy(impeller):
    """bench_global's impeller view 2 (a third of the part, in a sensor frame 120 deg / 300 mm
    away) ended 5 deg / 20 mm off before, 12 deg after the registration."""
    from shapeverify.simulate import virtual_scan

    vs = virtual_scan(impeller.model, view=np.array([0.658, 0.067, 0.750]), pixel=0.3,
                      noise=0.02, motion=(120.0, 300.0), rng=1)
    ga = global_alignment(vs.scan, impeller)
    axis, centre = _restart._model_axis(impeller)
    errs = []
    for k in range(11):       # the blade copies: any one is right for the search
        S = _restart._spin(axis, centre, 2 * np.pi * k / 11)
        acc = vs.accuracy(np.linalg.inv(S) @ ga.T_model_scan)
        errs.append((acc.rotation_deg, acc.translation))
    rot, tr = min(errs, key=sum)
    assert rot < 3.0 and tr < 3.0, (ga, errs)
    assert ga.source == "axis-pairs"
    assert _model_side(impeller) is not None
