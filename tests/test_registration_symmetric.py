"""Symmetric parts (issue 14 item 3): a turned part's free spin is named, does not block
convergence, and a good turned part passes inspection."""

import warnings

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, _CIRCLE_KNOTS, _CIRCLE_W, _CIRCLE_XY
from shapeverify.nearest import prepare
from shapeverify.registration import DegenerateGeometryWarning, register
from shapeverify.simulate import random_motion, virtual_scan

#: (r, z) profile of a turned part (mm): bore 10, flange 40 x 30, shaft 25, chamfer to 20
PROFILE = np.array([[10, 0], [40, 0], [40, 30], [25, 30], [25, 70], [20, 75], [10, 75]], float)


def turned_part(profile=PROFILE) -> Model:
    """One exact NURBS face: the closed (r, z) polyline revolved about the z axis."""
    prof = np.vstack([profile, profile[:1]])
    m = len(prof)
    P = np.empty((9, m, 3))
    P[:, :, 0] = _CIRCLE_XY[:, 0, None] * prof[None, :, 0]
    P[:, :, 1] = _CIRCLE_XY[:, 1, None] * prof[None, :, 0]
    P[:, :, 2] = prof[None, :, 1]
    W = np.repeat(_CIRCLE_W[:, None], m, axis=1)
    seg = np.r_[0, np.cumsum(np.linalg.norm(np.diff(prof, axis=0), axis=1))]
    s = NurbsSurface(2, 1, _CIRCLE_KNOTS, np.r_[0, seg / seg[-1], 1], P, W)
    t = np.linspace(0, 1, 64, endpoint=False)
    loop = np.concatenate([np.c_[t, 0 * t], np.c_[1 + 0 * t, t], np.c_[1 - t, 1 + 0 * t],
                           np.c_[0 * t, 1 - t]])
    return Model(faces=(Face(s, (loop,), (np.zeros(len(loop), bool),)),), source="turned part")


@pytest.fixture(scope="module")
def turned():
    model = turned_part()
    return model, prepare(model, spacing=1.0)


def _two_views(model, motion, seed):
    """Front and back views of the part in one scan (one rigid motion), ~60 % of its area."""
    motion = random_motion(*motion, center=(0.0, 0.0, 40.0), rng=seed)
    a = virtual_scan(model, view=(1.0, 0.2, 0.5), pixel=1.0, noise=0.02, motion=motion, rng=seed)
    b = virtual_scan(model, view=(-1.0, -0.3, 0.5), pixel=1.0, noise=0.02, motion=motion,
                     rng=seed + 1)
    return a, b, np.vstack([a.scan, b.scan])


@pytest.mark.slow   # preparing the part: 5-30 s
@pytest.mark.parametrize("seed", [0, 1])
def test_turned_part_converges_with_its_spin_named(turned, seed):
    model, prep = turned
    a, _, _ = _two_views(model, (4.0, 4.0), seed)
    with pytest.warns(DegenerateGeometryWarning, match="1 pose direction"):
        reg = register(a.scan, prep)
    assert reg.converged, reg.message
    assert len(reg.undetermined) == 1 and reg.undetermined[0].startswith("rotation about axis")
    assert "[0.000, 0.000, 1.000]" in reg.undetermined[0].replace("-0.000", "0.000") or \
        "[0.000, 0.000, -1.000]" in reg.undetermined[0].replace("-0.000", "0.000")
    np.testing.assert_allclose(np.abs(reg.undetermined_directions[0, :3]), [0, 0, 1], atol=1e-6)
    assert reg.warnings == ()
    # the determined directions are right: every point lies on the part (the spin moves
    # points along the surface only)
    X = a.scan[a.inliers] @ reg.R.T + reg.t
    d = prep.closest(X, exact=True).distances
    assert np.sqrt(np.mean(d ** 2)) < 0.03
    # the axis itself is recovered: the truth's axis point and direction
    Tt = a.T_model_scan
    axis_scan = np.linalg.inv(Tt)[:3, :3] @ [0, 0, 1.0]
    np.testing.assert_allclose(reg.R @ axis_scan, [0, 0, 1.0], atol=2e-4)


@pytest.mark.slow
def test_good_turned_part_passes_inspection(turned):
    import shapeverify as sv

    model, prep = turned
    a, b, scan = _two_views(model, (3.0, 3.0), 5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sv.inspect(prep, scan, tolerance=0.5)
    assert res.registration.converged and len(res.registration.undetermined) == 1
    assert res.verdict == "pass", res.reasons
