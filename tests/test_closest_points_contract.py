"""The ClosestPoints contract over three implementations (issue 31 items 4 and 6; scipy.spatial's
``kdtree_type`` fixture is the model): the DVG tree (:class:`shapeverify.nearest.Prepared`, fast
answers and exact on request), the exact mode on its own
(:class:`shapeverify.nearest.protocol.ExactSearch`) and a kd-tree adapter
(``tests/kdtree_closest.py``: scipy's cKDTree and the same tangent-patch projection, written
again in numpy).  Registration and inspection must work through the protocol alone: the same
registration and deviation contract holds for each, against the simulated scan's true pose and
the exact NURBS surface (points sampled on it and offset along its normal by known amounts).
"""

from __future__ import annotations

import numpy as np
import pytest

from kdtree_closest import KDTreeClosest
from shapeverify.nearest.protocol import (PROTOCOL_ATTRIBUTES, ClosestPoints, ExactSearch,
                                          missing_attributes)

SPACING = 2.0
#: worst signed-distance error (mm) of each implementation's answers to ``closest(X,
#: exact=True)`` (what the inspection's deviations use) on the wavy panel: refined on the NURBS
#: for the tree and the exact mode; the tangent-patch projection (curvature 0.01 /mm, patches of
#: about 1 mm half width) for the kd-tree adapter
DEVIATION_ERROR = {"dvg": 1e-6, "exact": 1e-6, "kdtree": 0.02}


@pytest.fixture(scope="module")
def prep():
    import shapeverify as sv
    from shapeverify.cad.examples import wavy_panel

    return sv.prepare(wavy_panel(), spacing=SPACING)


@pytest.fixture(scope="module", params=["dvg", "exact", "kdtree"])
def closest_points(request, prep):
    """One implementation of the protocol (as scipy's ``kdtree_type``)."""
    impl = {"dvg": lambda: prep, "exact": lambda: ExactSearch(prep),
            "kdtree": lambda: KDTreeClosest(prep)}[request.param]()
    return request.param, impl


@pytest.fixture(scope="module")
def surface(prep):
    """Points on the exact surface, off its free edges, with their true outward normals."""
    mp = prep.model.sample(3.0, rng=5)
    keep = ~np.asarray(mp.boundary, bool)
    P, N = np.asarray(mp.points)[keep], np.asarray(mp.normals)[keep]
    inner = (P[:, 0] > 5) & (P[:, 0] < 115) & (P[:, 1] > 5) & (P[:, 1] < 85)
    return P[inner], N[inner]


def test_each_implementation_has_every_protocol_attribute(closest_points):
    name, impl = closest_points
    assert isinstance(impl, ClosestPoints), name
    assert missing_attributes(impl) == [], name
    assert impl.n_points == len(impl.points.points)
    assert impl.points is impl.points               # the same object on every access
    q = np.array([[60.0, 45.0, 5.0], [10.0, 80.0, -3.0], [200.0, 0.0, 0.0]])
    for exact in (False, True):
        c = impl.closest(q, exact=exact)
        assert c.points.shape == (3, 3) and c.normals.shape == (3, 3) and c.uv.shape == (3, 2)
        assert c.distances.shape == c.face.shape == c.index.shape == c.on_boundary.shape == (3,)
        assert c.index.dtype == np.int64 and c.on_boundary.dtype == np.bool_
        assert np.all((c.index >= 0) & (c.index < impl.n_points))
        np.testing.assert_allclose(np.linalg.norm(q - c.points, axis=1), np.abs(c.distances),
                                   rtol=1e-6)
        np.testing.assert_allclose(np.linalg.norm(c.normals, axis=1), 1.0, rtol=1e-6)
        assert bool(c.on_boundary[2])                # far past the panel's free edge
    with pytest.raises(ValueError):
        impl.closest(np.array([[0.0, np.nan, 0.0]]))


def test_protocol_names_what_registration_and_inspection_read():
    """The documented attributes are the protocol's (docs/internals.md lists the same)."""
    from pathlib import Path

    doc = (Path(__file__).parents[1] / "docs" / "internals.md").read_text()
    section = doc[doc.index("## The ClosestPoints protocol"):]
    section = section[:section.index("\n## ", 5)]
    import re

    listed = re.findall(r"^    ([a-z_]+)[:(]", section, re.M)
    assert listed == list(PROTOCOL_ATTRIBUTES), listed


def test_deviations_contract(closest_points, surface):
    """Signed deviations of points offset along the true normal by known amounts: each
    implementation within its error (:data:`DEVIATION_ERROR`), with the sign."""
    from shapeverify.inspection import deviations

    name, impl = closest_points
    P, N = surface
    delta = np.random.default_rng(2).uniform(-0.5, 0.5, len(P))
    dev = deviations(P + delta[:, None] * N, impl, np.eye(4), 1.0)
    assert dev.n_evaluated == len(P), name
    err = np.abs(dev.values - delta)
    assert err.max() < DEVIATION_ERROR[name], (name, err.max())


def test_kdtree_adapter_reproduces_the_dvg_fast_answers(prep):
    """The adapter is an independent search with the same projection: where both find the
    same nearest model point, the fast answers are the same to the storage's precision."""
    kd = KDTreeClosest(prep)
    q = np.random.default_rng(3).uniform([0, 0, -4], [120, 90, 8], (4000, 3))
    a, b = prep.closest(q), kd.closest(q)
    same = a.index == b.index
    assert same.mean() > 0.99
    d_near = np.linalg.norm(q - prep.points.points[a.index], axis=1)
    d_kd = np.linalg.norm(q - prep.points.points[b.index], axis=1)
    assert np.all(d_near <= d_kd + 1e-9)        # where they differ: ties, never a worse point
    np.testing.assert_allclose(a.distances[same], b.distances[same], atol=1e-6)
    np.testing.assert_allclose(a.points[same], b.points[same], atol=1e-6)
    assert np.array_equal(a.on_boundary[same], b.on_boundary[same])


@pytest.mark.slow
def test_registration_contract(closest_points, prep):
    """ICP from the identity finds the simulated scan's true pose through each implementation:
    the scan points land within 0.02 mm RMS of where the true pose puts them."""
    from shapeverify.registration import register
    from shapeverify.simulate import ScanEffects, virtual_scan

    name, impl = closest_points
    vs = virtual_scan(prep.model, pixel=2.0, noise=0.02, motion=(2.0, 1.5), rng=4)
    reg = register(vs.scan, impl, init=np.eye(4))
    assert reg.converged, (name, reg.message)
    T, Tt = np.asarray(reg.T_model_scan), vs.T_model_scan
    X = vs.scan
    shift = np.sqrt(np.mean(np.sum((X @ T[:3, :3].T + T[:3, 3] - X @ Tt[:3, :3].T - Tt[:3, 3])
                                   ** 2, axis=1)))
    assert shift < 0.02, (name, shift)


@pytest.mark.slow
def test_inspection_contract(closest_points, prep):
    """The whole inspection through each implementation: a 0.5 mm dent (radius 12 mm) in a
    scan with 0.02 mm noise fails the part as one region about 0.5 mm deep, the panel fully
    seen."""
    import warnings

    import shapeverify as sv
    from shapeverify.simulate import ScanEffects, virtual_scan

    name, impl = closest_points
    vs = virtual_scan(prep.model, pixel=1.0, noise=0.02, motion=(2.0, 1.5),
                      effects=ScanEffects(dents=[(0.5, 12.0)]), rng=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sv.inspect(impl, vs.scan, tolerance=0.2, init=np.eye(4))
    assert (str(res.verdict), res.rule, len(res.regions)) == ("fail", "regions", 1), name
    assert abs(res.regions[0].extreme + 0.5) < 0.05, (name, res.regions[0].extreme)
    assert res.coverage.fraction > 0.95, name
