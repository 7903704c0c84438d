"""The scan's noise, compiled and measured once (issue 32 item 7).

``registration._noise.scan_noise`` was 85 % of an inspection's CPU (0.61 of 0.71 s on the
30,000-point bench scan), run twice per inspection.  Pinned here:

* the compiled version (``registration._noise_kernels``) equals the vectorised numpy version it
  replaced (kept verbatim in ``scan_noise_reference.py``) to 1e-9 relative on scans of every
  kind its rules handle: thin walls, two sheets with outliers, a doubled exposure, each point
  twice, noise as coarse as the spacing, a simulated panel scan with outliers, fewer points
  than it measures;
* the registration's estimate is handed to the inspection, which reuses it when it would
  measure the same points (every point evaluated), and measures its own otherwise.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import independent_scans as ind
import shapeverify as sv
from scan_noise_reference import reference_scan_noise
from shapeverify.registration import _noise
from shapeverify.registration._noise import NoiseEstimate, noise_of, scan_noise

_R = Rotation.from_rotvec([0.4, -0.3, 0.2]).as_matrix()


def _sheets(gap, seed, outliers=0.0, noise=0.02, size=50.0):
    rng = np.random.default_rng(seed)
    n = int(size * size)
    P = np.vstack([np.c_[rng.uniform(0, size, (n, 2)), z + rng.normal(0, noise, n)]
                   for z in (0.0, gap)])
    k = int(outliers * len(P))
    if k:
        P = np.vstack([P, P[rng.choice(len(P), k)] + rng.normal(0.0, 1.0, (k, 3))])
    return P[rng.permutation(len(P))] @ _R.T


def _twice(seed):
    one = _sheets(1000.0, seed)
    rng = np.random.default_rng(seed)
    return np.vstack([one, one])[rng.permutation(2 * len(one))]


def _plate(seed):
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox

    rng = np.random.default_rng(seed)
    V, T, _ = ind.tessellate(BRepPrimAPI_MakeBox(50.0, 30.0, 1.2).Shape(), 0.002)
    P, N = ind.random_points(V, T, 1.0, rng)
    return (P + rng.normal(0.0, 0.02, len(P))[:, None] * N) @ _R.T + 5.0


def _panel_scan(seed):
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.simulate import ScanEffects, virtual_scan

    prep = sv.prepare(wavy_panel(), spacing=2.0)
    return virtual_scan(prep, pixel=1.0, noise=0.02, motion=(2.0, 3.0), rng=seed,
                        effects=ScanEffects(outlier_fraction=0.03)).scan


SCANS = {
    "two sheets 0.6 mm apart": lambda: _sheets(0.6, 1),
    "two sheets 1.5 mm apart, 3 % outliers": lambda: _sheets(1.5, 2, outliers=0.03),
    "a doubled exposure 0.02 mm apart": lambda: _sheets(0.02, 3),
    "each point twice": lambda: _twice(4),
    "noise as coarse as the spacing": lambda: _sheets(1000.0, 5, noise=1.0),
    "a 1.2 mm plate, both sides": lambda: _plate(6),
    "a simulated panel scan with outliers": lambda: _panel_scan(7),
    "300 points (every one a centre)": lambda: _sheets(1000.0, 8)[:300],
}


@pytest.mark.parametrize("name", list(SCANS))
def test_compiled_scan_noise_equals_the_numpy_version_it_replaced(name):
    P = SCANS[name]()
    new, ref = scan_noise(P), reference_scan_noise(P)
    assert np.isfinite(ref) and ref > 0
    assert new == pytest.approx(ref, rel=1e-9, abs=0.0)


def test_compiled_scan_noise_is_nan_where_the_numpy_version_was():
    """Too few points (K + 1 needed), and too few well-fixed quadrics (points on a line)."""
    rng = np.random.default_rng(9)
    assert np.isnan(scan_noise(rng.normal(size=(_noise.K, 3))))
    line = np.c_[np.linspace(0, 100, 400), np.zeros(400), rng.normal(0, 0.02, 400)]
    assert np.isnan(reference_scan_noise(line))
    assert np.isnan(scan_noise(line))


def test_on_an_ill_conditioned_raster_both_versions_agree_to_their_own_round_off():
    """A raster whose rows lie 10 x farther apart than its points: the quadrics about most
    points rest on two rows (condition numbers 1e10-1e13), so the numpy version itself moves
    by ~0.3 % when the coordinates change by 1e-15 relative; the compiled one (other LAPACK,
    other summation order) lies within that."""
    rng = np.random.default_rng(6)
    gx, gy = np.meshgrid(np.arange(0, 60, 0.3), np.arange(0, 60, 3.0))
    P = np.c_[gx.ravel(), gy.ravel(), rng.normal(0, 0.02, gx.size)] @ _R.T
    refs = [reference_scan_noise(P * (1.0 + e)) for e in (0.0, 1e-15, -1e-15)]
    spread = (max(refs) - min(refs)) / refs[0]
    assert spread > 1e-3                              # the case is round-off sensitive
    assert scan_noise(P) == pytest.approx(refs[0], rel=3 * spread)
    assert scan_noise(P) == pytest.approx(0.02, rel=0.15)


@pytest.mark.parametrize("name", ["two sheets 1.5 mm apart, 3 % outliers",
                                  "a 1.2 mm plate, both sides"])
def test_scan_noise_does_not_change_when_the_scan_moves_rigidly(name):
    """What lets the inspection reuse the registration's estimate on the registered points."""
    P = SCANS[name]()
    T = Rotation.from_rotvec([0.02, -0.01, 0.03]).as_matrix()
    assert scan_noise(P @ T.T + [3.0, -2.0, 1.0]) == pytest.approx(scan_noise(P), rel=1e-12)


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    """A closed box (no free edges: every point of a clean scan is evaluated) and a scan of
    it, sampled by area with 0.02 mm of noise, a little off its pose."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox

    from shapeverify.cad.examples import _write_step
    from shapeverify.cad.load import load_model

    shape = BRepPrimAPI_MakeBox(60.0, 40.0, 20.0).Shape()
    path = _write_step(shape, tmp_path_factory.mktemp("box") / "box.step", "box")
    prep = sv.prepare(load_model(path), spacing=2.0)
    rng = np.random.default_rng(1)
    V, T, _ = ind.tessellate(shape, 0.002)
    P, N = ind.random_points(V, T, 1.5, rng)
    P = P + rng.normal(0.0, 0.02, len(P))[:, None] * N
    R = Rotation.from_rotvec([0.01, -0.02, 0.015]).as_matrix()
    return prep, P @ R.T + [0.5, -0.3, 0.2]


def _counting(monkeypatch):
    calls = []
    real = _noise.scan_noise

    def counted(P):
        calls.append(len(P))
        return real(P)

    monkeypatch.setattr(_noise, "scan_noise", counted)
    return calls


def test_inspection_reuses_the_registrations_noise_when_every_point_is_evaluated(box,
                                                                                  monkeypatch):
    prep, scan = box
    calls = _counting(monkeypatch)
    res = sv.inspect(prep, scan, tolerance=0.2)
    ev = res.deviations.evaluated
    assert ev.all() and str(res.verdict) == "pass"
    assert calls == [len(scan)]                       # measured once, by the registration
    est = res.registration.noise
    assert isinstance(est, NoiseEstimate) and (est.n, est.step) == (len(scan), 1)
    assert res.noise == est.sigma
    # what the inspection measured before: its evaluated points, in the model's frame
    assert res.noise == pytest.approx(reference_scan_noise(res.deviations.points_model[ev]),
                                      rel=1e-12)


def test_inspection_measures_the_noise_itself_without_the_registrations(box, monkeypatch):
    """A registration rebuilt without it (the service, ``inspect_registered`` with a pose of
    one's own): the inspection measures its evaluated points, to the same value."""
    from types import SimpleNamespace

    from shapeverify.inspection import inspect_registered

    prep, scan = box
    res = sv.inspect(prep, scan, tolerance=0.2)
    reg = res.registration
    plain = SimpleNamespace(T_model_scan=reg.T_model_scan, rms=reg.rms,
                            iterations=reg.iterations, converged=reg.converged,
                            inlier_fraction=reg.inlier_fraction)
    calls = _counting(monkeypatch)
    again = inspect_registered(prep, scan, plain, tolerance=0.2)
    assert calls == [len(scan)]
    assert again.noise == pytest.approx(res.noise, rel=1e-12)
    assert str(again.verdict) == str(res.verdict)


def test_inspection_measures_its_evaluated_points_when_some_are_not_evaluated(monkeypatch):
    """A panel scan with outliers: the evaluated points are not the registered ones, so the
    inspection measures them (the value it always had), the registration its own."""
    scan = SCANS["a simulated panel scan with outliers"]()
    from shapeverify.cad.examples import wavy_panel

    prep = sv.prepare(wavy_panel(), spacing=2.0)
    calls = _counting(monkeypatch)
    res = sv.inspect(prep, scan, tolerance=0.2)
    ev = res.deviations.evaluated
    assert not ev.all() and len(calls) == 2
    assert res.noise == pytest.approx(reference_scan_noise(res.deviations.points_model[ev]),
                                      rel=1e-9)
    assert res.registration.noise.sigma == pytest.approx(reference_scan_noise(scan), rel=1e-9)


def test_noise_of_subsamples_as_the_registration_did():
    P = _sheets(1000.0, 10, size=40.0)
    est = noise_of(P, 1000)
    assert (est.n, est.step) == (len(P), len(P) // 1000)
    assert est.sigma == scan_noise(P[::len(P) // 1000])
    assert est.reusable_for(len(P), 1000) and not est.reusable_for(len(P), 100)
    assert not est.reusable_for(len(P) - 1, 1000)
