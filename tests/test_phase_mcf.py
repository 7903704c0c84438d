"""Minimum-cost-flow unwrapping across faults (issue 18 item 6): solver exactness, fault fields."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import linprog

from shapeverify import phase
from shapeverify.phase import _flow, _kernels
from shapeverify.phase.fields import fault_field, smooth_field, wrong_fraction
from shapeverify.phase.network_flow import unwrap_mcf

TWO_PI = 2 * np.pi


def _loop_matrix(H, W):
    """Sparse (loops x edges) matrix: the change of each loop's charge per unit edge correction."""
    rows, cols, vals = [], [], []
    nh = H * (W - 1)
    for i in range(H):
        for j in range(W - 1):
            e = i * (W - 1) + j
            if i < H - 1:
                rows.append(i * (W - 1) + j), cols.append(e), vals.append(1)
            if i > 0:
                rows.append((i - 1) * (W - 1) + j), cols.append(e), vals.append(-1)
    for i in range(H - 1):
        for j in range(W):
            e = nh + i * W + j
            if j > 0:
                rows.append(i * (W - 1) + j - 1), cols.append(e), vals.append(1)
            if j < W - 1:
                rows.append(i * (W - 1) + j), cols.append(e), vals.append(-1)
    return sp.csr_matrix((vals, (rows, cols)), shape=((H - 1) * (W - 1), nh + (H - 1) * W))


@pytest.mark.parametrize("seed", [3, 5])
def test_min_cost_flow_equals_linear_programme(seed):
    # noisy fault field: hundreds of residues; random asymmetric costs
    f = fault_field((36, 44), sigma=0.9, rng=seed)
    H, W = f.psi.shape
    m = np.ones((H, W), bool)
    jumps = _kernels.edge_jumps(f.psi, m)
    q = _flow.loop_charges(jumps, H, W)
    assert np.count_nonzero(q[:-1]) > 50
    rng = np.random.default_rng(seed)
    E = H * (W - 1) + (H - 1) * W
    cp = rng.uniform(0.1, 3.0, E)
    cm = rng.uniform(0.1, 3.0, E)
    flow, n_aug, _ = _flow.min_cost_flow(q.copy(), cp, cm, H, W)
    A = _loop_matrix(H, W)
    assert np.array_equal(A @ flow + q[:-1], np.zeros(A.shape[0]))        # every residue cancelled
    lp = linprog(np.concatenate([cp, cm]), A_eq=sp.hstack([A, -A]), b_eq=-q[:-1], bounds=(0, None),
                 method="highs")
    ours = float(np.sum(np.where(flow > 0, cp * flow, -cm * flow)))
    assert lp.status == 0
    assert ours == pytest.approx(lp.fun, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("step,sigma", [(1.5 * np.pi, 0.8), (1.25 * np.pi, 0.8), (1.5 * np.pi, 0.4),
                                        (1.6 * np.pi, 0.0)])
def test_auto_unwraps_across_a_fault_that_path_following_crosses(step, sigma):
    f = fault_field(256, step=step, sigma=sigma)
    phi = phase.unwrap(f.psi)
    k = (phi - f.psi) / TWO_PI
    assert np.allclose(k, np.round(k), atol=1e-9)                       # congruent with the data
    assert wrong_fraction(phi, f.true) <= 0.003
    if sigma == 0.8 and step == 1.5 * np.pi:
        # the previous default (smoothing + reliability sorting) puts a region on the wrong fringe
        assert wrong_fraction(phase.unwrap(f.psi, method="filtered"), f.true) > 0.05


def test_cost_model_not_shortest_cut_decides_the_fault():
    # classical unit costs take the shortest way from the fault's residue to the border
    f = fault_field(256, step=1.5 * np.pi, sigma=0.0)
    assert wrong_fraction(unwrap_mcf(f.psi, cost="uniform"), f.true) > 0.2
    assert wrong_fraction(unwrap_mcf(f.psi), f.true) < 1e-3


def test_smooth_field_matches_filtered_and_is_exact_without_noise():
    f = smooth_field(200, sigma=0.0)
    phi = phase.unwrap(f.psi)
    assert np.allclose(phi - phi[0, 0], f.true - f.true[0, 0], atol=1e-9)
    f = smooth_field(200, sigma=0.8)
    assert wrong_fraction(phase.unwrap(f.psi), f.true) <= max(
        wrong_fraction(phase.unwrap(f.psi, method="filtered"), f.true), 2e-4)


def test_fault_with_mask_hole_and_nan():
    f = fault_field(192, step=1.5 * np.pi, sigma=0.5)
    y, x = np.mgrid[0:192, 0:192]
    mask = (x - 140) ** 2 + (y - 50) ** 2 > 20 ** 2
    psi = f.psi.copy()
    psi[~mask] = np.nan
    phi = phase.unwrap(psi)
    assert np.all(np.isnan(phi[~mask])) and np.all(np.isfinite(phi[mask]))
    assert wrong_fraction(phi, f.true, mask) <= 0.003
    assert np.array_equal(phi, phase.unwrap(psi), equal_nan=True)          # deterministic


def test_quality_scales_costs_and_bad_input_is_rejected():
    f = fault_field(96, step=1.5 * np.pi, sigma=0.3)
    q = np.ones(f.psi.shape)
    assert np.array_equal(unwrap_mcf(f.psi, quality=q), unwrap_mcf(f.psi))
    with pytest.raises(ValueError, match="quality must be >= 0"):
        unwrap_mcf(f.psi, quality=-q)
    with pytest.raises(ValueError, match="beta"):
        unwrap_mcf(f.psi, beta=0.0)
    with pytest.raises(ValueError, match="window"):
        unwrap_mcf(f.psi, window=4)
    with pytest.raises(ValueError, match="cost"):
        unwrap_mcf(f.psi, cost="l2")
    with pytest.raises(ValueError, match="tip"):
        fault_field(64, tip=(0.5, 1.2))


def test_steep_fault_staircase_corners_are_cut_along_the_fault():
    # a fault at ~70 degrees: the cut is a staircase whose corner edges see no step in their own
    # boxes; corner relief keeps the cut on the fault instead of a short way to the border
    f = fault_field(256, step=1.5 * np.pi, sigma=0.4, rng=2, tip=(0.9, 0.3), start_row=0.05)
    assert wrong_fraction(unwrap_mcf(f.psi, corners=False), f.true) > 0.004
    assert wrong_fraction(unwrap_mcf(f.psi), f.true) < 0.002
