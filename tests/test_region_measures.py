"""A region's area and extreme that do not depend on the sampling (issue 29 item 1).

Before: the area was the sum of a kernel density's area per out-of-tolerance point, and the
extreme a quadratic over a fixed share of the region, dropped for the neighbourhood median when
its peak exceeded the largest sample: at 1/5 of a dent's radius the wavy cube's dent read area
-11 %, extreme -14 % (grid) and the panel's -41 % / -33 % (random).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull, Voronoi, cKDTree

from shapeverify.inspection.regions import find_regions
from shapeverify.inspection.region_measures import out_area

#: a cos^2 dent on a plane: radius, depth, tolerance, noise (the panel's, mm)
R, DEPTH, TOL, NOISE = 15.0, -0.5, 0.2, 0.02
#: where |dent| = TOL, and the out-of-tolerance area
R_OUT = np.arccos(np.sqrt(TOL / abs(DEPTH))) * 2 * R / np.pi
TRUE_AREA = np.pi * R_OUT ** 2


def _plane(kind, s, rng, half=3 * R):
    if kind == "random":
        return rng.uniform(-half, half, (rng.poisson((2 * half / s) ** 2), 2))
    hx, hy = (s, s) if kind == "grid" else (s / np.sqrt(3), s * np.sqrt(3))   # same area per point
    X, Y = np.meshgrid(np.arange(-half, half, hx) + rng.random() * hx,
                       np.arange(-half, half, hy) + rng.random() * hy)
    P = np.column_stack([X.ravel(), Y.ravel()])
    return P[rng.permutation(len(P))]


def test_cells_are_the_voronoi_cells_of_scipy():
    """The cells that carry the area are the points' Voronoi cells (scipy.spatial.Voronoi, Qhull)
    where they are smaller than the bounding square; a linear g splits them exactly."""
    rng = np.random.default_rng(0)
    s = 1.0
    P2 = rng.uniform(0, 30, (900, 2))
    pts = np.column_stack([P2, np.zeros(len(P2))])
    normals = np.tile([0.0, 0.0, 1.0], (len(P2), 1))
    ev = np.arange(len(P2))
    q = np.flatnonzero(np.all((P2 > 8) & (P2 < 22), axis=1))
    g_all = P2[:, 0] - 15.0                       # linear: out where x > 15
    part, cell = out_area(cKDTree(pts), ev, pts, normals, g_all, q, s)
    vor = Voronoi(P2)
    checked = 0
    for k, i in enumerate(q):
        reg = vor.regions[vor.point_region[i]]
        if -1 in reg or not reg:
            continue
        poly = vor.vertices[reg]
        if np.abs(poly - P2[i]).max() >= 1.5 * s:          # cut by the bounding square
            continue
        assert cell[k] == pytest.approx(ConvexHull(poly).volume, rel=1e-9)
        checked += 1
    assert checked > 0.8 * q.size
    # the out part of each cell: its share at x > 15 (the slope is exact for a linear g)
    total = part.sum()
    assert total == pytest.approx(np.sum(cell[P2[q, 0] > 15]), rel=0.05)
    assert np.all((part >= 0) & (part <= cell + 1e-12))


@pytest.mark.parametrize("kind", ["random", "grid", "aniso"])
@pytest.mark.parametrize("ratio", [1 / 5, 1 / 15])
def test_dent_area_and_extreme_hold_at_coarse_spacing(kind, ratio):
    """A dent sampled at 1/15 and 1/5 of its radius: area within 15 % of the analytic
    out-of-tolerance area, extreme within 10 % of the depth and within 3 stated uncertainties
    (plus 3 % for the quadratic's model), centroid within half a spacing of the centre."""
    s = ratio * R
    for seed in range(3):
        rng = np.random.default_rng(seed)
        P2 = _plane(kind, s, rng)
        r = np.hypot(*P2.T)
        d = np.where(r < R, DEPTH * np.cos(np.pi * r / (2 * R)) ** 2, 0.0) + rng.normal(0, NOISE, len(r))
        pts = np.column_stack([P2, np.zeros(len(P2))])
        n = len(P2)
        regions, _, _ = find_regions(pts, d, np.ones(n, bool), np.abs(d) <= TOL, np.zeros(n, int),
                                     np.tile([0.0, 0.0, 1.0], (n, 1)),
                                     limits=(np.full(n, -TOL), np.full(n, TOL)))
        assert len(regions) == 1
        g = regions[0]
        assert abs(g.area / TRUE_AREA - 1) < 0.15, (seed, g.area, TRUE_AREA)
        assert abs(g.extreme / DEPTH - 1) < 0.10, (seed, g.extreme)
        assert abs(g.extreme - DEPTH) <= 3 * g.extreme_uncertainty + 0.03 * abs(DEPTH), g
        assert g.extreme < -TOL and np.isfinite(g.extreme_uncertainty)
        assert np.linalg.norm(g.centroid[:2]) < 0.5 * s


def _flat(s, rng, half=20.0):
    P2 = rng.uniform(-half, half, (rng.poisson((2 * half / s) ** 2), 2))
    return np.column_stack([P2, np.zeros(len(P2))])


def _regions(pts, d):
    n = len(d)
    return find_regions(pts, d, np.ones(n, bool), np.abs(d) <= TOL, np.zeros(n, int),
                        np.tile([0.0, 0.0, 1.0], (n, 1)), limits=(np.full(n, -TOL), np.full(n, TOL)))


def test_a_layer_over_good_surface_is_outliers_not_a_defect():
    """Issue 29 item 2: a reflection copied 0.6 mm over the impeller's in-tolerance surface
    (its feet among the surface's own) made up to 4 'material added' regions on a good part."""
    rng = np.random.default_rng(7)
    pts = _flat(0.5, rng)
    d = rng.normal(0, NOISE, len(pts))
    ghost = np.flatnonzero(np.hypot(pts[:, 0] - 3, pts[:, 1]) < 4.0)
    g_pts = pts[ghost] + rng.normal(0, 0.1, (ghost.size, 3)) * [1, 1, 0]
    regions, outliers, _ = _regions(np.vstack([pts, g_pts]),
                                    np.concatenate([d, 0.6 + rng.normal(0, NOISE, ghost.size)]))
    assert regions == [] and outliers.n_layer > 0.9 * ghost.size


@pytest.mark.parametrize("radius,seed", [(1.0, 2), (1.5, 8), (4.0, 8)])
def test_a_sharp_pit_is_still_a_defect(radius, seed):
    """A pit with a step at its rim (the surface inside replaced, not seen under it) stays one
    region, however small (radius 2, 3 and 8 spacings; at 2 the rim's good surface within 1.5
    spacings of its core points made it a 'layer' before the density test)."""
    rng = np.random.default_rng(seed)
    pts = _flat(0.5, rng)
    d = rng.normal(0, NOISE, len(pts))
    d[np.hypot(pts[:, 0], pts[:, 1]) < radius] -= 0.6
    regions, outliers, _ = _regions(pts, d)
    assert len(regions) == 1 and outliers.n_layer == 0
    assert regions[0].area == pytest.approx(np.pi * radius ** 2, rel=0.15)
    assert abs(regions[0].extreme + 0.6) < 0.05


def _reflection_crossing(seed, density, angle, s=0.5, half=10.0, tol=0.15):
    """A good flat scan (spacing ``s``) crossed along x = 0 by a reflection: a sheet tilted by
    ``angle`` (rad), sampled at ``density`` x the scan's density, whose points within 1 mm of
    the surface (the evaluation distance) are evaluated."""
    rng = np.random.default_rng(seed)
    P2 = rng.uniform(-half, half, (rng.poisson((2 * half / s) ** 2), 2))
    d = rng.normal(0, NOISE, len(P2))
    u = rng.uniform(-4, 4, (rng.poisson(density * 64 / s ** 2), 2))
    z = u[:, 0] * np.sin(angle)
    keep = np.abs(z) < 1.0
    G2 = np.column_stack([u[keep, 0] * np.cos(angle), u[keep, 1]])
    pts = np.column_stack([np.vstack([P2, G2]), np.zeros(len(P2) + len(G2))])
    v = np.concatenate([d, z[keep] + rng.normal(0, NOISE, keep.sum())])
    n = len(v)
    return find_regions(pts, v, np.ones(n, bool), np.abs(v) <= tol, np.zeros(n, int),
                        np.tile([0.0, 0.0, 1.0], (n, 1)), limits=(np.full(n, -tol), np.full(n, tol)))


@pytest.mark.parametrize("density", [0.5, 1.0])
def test_a_reflection_crossing_good_surface_leaves_no_region(density):
    """Issue 29 item 2: a reflection crossing a blade of a good impeller left a region of 6
    points (0.5 mm spacing, seed 4: -0.64 mm inside the blade) where the reflection's points
    happened to crowd; the blade's in-tolerance surface is seen all around and between them.
    Here (seed 3 of both densities) the same: 'material missing' regions over good surface
    before, outliers now (the points lie inside the alpha shape of the in-tolerance surface)."""
    for seed in range(6):
        regions, outliers, _ = _reflection_crossing(seed, density, 0.5)
        assert regions == [], (seed, regions)
        if seed == 3:
            assert outliers.n_layer > 0


@pytest.mark.parametrize("kind", ["grid", "aniso", "random"])
def test_a_scratch_two_spacings_wide_is_still_one_region(kind):
    """A scratch 2 spacings wide and 32 long: the good surface on both banks is within reach
    of its points, but it is not seen *under* them (the triangles across the scratch are
    larger than the surface's own): one region (a rule with the alpha taken from the median
    circumradius called the anisotropic rows' scratch a layer)."""
    rng = np.random.default_rng(1)
    s = 0.5
    if kind == "random":
        P2 = rng.uniform(-20, 20, (rng.poisson((40 / s) ** 2), 2))
    else:
        hx, hy = (s, s) if kind == "grid" else (s / np.sqrt(3), s * np.sqrt(3))
        X, Y = np.meshgrid(np.arange(-20, 20, hx) + rng.random() * hx,
                           np.arange(-20, 20, hy) + rng.random() * hy)
        P2 = np.column_stack([X.ravel(), Y.ravel()])
    pts = np.column_stack([P2, np.zeros(len(P2))])
    d = rng.normal(0, NOISE, len(pts))
    scratch = (np.abs(P2[:, 0]) < s) & (np.abs(P2[:, 1]) < 8)
    d[scratch] -= 0.6
    regions, outliers, _ = _regions(pts, d)
    assert outliers.n_layer == 0
    assert sum(r.n for r in regions) > 0.8 * np.count_nonzero(scratch)
    if kind != "random":          # random sampling cuts a scratch this narrow in two (as before)
        assert len(regions) == 1


def test_a_shallow_dent_is_not_taken_for_a_layer_by_its_noise():
    """A dent 0.25 mm deep at a limit of 0.2 (lattice at 1 mm): points inside it that the noise
    brings deep into the tolerance are sparse; taken as 'the surface seen under' the dent at
    their own spacing they covered it (the dent was a layer: no region)."""
    rng = np.random.default_rng(0)
    X, Y = np.meshgrid(np.arange(-45, 45, 1.0) + rng.random(), np.arange(-45, 45, 1.0) + rng.random())
    P2 = np.column_stack([X.ravel(), Y.ravel()])
    pts = np.column_stack([P2, np.zeros(len(P2))])
    r = np.hypot(*P2.T)
    d = np.where(r < R, -0.25 * np.cos(np.pi * r / (2 * R)) ** 2, 0.0) + rng.normal(0, NOISE, len(r))
    regions, outliers, _ = _regions(pts, d)
    assert len(regions) == 1 and outliers.n_layer == 0


@pytest.mark.parametrize("density", [0.5, 0.7])
def test_a_sparse_layer_under_good_surface_leaves_no_region(density):
    """Issue 29 item 2: reflections 0.25-0.6 mm inside the good impeller made 'material
    missing' regions (0.5 mm spacing, 6 of 20 seeds).  A layer's core points (neighbourhood
    median beyond the limit) are its points in the sampling holes of the surface over it, where
    the alpha shape of the surface does not cover them; here a layer at half to 0.7 of the
    surface's density 0.6 mm under a random flat scan left a region in 4 of these 24 scans
    (density 0.5: seeds 2, 11; 0.7: seeds 0, 5).  All its out-of-tolerance points have the
    surface around them like the surface's own points (region_measures.seen_around)."""
    s = 0.5
    for seed in range(12):
        rng = np.random.default_rng(seed)
        P2 = rng.uniform(-10, 10, (rng.poisson((20 / s) ** 2), 2))
        G2 = rng.uniform(-3, 3, (rng.poisson(density * 36 / s ** 2), 2))
        pts = np.column_stack([np.vstack([P2, G2]), np.zeros(len(P2) + len(G2))])
        v = np.concatenate([rng.normal(0, NOISE, len(P2)), -0.6 + rng.normal(0, NOISE, len(G2))])
        n = len(v)
        tol = 0.15
        regions, outliers, _ = find_regions(pts, v, np.ones(n, bool), np.abs(v) <= tol,
                                            np.zeros(n, int), np.tile([0.0, 0.0, 1.0], (n, 1)),
                                            limits=(np.full(n, -tol), np.full(n, tol)))
        assert regions == [], (seed, regions)
        assert outliers.n == np.count_nonzero(np.abs(v) > tol)
