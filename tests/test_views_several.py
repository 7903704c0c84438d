"""A part measured in several views (issue 30 item 2): each view placed from no start, the views
refined together, one verdict for the whole part.

Issue 30: "a part is measured in several views (a robot or turntable moves the part or the
sensor); today each view is inspected alone, so no view covers enough, and overlaps disagree".
The held-back multi-view case is not on this machine; its stand-in here is built without the
project's sampler or simulator:

* the NIST CTC 01 test part (800 x 450 x 150 mm, 117 faces; ``shared_data``), tessellated by
  OpenCASCADE and sampled uniformly by area (4 mm); each of 6 views keeps the points visible
  from one direction: facing it (normal . view > 0.15) and not hidden by nearer surface (a
  z-buffer of a denser 2 mm sample on a 4 mm grid across the view, a point kept within its
  own slope across a cell of the nearest depth); noise 0.02 mm along the normal; each view in
  its own random frame (any rotation, 300 mm off);
* the Stanford bunny's real views bun000/bun045/bun090 (``shared_data``) with their poses in
  ``bun.conf``, for the views' refinement against each other with no CAD.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import shapeverify as sv
from independent_scans import file_tessellation, random_points
from model_cache import cached_prepared

pytestmark = pytest.mark.slow

NIST = "cad/nist/nist_ctc_01_asme1_ap242-e1.stp"
#: the view directions (from the part towards the sensor): above, below and four sides, tilted
DIRECTIONS = ((0.3, 0.2, 1.0), (0.2, -0.3, -1.0), (1.0, 0.3, 0.4), (-1.0, -0.2, 0.3),
              (0.2, 1.0, 0.4), (-0.3, -1.0, -0.3))


def visible(P, N, view, cell, dense):
    """Which of the points ``P`` (normals ``N``) are seen from the direction ``view``: facing it,
    and within their own slope across one ``cell`` of the nearest depth of ``dense`` (a denser
    sample of the whole surface) in their cell of a grid across the view."""
    v = np.asarray(view, float) / np.linalg.norm(view)
    a = np.cross(v, [1.0, 0, 0] if abs(v[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(v, a)

    def cells(X):
        return np.floor(np.c_[X @ a, X @ b] / cell).astype(np.int64)

    kd, kp = cells(dense), cells(P)
    lo = np.minimum(kd.min(axis=0), kp.min(axis=0))
    width = int(max(kd[:, 1].max(), kp[:, 1].max()) - lo[1] + 1)
    fd, fp = (kd[:, 0] - lo[0]) * width + kd[:, 1] - lo[1], (kp[:, 0] - lo[0]) * width + kp[:, 1] - lo[1]
    u, inv = np.unique(fd, return_inverse=True)
    nearest = np.full(u.size, -np.inf)
    np.maximum.at(nearest, inv, dense @ v)
    j = np.clip(np.searchsorted(u, fp), 0, u.size - 1)
    depth = np.where(u[j] == fp, nearest[j], -np.inf)
    c = N @ v
    slope = np.sqrt(np.maximum(1.0 - c ** 2, 0.0)) / np.maximum(c, 1e-3)
    return (c > 0.15) & (P @ v >= depth - 1.5 * cell * np.minimum(slope, 3.0) - 0.05)


@pytest.fixture(scope="module")
def nist(shared_data):
    """(prepared part, the surface sample P, N and the 6 views' masks of it)."""
    path = shared_data / NIST
    V, T, _ = file_tessellation(path, 0.05)     # once per suite run (tests/model_cache.py)
    rng = np.random.default_rng(0)
    dense, _ = random_points(V, T, 2.0, rng)
    P, N = random_points(V, T, 4.0, rng)
    masks = [visible(P, N, d, 4.0, dense) for d in DIRECTIONS]
    return cached_prepared(path), P, N, masks      # prepare(load_model(path)), once per run


def _views(P, N, masks, seed, dent=None):
    """Each view's points in its own random frame, and its true T_model_scan."""
    rng = np.random.default_rng(seed)
    depth = np.zeros(len(P))
    if dent is not None:                 # (centre, radius, depth): into the material
        c, rad, dd = dent
        d = np.linalg.norm(P - c, axis=1)
        depth = dd * np.cos(0.5 * np.pi * np.minimum(d / rad, 1.0)) ** 2
    views, truths = [], []
    for m in masks:
        Q = P[m] + (rng.normal(0.0, 0.02, m.sum()) - depth[m])[:, None] * N[m]
        M = np.eye(4)
        M[:3, :3] = Rotation.random(random_state=int(rng.integers(1 << 31))).as_matrix()
        M[:3, 3] = rng.normal(size=3) * 300.0
        views.append(Q @ M[:3, :3].T + M[:3, 3])
        truths.append(np.linalg.inv(M))
    return views, truths


def _pose_error(T, T_true, pts):
    D = np.asarray(T) @ np.linalg.inv(T_true)
    X = pts @ T_true[:3, :3].T + T_true[:3, 3]
    ang = np.degrees(np.linalg.norm(Rotation.from_matrix(D[:3, :3]).as_rotvec()))
    return ang, float(np.max(np.linalg.norm(X @ D[:3, :3].T + D[:3, 3] - X, axis=1)))


@pytest.fixture(scope="module")
def good(nist):
    prep, P, N, masks = nist
    views, truths = _views(P, N, masks, seed=1)
    return views, truths, sv.inspect(prep, views, tolerance=0.1, min_coverage=0.9)


def test_six_views_from_no_start_give_right_poses_and_one_passing_part(nist, good):
    views, truths, res = good
    assert all(v.used for v in res.views)
    for v, p, T in zip(res.views, views, truths):
        ang, move = _pose_error(v.T_model_scan, T, p)
        assert ang < 0.05 and move < 0.05, (v.name, ang, move)
        # each view alone sees 43-50 % of the part: not enough for a verdict of the whole
        assert v.verdict == "incomplete" and v.coverage < 0.6, v
    assert res.coverage.fraction >= 0.9, res.coverage
    assert str(res.verdict) == "pass", res.reasons


def test_dent_seen_in_several_views_fails_the_part_with_one_region(nist, good):
    prep, P, N, masks = nist
    seen = np.logical_or.reduce(masks)
    # a point of the top face (normal +z, the highest plane) seen by the views
    top = seen & (N[:, 2] > 0.99) & (P[:, 2] > P[:, 2].max() - 1e-6)
    centre = P[np.flatnonzero(top)[len(np.flatnonzero(top)) // 2]]
    views, truths = _views(P, N, masks, seed=1, dent=(centre, 15.0, 0.4))
    # placed from the good part's poses (the same fixture), then refined view by view and jointly
    res = sv.inspect(prep, views, tolerance=0.1, min_coverage=0.9,
                     init=[v.T_model_scan for v in good[2].views])
    assert str(res.verdict) == "fail", res.reasons
    assert len(res.regions) == 1, res.regions
    assert np.linalg.norm(np.asarray(res.regions[0].centroid) - centre) < 10.0
    assert -0.45 < res.regions[0].extreme < -0.3


# -- the bunny: the views against each other, no CAD ------------------------------------------

def test_bunny_views_refined_against_each_other_agree_with_bun_conf(shared_data):
    """bun045 and bun090 started 2.3-2.9 deg and 2-6 mm off their bun.conf poses (bun000 held
    fixed) are refined against each other and bun000 only (``joint_refine`` with no CAD).

    bun.conf's poses are themselves the result of Stanford's ICP, not a ground truth: the
    refinement (every second point of each view) lands 0.07 deg / 0.06 mm (bun045) and 0.11 deg
    / 0.19 mm (bun090, centroid displacement) from them (all points: 0.07 / 0.04 and 0.13 /
    0.18), the same from every start.  Asserted: within 0.25 deg and 0.3 mm of bun.conf (below a
    quarter of the scans' 1.4 mm point spacing; about twice what is measured), and the same
    fixed point from two different starts (0.005 deg, 0.01 mm).
    """
    import partial_view_proxies as pv
    from shapeverify.inspection.regions import surface_spacing
    from shapeverify.inspection.views import joint_refine
    from shapeverify.io.points import read_points

    d = shared_data / "scans" / "bunny"
    pts = [read_points(d / n)[::2] * 1000.0 for n in pv.BUNNY_VIEWS]   # every 2nd point: CPU
    conf = [pv._bunny_pose(d, n) for n in pv.BUNNY_VIEWS]
    conf = [np.linalg.inv(conf[0]) @ C for C in conf]
    spacing = surface_spacing(pts[0][::4])
    rng = np.random.default_rng(0)
    found = []
    for _ in range(2):
        start = [conf[0]]
        for C in conf[1:]:
            E = np.eye(4)
            axis = rng.normal(size=3)
            E[:3, :3] = Rotation.from_rotvec(np.radians(rng.uniform(2.0, 3.0)) * axis
                                             / np.linalg.norm(axis)).as_matrix()
            ax = rng.normal(size=3)
            E[:3, 3] = rng.uniform(2.0, 6.0) * ax / np.linalg.norm(ax)
            start.append(E @ C)
        for i in (1, 2):
            assert _pose_error(start[i], conf[i], pts[i])[0] > 1.0
        T = joint_refine(pts, start, None, spacing, rounds=30, reach=5.0)   # coarse
        T = joint_refine(pts, T, None, spacing, rounds=10)                  # 2 spacings
        assert np.array_equal(T[0], conf[0])                                # held fixed
        for i in (1, 2):
            D = T[i] @ np.linalg.inv(conf[i])
            c = pts[i].mean(axis=0) @ conf[i][:3, :3].T + conf[i][:3, 3]
            ang = np.degrees(np.linalg.norm(Rotation.from_matrix(D[:3, :3]).as_rotvec()))
            assert ang < 0.25 and np.linalg.norm(D[:3, :3] @ c + D[:3, 3] - c) < 0.3, (i, ang)
        found.append(T)
    for T in found[1:]:
        for i in (1, 2):
            ang, move = _pose_error(T[i], found[0][i], pts[i][::50])
            assert ang < 0.005 and move < 0.01
