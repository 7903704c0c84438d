"""Datums from datum targets and patterns (:mod:`shapeverify.characteristics.datum_targets`,
the 'targets' and 'pattern' kinds of :mod:`shapeverify.characteristics.drf`), each against an
independent computation: a regression of z on (x, y), the rigid motion a perfect part was
moved by, scipy's least squares over the free motions."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from shapeverify.characteristics.datum_targets import line_contact, point_contact
from shapeverify.characteristics.drf import DatumFeature, fit_drf, rigid_exp


def _patch(rng, c, n, r=2.0, k=40, noise=0.0, tilt=(0.0, 0.0), off=0.0):
    """k points in a disc of radius r about c on the plane with normal n, tilted by slopes
    ``tilt`` along the disc's two tangents and moved ``off`` along n."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    a = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    u = rng.uniform(-r, r, (k, 2))
    u = u[np.hypot(u[:, 0], u[:, 1]) <= r]
    h = off + tilt[0] * u[:, 0] + tilt[1] * u[:, 1] + rng.normal(0, noise, len(u))
    return np.asarray(c) + u[:, :1] * a + u[:, 1:] * b + h[:, None] * n


def test_point_target_contact_is_the_neighbourhood_plane_on_the_target_normal():
    """Against a regression z = a x + b y + c of the same noisy points, cut at (x0, y0)."""
    rng = np.random.default_rng(1)
    p0 = np.array([3.0, -2.0, 5.0])
    X = _patch(rng, p0, [0, 0, 1], k=200, noise=0.01, tilt=(0.03, -0.02), off=0.07)
    a, b, c = np.linalg.lstsq(np.column_stack([X[:, 0], X[:, 1], np.ones(len(X))]), X[:, 2],
                              rcond=None)[0]
    s_ref = a * p0[0] + b * p0[1] + c - p0[2]
    # the orthogonal least-squares plane differs from the z-regression by O(noise^2 slope)
    assert point_contact(X, p0, [0, 0, 1]) == pytest.approx(s_ref, abs=2e-4)
    # exact points: exact answer (the tilt does not move the point under p0)
    Y = _patch(rng, p0, [0, 0, 1], k=50, tilt=(0.1, 0.05), off=-0.3)
    assert point_contact(Y, p0, [0, 0, 1]) == pytest.approx(-0.3, abs=1e-12)


def test_point_target_leaves_out_points_behind_a_thin_wall():
    """Points of the other side of a 2.7 mm wall (their own face missing from the model, so
    their closest CAD point is on the target's face) do not move the contact."""
    rng = np.random.default_rng(11)
    p0 = np.array([0.0, 0.0, 0.0])
    X = _patch(rng, p0, [0, 0, 1], k=40, off=0.05)
    back = _patch(rng, p0, [0, 0, 1], k=12, off=-2.7)
    assert point_contact(np.vstack([X, back]), p0, [0, 0, 1]) == pytest.approx(0.05, abs=1e-12)


def test_point_target_without_enough_points_names_the_target():
    with pytest.raises(ValueError, match=r"2 scan points near the datum target at \[1.0"):
        point_contact(np.zeros((2, 3)), [1.0, 2.0, 3.0], [0, 0, 1])


def test_line_target_contacts_are_the_deviation_line_at_its_ends():
    """Surface z = 0.2 + 0.01 t along a line of length 40: contacts 0.2 -/+ 0.2 exactly."""
    rng = np.random.default_rng(2)
    t = rng.uniform(-20, 20, 300)
    w = rng.uniform(-0.5, 0.5, 300)
    X = np.column_stack([t, w, 0.2 + 0.01 * t])
    s1, s2 = line_contact(X, [0, 0, 0], [1, 0, 0], [0, 0, 1], 40.0)
    assert (s1, s2) == (pytest.approx(0.0, abs=1e-12), pytest.approx(0.4, abs=1e-12))


def _box_targets(M, rng):
    """A 3-2-1 set of point targets on the box [0,100]x[0,60]x[0,40] (A: z=0, B: y=0,
    C: x=0), the box moved by the rigid motion M: (A, B, C) DatumFeatures."""
    specs = {"A": ([[20, 10, 0], [80, 10, 0], [50, 50, 0]], [0, 0, -1]),
             "B": ([[20, 0, 20], [80, 0, 20]], [0, -1, 0]),
             "C": ([[0, 30, 20]], [-1, 0, 0])}
    out = []
    for name, (pts, n) in specs.items():
        X, contacts = [], []
        for p in pts:
            P = _patch(rng, p, n, k=60)
            P = P @ M[:3, :3].T + M[:3, 3]
            contacts.append(("point", np.array(p, float), np.array(n, float),
                             np.arange(sum(map(len, X)), sum(map(len, X)) + len(P)), None, 0.0))
            X.append(P)
        out.append(DatumFeature(name, "targets", np.mean(pts, axis=0), np.array(n, float),
                                np.concatenate(X), contacts=tuple(contacts)))
    return out


def test_321_point_targets_undo_the_rigid_motion_of_a_perfect_part():
    rng = np.random.default_rng(3)
    M = rigid_exp([0.01, -0.02, 0.015, 0.4, -0.3, 0.25])
    drf = fit_drf(_box_targets(M, rng), size=100.0)
    assert drf.free == []
    np.testing.assert_allclose(drf.T @ M, np.eye(4), atol=1e-9)


def test_four_point_secondary_is_least_squares_in_its_free_directions():
    """A: 3 points (exact); B: 4 points on y=0 with two of them 0.1 mm proud: B removes ty and
    rz as the least squares of its 4 contacts; against scipy over (ty, rz).  (Noisy pads:
    B's rows keep to ty and rz, so C still fixes tx.)"""
    rng = np.random.default_rng(4)
    Bp = np.array([[10, 0, 20], [40, 0, 20], [70, 0, 20], [90, 0, 20]], float)
    bumps = np.array([0.1, 0.0, 0.1, -0.05])        # along -y (outward)
    A = _box_targets(np.eye(4), rng)[0]
    X, contacts = [], []
    for p, h in zip(Bp, bumps):
        P = _patch(rng, p, [0, -1, 0], k=60, off=h)
        contacts.append(("point", p, np.array([0, -1.0, 0]),
                         np.arange(sum(map(len, X)), sum(map(len, X)) + len(P)), None, 0.0))
        X.append(P)
    B = DatumFeature("B", "targets", Bp.mean(axis=0), np.array([0, -1.0, 0]),
                     np.concatenate(X), contacts=tuple(contacts))
    drf = fit_drf([A, B], size=100.0)

    def resid(v):
        """y of each moved pad (rz about z, then ty) under its simulator, which stays at its
        basic x: y = 0 wanted."""
        T = rigid_exp([0, 0, v[0], 0, v[1], 0])
        a = np.column_stack([Bp[:, 0], -bumps, Bp[:, 2]]) @ T[:3, :3].T + T[:3, 3]
        return a[:, 1] + (Bp[:, 0] - a[:, 0]) * np.tan(v[0])

    ref = least_squares(resid, [0.0, 0.0], xtol=1e-15, ftol=1e-15).x
    got = drf.T
    # the DRF's rows move each contact along its CAD normal (first order in the 1.2 mrad
    # turn: 4e-9 rad, 4e-7 mm over the 90 mm pad spread)
    assert np.arctan2(got[1, 0], got[0, 0]) == pytest.approx(ref[0], abs=1e-8)
    # the translation at the origin along y
    assert got[1, 3] == pytest.approx(ref[1], abs=1e-6)


def _hole(rng, c, r=3.0, h=10.0, k=400, shift=(0.0, 0.0)):
    th = rng.uniform(0, 2 * np.pi, k)
    z = rng.uniform(0, h, k)
    return np.column_stack([c[0] + shift[0] + r * np.cos(th), c[1] + shift[1] + r * np.sin(th),
                            c[2] + z])


def _pattern(rng, centres, shifts, M=np.eye(4)):
    X, groups = [], []
    for c, s in zip(centres, shifts):
        P = _hole(rng, c, shift=s) @ M[:3, :3].T + M[:3, 3]
        groups.append((np.array(c, float), np.array([0, 0, 1.0]),
                       np.arange(sum(map(len, X)), sum(map(len, X)) + len(P)), True))
        X.append(P)
    return DatumFeature("F", "pattern", np.mean(centres, axis=0), np.array([0, 0, 1.0]),
                        np.concatenate(X), groups=tuple(groups))


def test_pattern_datum_of_four_holes_undoes_a_rigid_motion():
    rng = np.random.default_rng(5)
    centres = [[0, 0, 0], [50, 0, 0], [50, 30, 0], [0, 30, 0]]
    M = rigid_exp([0.004, -0.003, 0.01, 0.3, -0.2, 0.1])
    drf = fit_drf([_pattern(rng, centres, [(0, 0)] * 4, M)], size=60.0)
    assert len(drf.free) == 1 and drf.free[0].startswith("translation along (+0.000, +0.000")
    # all but the free translation along z
    D = drf.T @ M
    np.testing.assert_allclose(D[:3, :3], np.eye(3), atol=1e-9)
    np.testing.assert_allclose(D[:2, 3], 0.0, atol=1e-9)


def test_pattern_datum_with_one_hole_off_is_the_least_squares_pattern():
    """Hole 2 of 4 is 0.2 mm off: the pattern's in-plane placement (rz, tx, ty) is the least
    squares of the 4 axes' distances from their true positions (scipy)."""
    rng = np.random.default_rng(6)
    centres = np.array([[0, 0, 0], [50, 0, 0], [50, 30, 0], [0, 30, 0]], float)
    shifts = [(0, 0), (0.2, 0.0), (0, 0), (0, 0)]
    drf = fit_drf([_pattern(rng, centres, shifts)], size=60.0)

    measured = centres[:, :2] + np.array(shifts)

    def resid(v):
        c, s = np.cos(v[0]), np.sin(v[0])
        q = measured @ np.array([[c, -s], [s, c]]).T + v[1:]
        return (q - centres[:, :2]).ravel()

    ref = least_squares(resid, [0.0, 0.0, 0.0], xtol=1e-15, ftol=1e-15).x
    T = drf.T
    assert np.arctan2(T[1, 0], T[0, 0]) == pytest.approx(ref[0], abs=2e-6)
    np.testing.assert_allclose(T[:2, 3], ref[1:], atol=2e-5)


def test_noisy_pads_on_opposite_faces_leave_the_last_direction_to_the_tertiary():
    """CTC 02's set-up: A 3 points on z, B 4 points on the two opposite x faces of a width, C 1
    point on y, every pad with 0.02 mm noise: B fixes x and the turn about z only, C fixes y
    (rows along the CAD normals: the pads' noisy normals must not give B a say in y)."""
    rng = np.random.default_rng(12)
    M = rigid_exp([0.002, -0.001, 0.003, 0.3, 0.2, -0.1])
    pads = {"A": [([20, 10, 0], [0, 0, -1]), ([80, 10, 0], [0, 0, -1]), ([50, 50, 0], [0, 0, -1])],
            "B": [([0, 10, 20], [-1, 0, 0]), ([0, 50, 20], [-1, 0, 0]),
                  ([100, 10, 20], [1, 0, 0]), ([100, 50, 20], [1, 0, 0])],
            "C": [([50, 0, 20], [0, -1, 0])]}
    feats = []
    for name, pts in pads.items():
        X, contacts = [], []
        for p, n in pts:
            P = _patch(rng, p, n, r=2.5, k=30, noise=0.02) @ M[:3, :3].T + M[:3, 3]
            contacts.append(("point", np.array(p, float), np.array(n, float),
                             np.arange(sum(map(len, X)), sum(map(len, X)) + len(P)), None, 0.0))
            X.append(P)
        feats.append(DatumFeature(name, "targets", np.mean([p for p, _ in pts], axis=0),
                                  np.array(pts[0][1], float), np.concatenate(X),
                                  contacts=tuple(contacts)))
    drf = fit_drf(feats, size=100.0)
    assert drf.free == []
    D = drf.T @ M                      # the identity up to the pads' noise
    np.testing.assert_allclose(D[:3, :3], np.eye(3), atol=2e-3)
    assert np.abs(D[:3, 3]).max() < 0.05
    # C alone decides y: its contact sits on its nominal place
    c = drf.apply(feats[2].points)
    assert abs(np.median(c[:, 1])) < 0.03
