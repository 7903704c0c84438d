"""CAD-regularised unwrapping as a sum of norms (thesis Ch. 4.2, issue 15 item 7a)."""

import numpy as np
import pytest

from shapeverify import phase
from shapeverify.phase.sum_of_norms import _difference_operator, unwrap_sum_of_norms

TWO_PI = 2 * np.pi


def _block_field(h=60, w=72):
    y, x = np.mgrid[0:h, 0:w].astype(float)
    base = 0.003 * (x - w / 2) ** 2 + 0.06 * y
    block = (x > 0.3 * w) & (x < 0.7 * w) & (y > 0.25 * h)
    return y, x, base + 7.5 * block                       # steps of 2.4 pi


def test_recovers_steps_larger_than_pi_from_an_approximate_model():
    y, x, true = _block_field()
    rng = np.random.default_rng(0)
    psi = phase.wrap(true + 0.3 * rng.standard_normal(true.shape))
    ref = true + 0.5 * np.sin(y / 11.0) + 0.4 * np.cos(x / 13.0) + 4 * np.pi
    res = unwrap_sum_of_norms(psi, ref)
    k = (res.phase - psi) / TWO_PI
    assert np.allclose(k, np.round(k), atol=1e-9)                  # congruent with the data
    assert np.array_equal(np.round((res.phase - true) / TWO_PI), np.full(true.shape, 2.0))
    assert res.converged
    # the data-only minimum norm cannot see the 2.4 pi steps
    lp = phase.unwrap(psi, method="lp")
    assert len(np.unique(np.round((lp - true) / TWO_PI))) > 1


def test_robust_cad_term_ignores_a_local_defect_not_in_the_model():
    y, x, true0 = _block_field(64, 64)
    dent = 4.0 * np.exp(-((x - 32) ** 2 + (y - 40) ** 2) / (2 * 4.0 ** 2))   # > pi deep
    true = true0 - dent
    psi = phase.wrap(true + 0.2 * np.random.default_rng(1).standard_normal(true.shape))
    res = unwrap_sum_of_norms(psi, true0)
    assert np.array_equal(np.round((res.phase - true) / TWO_PI), np.zeros(true.shape))
    # the pixel-wise nearest value puts the bottom of the dent on the wrong fringe
    near = phase.unwrap_with_reference(psi, true0, method="nearest").phase
    assert np.count_nonzero(np.round((near - true) / TWO_PI)) > 0


def test_p2_q2_objective_equals_the_closed_form_least_squares_minimum():
    rng = np.random.default_rng(2)
    psi = rng.uniform(-np.pi, np.pi, (9, 11))
    ref = rng.normal(0.0, 2.0, (9, 11))
    lam = 0.3
    res = unwrap_sum_of_norms(psi, ref, p=2.0, q=2.0, lam=lam, max_iter=1)
    D, ok, _ = _difference_operator(np.ones(psi.shape, bool))
    Dd = D.toarray()
    g = np.concatenate([phase.wrap(np.diff(psi, axis=1)).ravel(),
                        phase.wrap(np.diff(psi, axis=0)).ravel()])[ok]
    r = ref.ravel()
    xls = np.linalg.solve(Dd.T @ Dd + lam * np.eye(r.size), Dd.T @ g + lam * r)
    obj = np.sum((Dd @ xls - g) ** 2) + lam * np.sum((xls - r) ** 2)
    assert res.objective == pytest.approx(obj, rel=1e-8)
    assert np.allclose(res.phase.ravel(), psi.ravel() + TWO_PI * np.rint((xls - psi.ravel()) / TWO_PI))


def test_mask_and_bad_input():
    y, x, true = _block_field(40, 48)
    psi = phase.wrap(true)
    psi[5:9, 5:12] = np.nan
    res = unwrap_sum_of_norms(psi, true)
    assert np.all(np.isnan(res.phase[5:9, 5:12]))
    ok = np.isfinite(psi)
    assert np.allclose(res.phase[ok], true[ok])
    with pytest.raises(ValueError, match="p must be"):
        unwrap_sum_of_norms(psi, true, p=0.0)
    with pytest.raises(ValueError, match="lam"):
        unwrap_sum_of_norms(psi, true, lam=0.0)
    with pytest.raises(ValueError, match="reference shape"):
        unwrap_sum_of_norms(psi, true[:-1])
    with pytest.raises(ValueError, match="weights must be >= 0"):
        unwrap_sum_of_norms(psi, true, weights=-np.ones(true.shape))
