"""CAD-regularised unwrapping (Paper V): steps larger than pi, approximate references, the loop."""

import numpy as np
import pytest
from scipy import optimize

from shapeverify.phase import (iterate_unwrap, unwrap, unwrap_with_reference, wrap)
from shapeverify.phase import UnwrapStop

TWO_PI = 2 * np.pi


def milled_trace(h=90, w=120, depth_fringes=3.4 / 2, shift=0.0):
    """A tilted, curved surface with a milled trace (a groove) of depth `depth_fringes` fringes.

    Phase in radians; the groove spans columns [40 + shift, 70 + shift).
    """
    y, x = np.mgrid[0:h, 0:w].astype(float)
    base = 0.12 * x + 0.05 * y + 4.0 * np.exp(-((x - 60 - shift) ** 2 + (y - 45) ** 2) / 900.0)
    groove = ((x >= 40 + shift) & (x < 70 + shift)) * (-TWO_PI * depth_fringes)
    return base + groove


def test_step_of_several_pi_recovered_with_reference_and_not_without():
    rng = np.random.default_rng(0)
    true = milled_trace()                                       # groove 3.4 pi deep
    psi = wrap(true + 0.15 * rng.standard_normal(true.shape))
    # without the reference the depth of the groove is lost (3.4 pi looks like -0.6 pi)
    for method in ("auto", "quality", "ls", "lp"):
        phi = unwrap(psi, method=method)
        d = phi - true
        assert abs(np.median(d[:, 45:65]) - np.median(d[:, :35])) > 3.0, method
    # an approximate reference: unknown 2 pi k offset, a smooth model error of up to ~1 rad
    y, x = np.mgrid[0:90, 0:120]
    ref = true + TWO_PI * 7 + 0.9 * np.sin(x / 25.0) * np.cos(y / 31.0)
    for method in ("auto", "quality", "ls", "wls", "lp", "nearest"):
        res = unwrap_with_reference(psi, ref, method=method)
        k = np.round((res.phase - true) / TWO_PI)
        assert np.all(k == 7), method                       # every pixel right, offset from ref
        assert res.far_fraction == 0.0
        assert np.allclose(np.round((res.phase - psi) / TWO_PI), (res.phase - psi) / TWO_PI)
    assert np.array_equal(unwrap(psi, reference=ref), unwrap_with_reference(psi, ref).phase)


def test_reference_with_pose_drift_needs_difference_unwrapping():
    # the reference is right up to a tilt of 3 fringes across the map (a pose error): the
    # pixel-wise method fails, unwrapping the difference recovers every pixel
    rng = np.random.default_rng(1)
    true = milled_trace(depth_fringes=2.6)
    psi = wrap(true + 0.2 * rng.standard_normal(true.shape))
    y, x = np.mgrid[0:90, 0:120]
    ref = true - TWO_PI * 3 * x / 120.0 + 1.0
    res = unwrap_with_reference(psi, ref)
    k = np.round((res.phase - true) / TWO_PI)
    assert len(np.unique(k)) == 1
    near = unwrap_with_reference(psi, ref, method="nearest")
    assert len(np.unique(np.round((near.phase - true) / TWO_PI))) > 1


def test_reference_places_separate_regions_and_tolerates_defects():
    rng = np.random.default_rng(2)
    true = milled_trace(depth_fringes=1.8)
    mask = np.ones(true.shape, bool)
    mask[:, 38:42] = False                                      # the groove's walls are not seen
    mask[:, 68:72] = False
    psi = wrap(true + 0.1 * rng.standard_normal(true.shape))
    psi[~mask] = np.nan
    # a local defect on the part (a bump of 5 rad the CAD model does not have)
    y, x = np.mgrid[0:90, 0:120]
    defect = 5.0 * np.exp(-((x - 100) ** 2 + (y - 20) ** 2) / 40.0)
    true_d = true + defect
    psi = wrap(true_d + 0.1 * rng.standard_normal(true.shape))
    res = unwrap_with_reference(psi, true + 0.3, mask=mask)
    assert len(res.offsets) == 3
    k = np.round((res.phase - true_d) / TWO_PI)[mask]
    assert np.all(k == 0)                      # three regions placed, the defect unwrapped too
    assert 0 < res.far_fraction < 0.01         # the defect's top deviates from the CAD by > pi
    # data-only unwrapping cannot relate the regions
    phi = unwrap(psi, mask=mask)
    kk = np.round((phi - true_d) / TWO_PI)[mask]
    assert len(np.unique(kk)) > 1


def test_misplaced_reference_step_only_spoils_the_strip():
    rng = np.random.default_rng(3)
    true = milled_trace(depth_fringes=1.35, shift=0.0)
    psi = wrap(true + 0.1 * rng.standard_normal(true.shape))
    ref = milled_trace(depth_fringes=1.35, shift=2.0)            # predicted edges 2 px off
    res = unwrap_with_reference(psi, ref)
    wrong = np.round((res.phase - true) / TWO_PI) != 0
    assert wrong.any()
    cols = np.unique(np.nonzero(wrong)[1])
    assert set(cols.tolist()) <= {40, 41, 70, 71}              # only the strips between edges


# --------------------------------------------------------------- the predict-unwrap-register loop

H, W = 60, 110
Y, X = np.mgrid[0:H, 0:W].astype(float)
STEP = 3.3 * np.pi


def scene_phase(t):
    """Phase of a part translated by t pixels along x: a smooth bump plus a 3.3 pi step."""
    return (3.0 * np.exp(-((X - 50 - t) ** 2 + (Y - 30) ** 2) / 300.0) + 0.02 * X
            + STEP * (X >= 60 + t))


def pose(t):
    T = np.eye(4)
    T[0, 3] = t
    return T


def make_callables(calls):
    def predict_phase(T):
        calls.append(float(T[0, 3]))
        return scene_phase(T[0, 3])

    def points_from_phase(phi):
        ok = np.isfinite(phi)
        return np.column_stack([X[ok], Y[ok], phi[ok]])

    def register(points):
        x, y, z = points.T

        def cost(t):                          # robust (capped) misfit to the model at shift t
            model = (3.0 * np.exp(-((x - 50 - t) ** 2 + (y - 30) ** 2) / 300.0) + 0.02 * x
                     + STEP * (x >= 60 + t))
            r = z - model
            r -= np.median(r)
            return np.sum(np.minimum(r * r, 1.0))

        grid = np.linspace(-8, 8, 161)
        t0 = grid[np.argmin([cost(t) for t in grid])]
        t = optimize.minimize_scalar(cost, bounds=(t0 - 0.1, t0 + 0.1), method="bounded",
                                     options={"xatol": 1e-9}).x
        return pose(t)

    return predict_phase, points_from_phase, register


def test_iterate_unwrap_converges_to_the_pose_and_the_exact_phase():
    rng = np.random.default_rng(4)
    t_true = 3.3
    true = scene_phase(t_true)
    psi = wrap(true + 0.1 * rng.standard_normal(true.shape))
    calls = []
    predict, points, register = make_callables(calls)
    # one regularised unwrapping at the wrong pose leaves the strip between the edges wrong
    first = unwrap_with_reference(psi, predict(pose(0.0)))
    assert np.any(np.round((first.phase - true) / TWO_PI) != 0)
    res = iterate_unwrap(psi, predict, points, register, pose(0.0),
                         stop=UnwrapStop(max_iterations=10))
    assert res.converged, res.message
    assert 2 <= res.iterations <= 6
    assert abs(res.T_model_scan[0, 3] - t_true) < 0.05
    assert np.all(np.round((res.phase - true) / TWO_PI) == 0)
    assert res.history[-1]["pixels_changed"] == 0
    assert res.history[0]["pixels_changed"] == -1
    assert "IterativeUnwrap(" in repr(res) and "converged=True" in repr(res)


def test_iterate_unwrap_rejects_bad_callables():
    psi = wrap(scene_phase(1.0))
    calls = []
    predict, points, register = make_callables(calls)
    with pytest.raises(ValueError, match="predict_phase returned shape"):
        iterate_unwrap(psi, lambda T: np.zeros((3, 3)), points, register, pose(0.0))
    with pytest.raises(ValueError, match="register"):
        iterate_unwrap(psi, predict, points, lambda p: np.eye(3), pose(0.0))
    with pytest.raises(ValueError, match="points_from_phase"):
        iterate_unwrap(psi, predict, lambda phi: phi, register, pose(0.0))
    with pytest.raises(ValueError, match="not seen"):
        iterate_unwrap(psi, lambda T: np.full((H, W), np.nan), points, register, pose(0.0))
    with pytest.raises(ValueError, match="T_model_scan"):
        iterate_unwrap(psi, predict, points, register, np.eye(3))


def test_reference_bad_input():
    psi = wrap(milled_trace())
    with pytest.raises(ValueError, match="reference shape"):
        unwrap(psi, reference=np.zeros((4, 4)))
    ref = milled_trace()
    ref[5, 5] = np.nan
    with pytest.raises(ValueError, match="reference has 1 NaN"):
        unwrap(psi, reference=ref)
    m = np.ones(psi.shape, bool)
    m[5, 5] = False
    assert np.isnan(unwrap(psi, reference=ref, mask=m)[5, 5])
    with pytest.raises(ValueError, match="unknown unwrapping method"):
        unwrap(psi, reference=milled_trace(), method="magic")
