"""Lower segments of composite feature control frames (ASME Y14.5-2009 §7.5.1, §8.3.1): the
feature-relating zone framework may translate, and turn about the free datum axes, to its best
place (:mod:`shapeverify.characteristics.composite`); checked against independent brute-force
computations: the exact smallest enclosing circle (all pairs and triples of points) for a
pattern of parallel holes, over a fine grid of rotations where the framework may turn, and
Nelder-Mead from several starts for a profile."""
import itertools

import numpy as np
import pytest

from shapeverify.characteristics.composite import (best_pattern_fit, best_profile_fit,
                                                   rotation_matrix)

Z = np.array([0.0, 0.0, 1.0])


def _circle_of(pts):
    """Smallest circle through 2 (diameter) or 3 points (circumcircle), (centre, radius)."""
    if len(pts) == 2:
        c = (pts[0] + pts[1]) / 2
        return c, float(np.linalg.norm(pts[0] - c))
    a, b, c = pts
    d = 2 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if abs(d) < 1e-14:
        return None
    ux = ((a @ a) * (b[1] - c[1]) + (b @ b) * (c[1] - a[1]) + (c @ c) * (a[1] - b[1])) / d
    uy = ((a @ a) * (c[0] - b[0]) + (b @ b) * (a[0] - c[0]) + (c @ c) * (b[0] - a[0])) / d
    u = np.array([ux, uy])
    return u, float(np.linalg.norm(a - u))


def brute_enclosing_radius(V):
    """Radius of the smallest circle holding the 2-D points V: every circle through 2 or 3 of
    them, the smallest that holds all (exhaustive, O(n^4))."""
    best = np.inf
    for r in (2, 3):
        for sub in itertools.combinations(range(len(V)), r):
            got = _circle_of(V[list(sub)])
            if got is None:
                continue
            c, rad = got
            if rad < best and np.all(np.linalg.norm(V - c, axis=1) <= rad + 1e-12):
                best = rad
    return best


def _pattern(rng, n=6, radius=40.0, depth=12.0):
    ang = np.arange(n) * 2 * np.pi / n + 0.3
    C = np.c_[radius * np.cos(ang), radius * np.sin(ang), np.zeros(n)]
    return C


def _ends(C, offsets):
    """Measured axis ends (top and bottom) of holes along z offset by offsets (n, 2, 2)."""
    out = []
    for c, o in zip(C, offsets):
        out.append(np.array([c + [o[0][0], o[0][1], 0.0], c + [o[1][0], o[1][1], -12.0]]))
    return out


def brute_translation_only(C, ends):
    V = np.vstack([(e - c)[:, :2] for c, e in zip(C, ends)])
    return 2 * brute_enclosing_radius(V)


def brute_with_rotation(C, ends, p):
    """Twice the min over theta (about z through p) of the enclosing radius of the ends'
    offsets: a grid of 2001 angles in +-2 mrad, then a bounded scalar search about the best."""
    from scipy.optimize import minimize_scalar

    def f(th):
        R = rotation_matrix(th * Z)
        V = np.vstack([((e - p) @ R.T + p - c)[:, :2] for c, e in zip(C, ends)])
        return brute_enclosing_radius(V)

    grid = np.linspace(-2e-3, 2e-3, 201)
    vals = [f(t) for t in grid]
    i = int(np.argmin(vals))
    r = minimize_scalar(f, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, 200)]),
                        method="bounded", options={"xatol": 1e-12})
    return 2 * min(r.fun, vals[i])


def test_lower_position_pattern_shifted_as_a_whole_passes_the_lower_segment():
    rng = np.random.default_rng(1)
    C = _pattern(rng)
    A = np.tile(Z, (len(C), 1))
    shift = np.array([0.4, 0.0])                        # the whole pattern 0.4 mm off
    offs = shift + rng.normal(0, 0.02, (len(C), 2, 2))
    ends = _ends(C, offs)
    got = best_pattern_fit(ends, C, A, np.zeros((0, 3)))
    assert got["value"] == pytest.approx(brute_translation_only(C, ends), abs=1e-6)
    assert got["value"] < 0.3                           # the lower 0.3 passes
    assert got["located"] > 0.8 - 0.1                   # located: ~2 x 0.4
    assert got["located"] < 1.5                         # and the upper 1.5 passes
    assert got["located"] > 0.3                         # where a located 0.3 would fail


def test_lower_position_with_free_rotation_matches_brute_force():
    rng = np.random.default_rng(2)
    C = _pattern(rng)
    A = np.tile(Z, (len(C), 1))
    th = 1.2e-3                                         # turned about z and shifted
    R = rotation_matrix(th * Z)[:2, :2]
    offs = np.array([[(R @ c[:2] - c[:2]) + [0.3, -0.2]] * 2 for c in C])
    offs = offs + rng.normal(0, 0.02, offs.shape)
    ends = _ends(C, offs)
    got = best_pattern_fit(ends, C, A, Z[None, :])
    assert got["value"] == pytest.approx(brute_with_rotation(C, ends, C.mean(axis=0)),
                                         abs=1e-6)
    # without the rotation the framework cannot follow the turn
    assert best_pattern_fit(ends, C, A, np.zeros((0, 3)))["value"] > got["value"] + 0.05


@pytest.mark.slow
@pytest.mark.parametrize("move", [0.3, 0.45])
def test_lower_position_one_hole_moved_fails_the_lower_segment(move):
    """One hole of six moved ``move`` off the others (the pattern also 0.4 mm off as a whole):
    the framework can split the move, so the zone needed is ``move`` (0.3: exactly the lower
    segment's 0.3, on the limit; 0.45 fails it), whatever the rotation."""
    rng = np.random.default_rng(3)
    C = _pattern(rng)
    A = np.tile(Z, (len(C), 1))
    offs = np.zeros((len(C), 2, 2)) + [0.4, 0.0]
    offs[2] += [0.0, move]
    ends = _ends(C, offs)
    got = best_pattern_fit(ends, C, A, Z[None, :])
    assert got["value"] == pytest.approx(brute_with_rotation(C, ends, C.mean(axis=0)),
                                         abs=1e-6)
    assert got["value"] == pytest.approx(move, abs=1e-6)
    noisy = _ends(C, offs + rng.normal(0, 0.01, offs.shape))
    got = best_pattern_fit(noisy, C, A, Z[None, :])
    assert got["value"] == pytest.approx(brute_with_rotation(C, noisy, C.mean(axis=0)),
                                         abs=1e-6)
    assert (got["value"] > 0.3) == (move > 0.3) or move == 0.3


# ------------------------------------------------------------------------------ profile
def _faces_cloud(rng, n=150):
    """Points on three analytic faces (plane z=0, cylinder r=20 about z, plane x=50), each
    point tagged with its face; the exact signed distance of moved points from their face."""
    a = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(5, 30, n)
    cyl = np.c_[20 * np.cos(a), 20 * np.sin(a), z]
    bot = np.c_[rng.uniform(-40, 40, n), rng.uniform(-40, 40, n), np.zeros(n)]
    side = np.c_[np.full(n, 50.0), rng.uniform(-30, 30, n), rng.uniform(0, 30, n)]
    X = np.vstack([cyl, bot, side])
    tag = np.repeat([0, 1, 2], n)
    return X, tag


def _signed(Y, tag):
    d = np.empty(len(Y))
    N = np.zeros_like(Y)
    r = np.hypot(Y[:, 0], Y[:, 1])
    m = tag == 0
    d[m] = r[m] - 20.0
    N[m] = np.c_[Y[m, 0] / r[m], Y[m, 1] / r[m], np.zeros(m.sum())]
    m = tag == 1
    d[m] = -Y[m, 2]
    N[m] = [0, 0, -1]
    m = tag == 2
    d[m] = Y[m, 0] - 50.0
    N[m] = [1, 0, 0]
    return d, N


def brute_profile(X, tag, rotations, p):
    """min over (rotation about the free axes through p, translation) of max |d|: Nelder-Mead
    from 6 starts, each restarted from its answer until it stops improving."""
    from scipy.optimize import minimize

    B = np.asarray(rotations, float).reshape(-1, 3)
    k = B.shape[0]

    def f(x):
        Y = (X - p) @ rotation_matrix(x[:k] @ B * 1e-3).T + p + x[k:]
        return float(np.abs(_signed(Y, tag)[0]).max())

    rng = np.random.default_rng(0)
    best = np.inf
    for s in range(6):
        x = rng.normal(0, 0.2, k + 3) if s else np.zeros(k + 3)
        prev = np.inf
        while True:
            r = minimize(f, x, method="Nelder-Mead",
                         options={"xatol": 1e-11, "fatol": 1e-13, "maxiter": 40000,
                                  "maxfev": 40000, "adaptive": True})
            x = r.x
            if r.fun > prev - 1e-12:
                break
            prev = r.fun
        best = min(best, prev)
    return best


@pytest.mark.slow
@pytest.mark.parametrize("rot", [False, True])
def test_lower_profile_zone_moves_to_its_best_place_as_brute_force(rot):
    """A profile of three faces displaced 0.4 mm as a whole (and turned 1 mrad about z, the
    free axis of a primary plane z), with a form error of +-0.05: the lower segment's value
    (twice the largest |d| at the best place) equals the brute force's to 1e-6 mm; located, the
    displacement counts."""
    rng = np.random.default_rng(5)
    X0, tag = _faces_cloud(rng)
    X0 = X0 + _signed(X0, tag)[1] * rng.uniform(-0.05, 0.05, (len(X0), 1))
    R = rotation_matrix([0, 0, 1e-3 if rot else 0.0])
    X = X0 @ R.T + [0.4, -0.3, 0.0]
    B = Z[None, :] if rot else np.zeros((0, 3))
    got = best_profile_fit(X, lambda Y: _signed(Y, tag), B)
    brute = brute_profile(X, tag, B, X.mean(axis=0))
    assert got["value"] == pytest.approx(brute, abs=1e-6)
    assert got["value"] <= 0.05 + 1e-9               # the form error only
    assert 2 * got["located"] > 0.4 * 2 - 0.1        # located: the 0.4 mm shift


# ------------------------------------------------------------------------------ end to end
_COMPOSITE_PLAN = """units: mm
alignment: {type: best_fit}
datums: {A: {faces: [face:0]}, B: {faces: [face:1]}, C: {faces: [face:2]}}
characteristics:
  - {name: POS_UPPER, type: position, features: [face:3], tol: 1.5, datums: [A, B, C],
     composite: upper}
  - {name: POS_LOWER, type: position, features: [face:3], tol: 0.3, datums: [A, B],
     composite: lower}
  - {name: POS_LOCATED, type: position, features: [face:3], tol: 0.3, datums: [A, B]}
  - {name: PROF_UPPER, type: surface_profile, faces: [face:3], tol: 2.0, datums: [A, B, C],
     composite: upper}
  - {name: PROF_LOWER, type: surface_profile, faces: [face:3], tol: 0.3, datums: [A],
     composite: lower}
  - {name: PROF_LOCATED, type: surface_profile, faces: [face:3], tol: 0.3, datums: [A, B, C]}
"""


@pytest.mark.slow
def test_composite_lower_segment_passes_a_boss_shifted_within_the_upper_zone():
    """The bracket's boss 0.5 mm off (x), perfect in itself: the located segments read about
    1.0 (position) and 0.5 x 2 (profile) and a located 0.3 fails; the upper segments (1.5,
    2.0) pass; the lower segments, whose datums only orient the zone, read the boss's own
    orientation and form (the scan noise) and pass."""
    from shapeverify.characteristics import evaluate_plan
    from shapeverify.characteristics.parts import BRACKET_BOSS, bracket
    from shapeverify.nearest import prepare
    from shapeverify.registration.rigid import apply_transform
    from shapeverify.simulate import virtual_scan
    from shapeverify.characteristics.drf import rigid_exp

    bx, by, br, bh = BRACKET_BOSS
    nominal = prepare(bracket(), spacing=1.0)
    moved = prepare(bracket(boss=(bx + 0.5, by, br, bh)), spacing=1.0)
    views = ([1.0, 1.0, 1.6], [-1.0, 1.0, 1.6], [1.0, -1.0, 1.6], [-1.0, -1.0, 1.6])
    P = np.vstack([virtual_scan(moved, view=v, pixel=1.0, noise=0.02, rng=17 + i).scan
                   for i, v in enumerate(views)])
    P = apply_transform(rigid_exp([0.02, -0.03, 0.01, 1.5, -2.0, 1.0]), P)
    res = evaluate_plan(nominal, P, _COMPOSITE_PLAN)
    v = {c.name: (c.verdict, round(c.measured, 3)) for c in res.characteristics}
    assert res["POS_LOCATED"].verdict == "fail" and res["PROF_LOCATED"].verdict == "fail", v
    assert res["POS_UPPER"].verdict == "pass" and res["PROF_UPPER"].verdict == "pass", v
    assert res["POS_LOWER"].verdict == "pass" and res["PROF_LOWER"].verdict == "pass", v
    assert res["POS_LOCATED"].measured == pytest.approx(1.0, abs=0.15)
    comp = res["POS_LOWER"].details["composite"]
    assert comp["located"] == pytest.approx(res["POS_LOCATED"].measured, abs=1e-9)
    assert res["POS_LOWER"].measured < 0.15
    assert res["PROF_LOWER"].measured < 0.15


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lower_position_of_features_with_their_own_zones_minimises_the_largest_excess(seed):
    """Features of different zones in one lower segment (a counterbored hole's hole and
    counterbore at MMC, each zone ``tol + its own bonus``): the framework's best place is the
    one with the smallest largest excess ``distance - radius`` of an axis over its own zone
    (``radii``), not the smallest largest distance.  Brute force for parallel axes (a
    translation across them): the convex ``max_i |v_i - t| - r_i`` on a 0.002 mm grid, then
    polished by Nelder-Mead from the grid's best."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    n = 6
    C = np.column_stack([rng.uniform(-40, 40, (n, 2)), np.zeros(n)])
    off = rng.uniform(-0.3, 0.3, (n, 2))
    radii = rng.uniform(0.2, 0.5, n)
    ends = [np.array([[*(c[:2] + o), -5.0], [*(c[:2] + o), 5.0]]) for c, o in zip(C, off)]
    fit = best_pattern_fit(ends, C, np.tile(Z, (n, 1)), np.zeros((0, 3)), radii=radii)
    got = float((np.asarray(fit["per_feature"]) / 2 - radii).max())

    def f(t):
        return float((np.linalg.norm(off - t, axis=1) - radii).max())

    g = np.arange(-0.3, 0.3, 0.002)
    T = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    F = (np.linalg.norm(off[None] - T[:, None], axis=2) - radii).max(1)
    t0 = T[F.argmin()]
    brute = minimize(f, t0, method="Nelder-Mead",
                     options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 20000}).fun
    assert got == pytest.approx(brute, abs=1e-6)
    # the plain fit (no radii) minimises the largest distance instead: never a smaller excess
    plain = best_pattern_fit(ends, C, np.tile(Z, (n, 1)), np.zeros((0, 3)))
    assert float((np.asarray(plain["per_feature"]) / 2 - radii).max()) >= got - 1e-9
