"""A dent on a sharp convex edge is one region (issue 29 item 1).

The wavy cube, a 0.05 mm dent (tolerance 0.02 mm) centred on a 90 degree edge, scanned at 1/15
of its radius by independent samplers (``benchmarks/check_defect_shapes.py``, ``edge``): **no
region** in 8 of 8 scans.  Each face's points are pushed in along its own normal; a point of one
face pushed in by ``delta`` lies ``t < delta`` from the other face, so it reads ``-t`` against
that face, its foot jumps across the edge onto a curve of the other face, and the dent's
out-of-tolerance points fall apart into two lobes (one per face) with the pushed points'
in-tolerance ones among each.  Those deep points were read as the part's surface seen under a
reflection (``region_measures.seen_among``, ``seen_around``, ``regions._over_measured_surface``):
both lobes were outliers, the dented part showed nothing.

The geometry here is that case without the cube's tessellation: the quarter space
``x <= 0, z <= 0`` (faces ``z = 0`` and ``x = 0``, the edge along ``y``), points drawn on both
faces, the dent ``depth cos^2(pi r / 2W)`` of the distance ``r`` to the edge point at the
origin pushed along each face's inward normal, Gaussian noise along it; each displaced point's
deviation, foot and normal are its exact closest point on the quarter space's boundary (the
nearer face).  Brute force for the truth: the dent's points are the only ones beyond the
limit, whatever their face.
"""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.inspection.regions import find_regions

DEPTH, TOL, W, NOISE = 0.05, 0.02, 0.12, 0.002


def _faces(kind, s, rng, half):
    """2-D samples ``(u, v)`` on a face ``u in [0, half], v in [-half, half]`` (``u``: distance
    from the edge)."""
    if kind == "random":
        n = rng.poisson(2 * half * half / s ** 2)
        return np.column_stack([rng.uniform(0, half, n), rng.uniform(-half, half, n)])
    hu, hv = (s, s) if kind == "grid" else (s * np.sqrt(3), s / np.sqrt(3))
    U, V = np.meshgrid(np.arange(0.0, half, hu) + rng.random() * hu,
                       np.arange(-half, half, hv) + rng.random() * hv)
    return np.column_stack([U.ravel(), V.ravel()])


def _edge_dent_scan(kind, seed, s):
    """(feet, deviations, normals, face) of a scan of the dented edge."""
    rng = np.random.default_rng(seed)
    half = 3 * W
    X = []
    for face in (0, 1):
        uv = _faces(kind, s, rng, half)
        r = np.hypot(*uv.T)
        push = np.where(r < W, DEPTH * np.cos(np.pi * r / (2 * W)) ** 2, 0.0)
        push += rng.normal(0.0, NOISE, len(uv))
        if face == 0:          # top z = 0 (outward +z): (-u, v, 0) pushed down
            X.append(np.column_stack([-uv[:, 0], uv[:, 1], -push]))
        else:                  # side x = 0 (outward +x): (0, v, -u) pushed in
            X.append(np.column_stack([-push, uv[:, 1], -uv[:, 0]]))
    X = np.concatenate(X)
    # exact closest point on the boundary of {x <= 0, z <= 0}
    inside = (X[:, 0] <= 0) & (X[:, 2] <= 0)
    to_top, to_side = -X[:, 2], -X[:, 0]
    top = np.where(inside, to_top <= to_side, X[:, 2] >= X[:, 0])
    feet = X.copy()
    feet[top, 2] = 0.0
    feet[~top, 0] = 0.0
    normals = np.where(top[:, None], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    d = np.einsum("ij,ij->i", X - feet, normals)
    # outside points beyond both faces' extents do not occur (pushes are inward or noise-small)
    return feet, d, normals, (~top).astype(np.int64)


@pytest.mark.parametrize("kind", ["random", "grid", "aniso"])
@pytest.mark.parametrize("seed", [0, 1])
def test_dent_on_a_convex_edge_is_one_region(kind, seed):
    s = W / 15
    feet, d, normals, face = _edge_dent_scan(kind, seed, s)
    n = len(d)
    # the truth: the dent's points beyond the limit fall into two lobes, one per face, with
    # an in-tolerance band between them (the point of one face read against the other)
    out = d < -TOL
    assert out.sum() > 50 and set(face[out]) == {0, 1}
    regions, outliers, _ = find_regions(
        feet, d, np.ones(n, bool), np.abs(d) <= TOL, face, normals,
        limits=(np.full(n, -TOL), np.full(n, TOL)))
    assert len(regions) == 1, (kind, seed, regions)
    r = regions[0]
    assert r.side == "below" and set(r.faces) == {0, 1}
    # its extreme lies beyond the limit and not beyond the deepest point measured (it reads
    # 0.65-1.1 x that here: the fitted peak of a surface whose feet gather on a curve is not
    # accurate at an edge; noted in issue 29)
    assert d.min() - 3 * NOISE <= r.extreme < -TOL
    assert outliers.n_layer == 0


def test_a_layer_over_an_edge_is_still_a_layer():
    """The other side of the change: a reflection 0.1 mm over the top face next to the same
    edge (no dent) stays a layer of outliers, not a region: the surface under it faces the way
    the part does."""
    s = 0.05
    rng = np.random.default_rng(3)
    half = 1.2
    uv = _faces("random", s, rng, half)
    top = np.column_stack([-uv[:, 0], uv[:, 1], rng.normal(0, NOISE, len(uv))])
    uv2 = _faces("random", s, rng, half)
    side = np.column_stack([rng.normal(0, NOISE, len(uv2)), uv2[:, 1], -uv2[:, 0]])
    g = rng.uniform(-0.3, 0.3, (rng.poisson(0.36 / s ** 2), 2))
    layer = np.column_stack([-0.5 + g[:, 0], g[:, 1], 0.1 + rng.normal(0, NOISE, len(g))])
    X = np.concatenate([top, side, layer])
    is_top = np.r_[np.ones(len(top), bool), np.zeros(len(side), bool), np.ones(len(g), bool)]
    feet = X.copy()
    feet[is_top, 2] = 0.0
    feet[~is_top, 0] = 0.0
    normals = np.where(is_top[:, None], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    d = np.einsum("ij,ij->i", X - feet, normals)
    n = len(d)
    regions, outliers, _ = find_regions(
        feet, d, np.ones(n, bool), np.abs(d) <= TOL, (~is_top).astype(np.int64), normals,
        limits=(np.full(n, -TOL), np.full(n, TOL)))
    assert regions == [], regions
    assert outliers.n_layer >= 0.9 * len(g)


def _true_area(n=400_000):
    """Brute force: the area of both faces where the displaced point (no noise) reads beyond
    the limit against the nearer face: ``min(push, u)`` (``u``: distance from the edge)."""
    rng = np.random.default_rng(9)
    half = 3 * W
    uv = np.column_stack([rng.uniform(0, half, n), rng.uniform(-half, half, n)])
    r = np.hypot(*uv.T)
    push = np.where(r < W, DEPTH * np.cos(np.pi * r / (2 * W)) ** 2, 0.0)
    return 2 * (2 * half * half) * np.mean(np.minimum(push, uv[:, 0]) > TOL)


def _edge_region_area(kind, seed):
    feet, d, normals, face = _edge_dent_scan(kind, seed, W / 15)
    n = len(d)
    regions, _, _ = find_regions(feet, d, np.ones(n, bool), np.abs(d) <= TOL, face, normals,
                                 limits=(np.full(n, -TOL), np.full(n, TOL)))
    assert len(regions) == 1
    return regions[0].area


def test_dent_on_a_convex_edge_area_within_15_percent():
    """The points folded over the edge (feet crowded onto a curve of the other face) are
    measured where they were sampled (:mod:`.region_folds`).  Random, lattice and anisotropic
    rows, 2 seeds each, 1/15 of the dent's radius: the area read 40-56 % low on the old code
    (cells among the crowded feet), 2-14 % low now."""
    truth = _true_area()
    ratios = np.array([_edge_region_area(kind, seed) / truth
                       for kind in ("random", "grid", "aniso") for seed in (0, 1)])
    assert np.all(np.abs(ratios - 1.0) <= 0.15), np.round(ratios, 3)


def _unfold(feet, d, normals, s):
    from shapeverify.inspection.region_folds import unfolded
    ev = np.arange(len(d))
    return unfolded(feet, d, normals, ev, ev, s)


def test_a_wall_standing_on_a_face_is_not_folded():
    """The wall of an object lying on a flat part crowds its feet on the rim's line as a fold
    does, but no CAD surface near it faces another way: its points keep their feet (a wall
    stands for no area of the part)."""
    rng = np.random.default_rng(4)
    s = 0.05
    flat = np.column_stack([rng.uniform(-1, 1, (1600, 2)), np.zeros(1600)])
    wall = np.column_stack([np.zeros(400), rng.uniform(-1, 1, 400), rng.uniform(0, 0.5, 400)])
    feet = np.vstack([flat, wall * [1, 1, 0]])
    d = np.concatenate([rng.normal(0, NOISE, 1600), wall[:, 2]])
    normals = np.tile([0.0, 0.0, 1.0], (2000, 1))
    assert not _unfold(feet, d, normals, s)[3].any()


def test_points_beside_an_edge_without_a_dent_are_not_folded():
    """Beside an undented edge no foot lies in a crowd: nothing moves."""
    s = W / 15
    rng = np.random.default_rng(5)
    X = []
    for face in (0, 1):
        uv = _faces("random", s, rng, 3 * W)
        e = rng.normal(0.0, NOISE, len(uv))
        X.append(np.column_stack([-uv[:, 0], uv[:, 1], e]) if face == 0 else
                 np.column_stack([e, uv[:, 1], -uv[:, 0]]))
    X = np.concatenate(X)
    top = np.where((X[:, 0] <= 0) & (X[:, 2] <= 0), -X[:, 2] <= -X[:, 0], X[:, 2] >= X[:, 0])
    feet = X.copy()
    feet[top, 2] = 0.0
    feet[~top, 0] = 0.0
    normals = np.where(top[:, None], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    d = np.einsum("ij,ij->i", X - feet, normals)
    assert not _unfold(feet, d, normals, s)[3].any()


def test_the_folded_points_move_back_to_where_they_were_sampled():
    """The dent's points read against the other face move back onto their own face's plane,
    near where they were sampled (the noise along the normal aside)."""
    feet, d, normals, face = _edge_dent_scan("random", 0, W / 15)
    X = feet + d[:, None] * normals
    moved, _, _, fold = _unfold(feet, d, normals, W / 15)
    assert fold.sum() > 50
    # a folded point's scan position lies under its own face: its sampled place is that
    # position with the push undone, on the plane z = 0 (face 0) or x = 0 (face 1)
    on_top = face[fold] == 1                   # its foot was on the side face: it came from the top
    P = moved[fold]
    assert np.allclose(P[on_top, 2], 0.0) and np.allclose(P[~on_top, 0], 0.0)
    assert np.allclose(P[on_top][:, :2], X[fold][on_top][:, :2])
