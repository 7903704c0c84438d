"""A partial cylinder (a radius) as a datum feature: FTC 10's datum K is a boss face of 166
degrees; the DRF refused it ("the scan covers 166 degrees of its circumference (its axis needs
240)"), so GT25 and GT29 (H|K|L) were never measured.  Its simulator is now the cylinder of
the basic radius placed by least squares (ASME Y14.5 datum feature simulator of basic size),
its direction fixed by the primary plane; checked against scipy's least squares."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from shapeverify.characteristics.drf import DatumFeature, fit_drf

C0 = np.array([52.0, 0.0, 23.5])
R0 = 7.5


def _plane(rng, n=400, noise=0.005):
    xz = rng.uniform([30, 0], [70, 40], (n, 2))
    return np.column_stack([xz[:, 0], rng.normal(0, noise, n), xz[:, 1]])


def _arc(rng, span_deg, centre_off, n=300, noise=0.005):
    t = np.radians(rng.uniform(-0.5 * span_deg, 0.5 * span_deg, n))
    y = rng.uniform(2.0, 10.0, n)
    r = R0 + rng.normal(0, noise, n)
    c = C0 + centre_off
    return np.column_stack([c[0] + r * np.cos(t), y, c[2] + r * np.sin(t)])


def _datums(P, X, arc_deg):
    A = DatumFeature("H", "plane", np.array([50.0, 0.0, 20.0]), np.array([0.0, -1.0, 0.0]), P)
    K = DatumFeature("K", "axis", C0, np.array([0.0, 1.0, 0.0]), X, hole=False,
                     arc=arc_deg, radius=R0)
    return A, K


def test_partial_cylinder_datum_is_placed_by_its_basic_radius_as_scipy_finds_it():
    rng = np.random.default_rng(3)
    off = np.array([0.12, 0.0, -0.07])
    X = _arc(rng, 166.0, off)
    # a perfect plane H: the frame's correction is then the arc's centre alone
    drf = fit_drf(_datums(_plane(rng, noise=0.0), X, 166.0), size=100.0)
    k = drf.datums[1]
    assert "basic radius 7.5" in k.fit
    # scipy: the centre (x, z) of the circle of radius R0 nearest the points in least squares
    ref = least_squares(lambda c: np.hypot(X[:, 0] - c[0], X[:, 2] - c[1]) - R0,
                        x0=[C0[0], C0[2]], xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    # the DRF moves the fitted axis onto the nominal one: the offset it corrects is the centre
    back = drf.apply(np.array([[ref[0], 5.0, ref[1]]]))[0]
    assert back[[0, 2]] == pytest.approx(C0[[0, 2]], abs=1e-6)
    assert ref == pytest.approx(C0[[0, 2]] + off[[0, 2]], abs=0.005)


def test_partial_cylinder_datum_needs_most_of_its_arc_scanned():
    rng = np.random.default_rng(4)
    X = _arc(rng, 60.0, np.zeros(3))
    with pytest.raises(ValueError, match="covers 60 degrees of the 166 its partial cylinder"):
        fit_drf(_datums(_plane(rng), X, 166.0), size=100.0)


def test_partial_cylinder_as_primary_datum_is_refused_with_the_reason():
    rng = np.random.default_rng(5)
    X = _arc(rng, 166.0, np.zeros(3))
    K = DatumFeature("K", "axis", C0, np.array([0.0, 1.0, 0.0]), X, hole=False, arc=166.0,
                     radius=R0)
    with pytest.raises(ValueError, match="direction fixed by a datum before it"):
        fit_drf([K], size=100.0)


def test_full_cylinder_datum_still_needs_240_degrees_scanned():
    rng = np.random.default_rng(6)
    X = _arc(rng, 166.0, np.zeros(3))
    with pytest.raises(ValueError, match="its axis needs 240"):
        fit_drf(_datums(_plane(rng), X, 360.0), size=100.0)
