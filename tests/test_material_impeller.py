"""Material only where there is material (issue 29 item 2): a good impeller scanned
independently never fails for material.

A held-back scan of a good impeller at its true pose failed with 2 "material" regions (+0.77 mm)
made mostly of outliers.  The scans here are not the project's simulator's: points drawn
uniformly by area on OpenCASCADE's tessellation of ``impeller.igs`` (:mod:`independent_scans`),
in random order, with Gaussian noise along the normal, 1-3 % scattered outliers (moved 0.2-3 mm
in random directions, or anywhere in the part's box) and clusters like reflections (surface
patches copied 1.5-4 mm off the part, within 45 degrees of the normal: beyond the evaluation
distance).  Points where BRepMesh's triangles stray from the exact faces (up to 0.16 mm on some
impeller faces, see ``benchmarks/results_independent.md``) are moved onto the exact faces before
the noise: those are the mesh's deviations, not the part's.
"""
from __future__ import annotations

import types

import numpy as np
import pytest

import independent_scans as ind
from shapeverify.inspection import inspect_registered

pytestmark = pytest.mark.slow

#: tolerance, noise, bump height and radius (mm); the impeller is 125 mm across
TOL, NOISE, BUMP, BUMP_RADIUS = 0.15, 0.02, 0.5, 5.0


def _identity():
    """The scans are made in the model's frame: no registration needed."""
    return types.SimpleNamespace(T_model_scan=np.eye(4), rms=0.0, iterations=1, converged=True,
                                 inlier_fraction=1.0)


@pytest.fixture(scope="module")
def impeller(shared_data):
    """(prepared impeller (default prepare, cached), its tessellation V, T, F)."""
    from model_cache import cached_prepared

    path = shared_data / "cad" / "impeller.igs"
    # built once per code version (tests/model_cache.py: keyed by the file's and the sources'
    # hashes; the cache here was keyed by the file's mtime alone and outlived code changes)
    prep = cached_prepared(path)
    # (once per suite run: test_impeller_reflection_regions uses this fixture too)
    V, T, F = ind.file_tessellation(path, 1e-4 * prep.model.size)
    area = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]), axis=1)
    ok = np.isfinite(area) & (area > 0)
    return prep, V, T[ok], F[ok]


def _scan(prep, V, T, spacing, seed, outliers=0.0, clusters=0, bump=None):
    """A good (or bumped) impeller scan; ``(points, normals of the surface points, rng)``."""
    rng = np.random.default_rng(seed)
    P, N = ind.random_points(V, T, spacing, rng)
    # where the mesh strays from the exact faces, the point is put on them (their foot point,
    # normal oriented like the triangle's): dropping them left holes under reflections
    cp = prep.closest(P, exact=True)
    off = np.abs(cp.distances) > 0.02
    P[off] = cp.points[off]
    flip = np.einsum("ij,ij->i", cp.normals[off], N[off]) < 0
    N[off] = np.where(flip[:, None], -cp.normals[off], cp.normals[off])
    h = rng.normal(0.0, NOISE, len(P))
    if bump is not None:
        h += ind.bump(P, bump, BUMP, BUMP_RADIUS)
    P = P + h[:, None] * N
    extra = []
    n_out = int(outliers * len(P))
    if n_out:
        k = rng.choice(len(P), n_out // 2, replace=False)           # moved 0.2-3 mm
        u = rng.normal(size=(k.size, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        extra.append(P[k] + u * rng.uniform(0.2, 3.0, k.size)[:, None])
        lo, hi = P.min(axis=0), P.max(axis=0)                       # anywhere in the box
        extra.append(rng.uniform(lo, hi, (n_out - k.size, 3)))
    for _ in range(clusters):                                       # reflections
        c = P[rng.integers(len(P))]
        sel = np.flatnonzero(np.linalg.norm(P - c, axis=1) < rng.uniform(2.0, 4.0))
        n = N[sel].mean(axis=0)
        n /= np.linalg.norm(n) or 1.0
        t = rng.normal(size=3)
        t -= (t @ n) * n
        t /= np.linalg.norm(t)
        ang = rng.uniform(0.0, np.pi / 4)
        d = np.cos(ang) * n + np.sin(ang) * t
        extra.append(P[sel] + rng.uniform(1.5, 4.0) * d * rng.choice([-1.0, 1.0]))
    if extra:
        P = np.vstack([P] + extra)
        P = P[rng.permutation(len(P))]
    return P, rng


@pytest.mark.parametrize("spacing,seed,outliers,clusters", [
    (0.7, 1, 0.0, 0), (0.7, 2, 0.01, 0), (0.7, 3, 0.03, 3), (1.0, 6, 0.03, 3), (0.5, 4, 0.02, 4)])
def test_good_impeller_scanned_independently_has_no_material_and_passes(impeller, spacing, seed,
                                                                        outliers, clusters):
    """Issue 29 item 2: a good impeller at its true pose failed with 2 material regions of
    mostly outliers (+0.77 mm).  A reflection landing within the evaluation distance of another
    blade made 'material added' regions over the blade's in-tolerance surface (1 mm spacing,
    seed 6; 0.5 mm, seed 4: 4 regions): a layer over measured surface is outliers, not a
    defect.  A reflection beside a blade's edge, 3.4 mm off and touching the blade's scan at
    one point, was a 'material' region (0.7 mm, seed 3): material is attached along a rim.
    0.5 mm, seed 4: a reflection crossing two blades left 2 regions (12 points +0.44 mm, 6
    points -0.64 mm inside a blade) where its points crowded among the blades' good surface:
    the surface is seen under (over) them, so they are outliers (regions.seen_under).  At 1 mm
    spacing the scan's own noise read 8 x too high (quadrics across the thin blades):
    'incomplete', not 'pass'."""
    prep, V, T, _ = impeller
    P, _ = _scan(prep, V, T, spacing, seed, outliers, clusters)
    res = inspect_registered(prep, P, _identity(), tolerance=TOL)
    assert not [r for r in res.regions if r.kind == "material"], res.reasons
    assert res.excluded["material"] == 0
    assert not res.regions, res.reasons
    # at 1 mm the scan's own noise read 0.15-0.17 mm (8 x the true 0.02 mm: quadrics over 24
    # neighbours across the thin blades) and the verdict was 'incomplete' (undecided)
    assert res.verdict == "pass", (res.noise, res.reasons)
    assert 0.7 * NOISE < res.noise < 1.3 * NOISE, res.noise


def test_a_real_bump_on_the_impeller_is_still_found(impeller):
    """The same scans with a real 0.5 mm bump (5 mm radius, on the largest face): one region of
    material added, no material region, the extreme within 10 % of the bump."""
    prep, V, T, F = impeller
    site = ind.dent_site(V, T, F, BUMP_RADIUS)
    P, _ = _scan(prep, V, T, 0.7, 5, outliers=0.02, clusters=3, bump=site)
    res = inspect_registered(prep, P, _identity(), tolerance=TOL)
    assert res.verdict == "fail", res.reasons
    assert [(r.kind, r.side) for r in res.regions] == [("deviation", "above")], res.reasons
    r = res.regions[0]
    assert abs(r.extreme / BUMP - 1) < 0.10, r
    assert np.linalg.norm(r.centroid - site) < 0.5 * BUMP_RADIUS
