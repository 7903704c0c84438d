"""Restarts about the model's near-symmetry axis (issue 14 item 6, the impeller from 6 deg / 12 mm
starts): :mod:`shapeverify.registration._restart`.

The impeller's hub leaves x, y and the spin to 5 % of the scan on the blade sides at the rim;
from a start half a blade pitch off, every local method converges 16-18 deg / 14 mm off (a
flagged wrong minimum).  The restart spins about the model's own near-symmetry axis, takes the
copy nearest the start and must land on the truth; easy starts must not run it at all."""
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.registration import RegistrationOptions, _restart, register
from shapeverify.registration.rigid import make_transform, rodrigues


def _side(points):
    return SimpleNamespace(axes_points=np.asarray(points, float))


def test_symmetry_axis_of_a_wheel_is_its_axis_and_a_box_has_none():
    rng = np.random.default_rng(0)
    # a wheel: a disc of radius 40 mm with 11 radial blades, tilted and moved
    r = 40.0 * np.sqrt(rng.random(4000))
    phi = 2 * np.pi * rng.random(4000)
    disc = np.c_[r * np.cos(phi), r * np.sin(phi), np.zeros(4000)]
    blades = []
    for k in range(11):
        a = 2 * np.pi * k / 11
        s, h = 30 + 10 * rng.random(200), 6 * rng.random(200)
        blades.append(np.c_[s * np.cos(a), s * np.sin(a), h])
    wheel = np.vstack([disc, *blades])
    R = rodrigues(np.array([0.3, -0.2, 0.5]))
    moved = wheel @ R.T + np.array([5.0, -3.0, 12.0])
    axis, centre = _restart.symmetry_axis(_side(moved))
    assert abs(abs(axis @ R[:, 2]) - 1.0) < 1e-3          # the wheel's axis, either sign
    np.testing.assert_allclose(centre, moved.mean(axis=0))
    # a box 100 x 60 x 20 mm: three distinct moments, no axis
    box = rng.random((4000, 3)) * np.array([100.0, 60.0, 20.0])
    assert _restart.symmetry_axis(_side(box)) is None
    # a long shaft (two equal small moments): the long axis
    shaft = np.c_[200 * rng.random(4000), 10 * np.cos(phi), 10 * np.sin(phi)]
    axis, _ = _restart.symmetry_axis(_side(shaft))
    assert abs(abs(axis[0]) - 1.0) < 1e-3


def test_spin_about_the_axis_keeps_the_centre_and_turns_by_the_angle():
    axis, centre = np.array([0.0, 0.6, 0.8]), np.array([1.0, 2.0, 3.0])
    T = _restart._spin(axis, centre, np.radians(40.0))
    np.testing.assert_allclose(T[:3, :3] @ centre + T[:3, 3], centre, atol=1e-12)
    np.testing.assert_allclose(T[:3, :3] @ axis, axis, atol=1e-12)
    assert np.degrees(np.arccos((np.trace(T[:3, :3]) - 1) / 2)) == pytest.approx(40.0)


@pytest.fixture(scope="module")
def impeller(shared_data):
    from model_cache import cached_prepared

    # a coarse preparation (1 mm, ~29k model points, 2 s) keeps the test short; the lock
    # from 6 deg / 12 mm is the same as at the default 0.25 mm
    # (imported and prepared once per suite run: tests/model_cache.py)
    return cached_prepared(shared_data / "cad" / "impeller.igs", spacing=1.0)


def _register(scan, prep, restart, monkeypatch, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return register(scan, prep, options=RegistrationOptions(restart=restart), **kw)


@pytest.mark.slow
def test_impeller_from_half_a_blade_pitch_off_registers_right(impeller, monkeypatch):
    from shapeverify.simulate import virtual_scan

    prep = impeller
    vs = virtual_scan(prep.model, pixel=0.5, noise=0.02, motion=(6.0, 12.0), rng=101)
    plain = _register(vs.scan, prep, False, monkeypatch)
    reg = _register(vs.scan, prep, True, monkeypatch)
    again = _register(vs.scan, prep, True, monkeypatch)
    # the mechanism is real: without the restart this start ends in a flagged wrong minimum
    a0 = vs.accuracy(plain.T_model_scan)
    assert a0.rotation_deg > 5.0 and a0.translation > 5.0, a0
    assert plain.warnings or not plain.converged
    acc = vs.accuracy(reg.T_model_scan)
    assert acc.rotation_deg < 0.05 and acc.translation < 0.05, (acc, reg)
    assert reg.converged and not reg.warnings, (reg.message, reg.warnings)
    assert np.array_equal(again.T_model_scan, reg.T_model_scan)
    # an easy start is not flagged: the restart does not run, the answer is bit-identical
    easy = virtual_scan(prep.model, pixel=0.5, noise=0.02, motion=(2.0, 2.0), rng=103)
    on = _register(easy.scan, prep, True, monkeypatch)
    off = _register(easy.scan, prep, False, monkeypatch)
    assert np.array_equal(on.T_model_scan, off.T_model_scan)
    assert easy.accuracy(on.T_model_scan).rotation_deg < 0.05


def test_restart_needs_a_near_symmetric_model(monkeypatch):
    """A model with three distinct principal moments gets no restart (None), decided from its
    points before the global search's (costly) model side is built."""
    import shapeverify.registration.global_search as gs

    rng = np.random.default_rng(1)
    box = rng.random((3000, 3)) * np.array([100.0, 60.0, 20.0])
    up = np.tile([0.0, 0.0, 1.0], (3000, 1))
    prep = SimpleNamespace(points=SimpleNamespace(points=box, normals=up))

    def built(prep):
        raise AssertionError("the model side must not be built for a model with no axis")

    monkeypatch.setattr(gs, "_model_side", built)
    T = make_transform(np.eye(3), np.zeros(3))
    assert _restart.restart(box[:100], prep, T, T, 30.0, np.random.default_rng(0)) is None
    # the same points as a wheel-like cloud (x, y moments equal) do have an axis
    phi = 2 * np.pi * rng.random(3000)
    r = 40.0 * np.sqrt(rng.random(3000))
    wheel = SimpleNamespace(points=SimpleNamespace(points=np.c_[r * np.cos(phi), r * np.sin(phi),
                                                                 2.0 * rng.random(3000)],
                                                   normals=up))
    axis, _ = _restart._model_axis(wheel)
    assert abs(abs(axis[2]) - 1.0) < 1e-3


@pytest.mark.slow
def test_unflagged_global_pose_31_deg_off_about_the_axis_is_spun_back(impeller):
    """The global search's end on an impeller seen by an oblique camera (Open3D's renderer,
    benchmarks/check_independent_scans.py) was 31 deg off about the axis, at 16 x the noise,
    converged and unflagged: the in-place spins of its end find the copy that fits."""
    from shapeverify.simulate import virtual_scan

    prep = impeller
    vs = virtual_scan(prep.model, view=np.array([0.6, 0.26, -0.76]), pixel=0.5, noise=0.02,
                      rng=7)
    T_true = vs.T_model_scan
    axis, centre = _restart._model_axis(prep)
    T_end = _restart._spin(axis, centre, np.radians(31.0)) @ T_true
    rng = np.random.default_rng(0)
    radius = float(np.sqrt(np.mean(np.sum((vs.scan - vs.scan.mean(axis=0)) ** 2, axis=1))))
    T = _restart.restart(vs.scan, prep, T_true, T_end, radius, rng, in_place=True)
    acc = vs.accuracy(T)
    assert acc.rotation_deg < 2.0 and acc.translation < 1.0, acc   # the short refinement's
    plain = vs.accuracy(T_end)
    assert plain.rotation_deg > 30.0


def test_scan_noise_is_the_sensor_noise_on_curved_surfaces():
    from shapeverify.registration._noise import scan_noise

    rng = np.random.default_rng(3)
    x, y = rng.uniform(-20, 20, (2, 30000))
    # (gentle slopes: the noise is along z, the estimate along the normals)
    for sigma, curv in ((0.005, 0.0), (0.02, 0.005), (0.05, 0.01)):
        P = np.c_[x, y, curv * (x ** 2 - 0.5 * y ** 2) + rng.normal(0, sigma, x.size)]
        R = rodrigues(np.array([0.4, -0.3, 0.2]))
        assert scan_noise(P @ R.T + 7.0) == pytest.approx(sigma, rel=0.15)
    assert np.isnan(scan_noise(P[:10]))


@pytest.mark.slow
def test_wrong_minimum_far_above_the_scan_noise_is_warned(impeller, monkeypatch):
    """An impeller seen from above in the sensor's frame: the global search ended 105 deg off
    at 43 x the scan's noise (0.86 mm: under the fit-distance bar of 2 mm), converged, with no
    warning (2026-12-05).  Whatever pose it finds, a residual scale far above the scan's own
    noise is never silent."""
    from shapeverify.registration._noise import scan_noise
    from shapeverify.simulate import virtual_scan

    prep = impeller
    vs = virtual_scan(prep.model, view=np.array([0.18881712, -0.19839033, 0.96176368]),
                      pixel=0.3, noise=0.02, motion=(120.0, 300.0), rng=1)
    reg = _register(vs.scan, prep, True, monkeypatch, init="global")
    noise = scan_noise(vs.scan)
    assert 0.01 < noise < 0.03
    if reg.scale > 5 * noise:
        assert any("scan's own noise" in w for w in reg.warnings), reg.warnings
    else:
        assert vs.accuracy(reg.T_model_scan).translation < 0.1 or reg.warnings
