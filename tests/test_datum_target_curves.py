"""Circular line datum targets (a ring closed on a boss or opened in a hole, NIST FTC 06's
'circular curve' targets G and H) and line targets on the flanks of a groove as a tertiary
centre plane (FTC 06's J and K), against brute force (issue 28):

* the ring's centre (:func:`.datum_targets.circle_contact`) against SLSQP on the exact
  (non-linearised) minimax of the points' radii, each point moved along the drafted surface to
  the ring's plane; for a hole the maximin;
* a DRF D|G (a plane, then a ring on a drafted boss) against the rigid motion a perfect part
  was moved by, and on a part whose boss is off its place, against the brute-force ring centre;
* a DRF D|C|J with J two line targets on the opposite 25-degree flanks of a groove against a
  grid search of the one free translation minimising the squared contacts (the least squares
  of the two lines' ends).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from shapeverify.characteristics.datum_targets import circle_contact
from shapeverify.characteristics.drf import DatumFeature, fit_drf, rigid_exp

SLOPE = 1.0 / 6.0           # FTC 06's drafted bosses: radius 9.525 + (85.09 - y) / 6
DRDH = -SLOPE               # the change of radius with height (+y): what the plan gives
R = 12.7


def _cone_band(rng, c, k=300, slope=SLOPE, band=1.0, noise=0.0, lobes=0.0):
    """k points on a cone about the y axis through c: radius R at c's height, growing by
    ``slope`` per mm downwards (-y), within ``band`` of the ring; radial form error
    ``lobes`` cos(3 phi) and noise."""
    phi = rng.uniform(0, 2 * np.pi, k)
    h = rng.uniform(-band, band, k)
    r = R - slope * h + lobes * np.cos(3 * phi) + rng.normal(0, noise, k)
    return np.asarray(c) + np.column_stack([r * np.cos(phi), h, r * np.sin(phi)])


def _brute_centre(X, c0, slope, hole):
    """The exact minimax (boss) / maximin (hole) centre by SLSQP, in the plane y = c0[1]."""
    q = X - c0
    h = q[:, 1]

    def radii(z):
        return np.hypot(q[:, 0] - z[0], q[:, 2] - z[1]) + slope * h

    sgn = -1.0 if hole else 1.0
    x0 = np.r_[0.0, 0.0, sgn * (radii([0, 0]) * sgn).max()]
    cons = {"type": "ineq", "fun": lambda z: sgn * (z[2] - radii(z[:2])) if not hole
            else radii(z[:2]) - z[2]}
    res = minimize(lambda z: sgn * z[2], x0, constraints=[cons], method="SLSQP",
                   options={"ftol": 1e-12, "maxiter": 500})
    assert res.success, res.message
    return c0 + np.array([res.x[0], 0.0, res.x[1]])


@pytest.mark.parametrize("hole", [False, True])
def test_ring_centre_is_the_exact_minimax_circle_of_the_drafted_band(hole):
    rng = np.random.default_rng(3 + hole)
    c0 = np.array([76.2, 66.04, -158.75])
    off = np.array([0.13, 0.0, -0.07])
    X = _cone_band(rng, c0, noise=0.01, lobes=0.02) + off
    got = circle_contact(X, c0, [0, 1, 0], R, DRDH, hole)
    ref = _brute_centre(X, c0, SLOPE, hole)
    assert got == pytest.approx(ref, abs=1e-6)
    assert got[1] == c0[1]
    # and without the draft correction the answer differs (the slope matters on a cone)
    bad = circle_contact(X, c0, [0, 1, 0], R, 0.0, hole)
    assert np.linalg.norm(bad - ref) > 1e-4


def test_ring_without_enough_of_the_circle_names_the_target():
    rng = np.random.default_rng(5)
    X = _cone_band(rng, [0, 0, 0])
    X = X[X[:, 0] > 0]                     # half the circle
    with pytest.raises(ValueError, match="degrees of the circular datum target"):
        circle_contact(X, [0, 0, 0], [0, 1, 0], R, DRDH, False)


def _plane(rng, c, n, k=400, size=30.0):
    n = np.asarray(n, float)
    a = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    u = rng.uniform(-size, size, (k, 2))
    return np.asarray(c) + u[:, :1] * a + u[:, 1:] * b


def _ring_feature(name, X, c0):
    return DatumFeature(name, "targets", np.asarray(c0, float), np.array([0.0, 1.0, 0.0]), X,
                        contacts=(("circular_line", np.asarray(c0, float),
                                   np.array([0.0, 1.0, 0.0]), np.arange(len(X)), None, 2 * R,
                                   {"slope": DRDH, "hole": False}),))


def test_plane_then_ring_undoes_the_rigid_motion_of_a_perfect_part():
    rng = np.random.default_rng(7)
    c0 = np.array([76.2, 66.04, -158.75])
    D = _plane(rng, [76.2, 31.75, -158.75], [0, 1, 0])       # outward normal -y side? +y
    G = _cone_band(rng, c0)
    M = rigid_exp([0.004, 0.003, -0.002, 0.3, -0.2, 0.25])
    mv = lambda X: X @ M[:3, :3].T + M[:3, 3]
    drf = fit_drf([DatumFeature("D", "plane", np.array([76.2, 31.75, -158.75]),
                                np.array([0.0, -1.0, 0.0]), mv(D)),
                   _ring_feature("G", mv(G), c0)], size=300.0)
    # the frame puts the moved part back, up to the rotation about the boss's axis it leaves
    # free: the ring's centre and D's plane are back in place
    back = drf.apply(mv(np.vstack([c0, c0 + [0, 10.0, 0]])))
    assert back[0] == pytest.approx(c0, abs=1e-6)
    assert back[1] == pytest.approx(c0 + [0, 10.0, 0], abs=1e-6)
    # the rotation about the boss's axis (76.2, -158.75)
    import re
    assert len(drf.free) == 1 and re.fullmatch(
        r"rotation about \([+-]0\.000, \+1\.000, [+-]0\.000\) through \(76\.200, 0\.000, "
        r"-158\.750\)", drf.free[0]), drf.free


def test_plane_then_ring_on_a_boss_off_its_place_centres_on_the_brute_force_ring():
    rng = np.random.default_rng(8)
    c0 = np.array([76.2, 66.04, -158.75])
    D = _plane(rng, [76.2, 31.75, -158.75], [0, 1, 0])
    G = _cone_band(rng, c0, noise=0.01, lobes=0.015) + [0.21, 0.0, -0.12]
    drf = fit_drf([DatumFeature("D", "plane", np.array([76.2, 31.75, -158.75]),
                                np.array([0.0, -1.0, 0.0]), D),
                   _ring_feature("G", G, c0)], size=300.0)
    ref = _brute_centre(G, c0, SLOPE, False)
    # in the frame, the brute-force ring centre of the part sits on the nominal axis
    got = drf.apply(ref[None])[0]
    assert got[[0, 2]] == pytest.approx(c0[[0, 2]], abs=1e-6)


def test_line_targets_on_the_flanks_of_a_groove_centre_the_tertiary_translation():
    """FTC 06's J: two lines along z on the groove's flanks (outward normals (+-cos 25,
    sin 25, 0), facing each other), after D (y) and C (z): the one free translation x is the
    least squares of the four line ends' contacts (a grid search of it here)."""
    rng = np.random.default_rng(9)
    D = _plane(rng, [80.0, 31.75, -16.0], [0, 1, 0])
    C = _plane(rng, [80.0, 50.0, 0.0], [0, 0, 1])
    ca, sa = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    n1, n2 = np.array([ca, sa, 0.0]), np.array([-ca, sa, 0.0])
    p1, p2 = np.array([68.5038, 82.5445542, -15.875]), np.array([96.5962, 82.5445542, -15.875])

    def flank(p, n, off, tilt):
        t = rng.uniform(-15.875, 15.875, 120)
        w = rng.uniform(-0.8, 0.8, 120)
        v = np.cross(n, [0, 0, 1.0])
        return p + np.outer(t, [0, 0, 1.0]) + np.outer(w, v) + np.outer(
            off + tilt * t + rng.normal(0, 0.01, 120), n)

    X1, X2 = flank(p1, n1, 0.08, 0.002), flank(p2, n2, -0.03, -0.001)
    X = np.vstack([X1, X2])
    J = DatumFeature("J", "targets", 0.5 * (p1 + p2), np.array([0.0, 1.0, 0.0]), X,
                     contacts=(("line", p1, n1, np.arange(120), np.array([0, 0, 1.0]), 31.75),
                               ("line", p2, n2, np.arange(120, 240), np.array([0, 0, 1.0]),
                                31.75)))
    drf = fit_drf([DatumFeature("D", "plane", np.array([80.0, 31.75, -16.0]),
                                np.array([0.0, -1.0, 0.0]), D),
                   DatumFeature("C", "plane", np.array([80.0, 50.0, 0.0]),
                                np.array([0.0, 0.0, 1.0]), C), J], size=300.0)
    assert drf.free == []
    tx = drf.T[0, 3]

    # brute force: the contacts' line fit of each flank (numpy polyfit of the deviation along
    # n on the parameter along z), ends at +-L/2, and a grid of x translations
    def ends(Xf, p, n):
        t = (Xf - p)[:, 2]
        b, a = np.polyfit(t, (Xf - p) @ n, 1)
        return [a - b * 15.875, a + b * 15.875]

    def cost(x):
        s1 = np.array(ends(X1 + [x, 0, 0], p1, n1))
        s2 = np.array(ends(X2 + [x, 0, 0], p2, n2))
        return float((s1 ** 2).sum() + (s2 ** 2).sum())

    grid = np.linspace(-0.2, 0.2, 4001)
    best = grid[int(np.argmin([cost(x) for x in grid]))]
    fine = np.linspace(best - 1e-4, best + 1e-4, 2001)
    best = fine[int(np.argmin([cost(x) for x in fine]))]
    assert tx == pytest.approx(best, abs=1e-6)
    # the centre plane: the two flanks' mean offsets (0.08, -0.03) give x = -(0.08 + 0.03)/2/cos
    assert tx == pytest.approx(-(0.08 - (-0.03)) / (2 * ca), abs=2e-3)
