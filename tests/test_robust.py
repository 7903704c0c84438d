"""One set of robust losses (issue 16): every implementation agrees with shapeverify.robust, and
the public IRLS regression (thesis Algorithm 3) finds the line through data with gross errors."""

from __future__ import annotations

import numpy as np
import pytest

from shapeverify import robust
from shapeverify.fitting import robust_weights as fitting_weights
from shapeverify.registration import _kernels
from shapeverify.registration.losses import get_loss as registration_get_loss

R = np.concatenate([np.linspace(-12.0, 12.0, 241), [0.0, 1e-9, 4.685, -1.345]])


def _numba(name, r, k):
    code = _kernels.LOSS_CODES[name]
    out = np.array([_kernels._rho_w(code, float(x), k) for x in r])
    return out[:, 0], out[:, 1]


IMPLEMENTATIONS = {
    "registration.losses": lambda name, r, sigma: (registration_get_loss(name).rho(r, sigma),
                                                   registration_get_loss(name).weight(r, sigma)),
    "registration numba kernel": lambda name, r, sigma: _numba(name, r, robust.get_loss(name).c * sigma),
    "fitting": lambda name, r, sigma: (None, fitting_weights(r, name, sigma)),
}


@pytest.mark.parametrize("impl", sorted(IMPLEMENTATIONS))
@pytest.mark.parametrize("name", sorted(robust.LOSSES))
def test_every_implementation_of_a_loss_agrees(impl, name):
    sigma = 1.3
    loss = robust.get_loss(name)
    rho, w = IMPLEMENTATIONS[impl](name, R, sigma)
    np.testing.assert_allclose(w, loss.weight(R, sigma), rtol=1e-12, atol=1e-15)
    if rho is not None:
        np.testing.assert_allclose(rho, loss.rho(R, sigma), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("name", sorted(robust.LOSSES))
def test_weight_is_rho_prime_over_r(name):
    loss, sigma = robust.get_loss(name), 0.7
    r = np.linspace(0.05, 6.0, 60)
    h = 1e-6
    d_rho = (loss.rho(r + h, sigma) - loss.rho(r - h, sigma)) / (2 * h)
    np.testing.assert_allclose(loss.weight(r, sigma), d_rho / r, rtol=1e-5, atol=1e-7)


def test_one_mad_constant():
    r = np.random.default_rng(0).normal(size=1001)
    assert robust.robust_scale(r) == robust.MAD_TO_SIGMA * np.median(np.abs(r))


@pytest.mark.parametrize("loss", ["huber", "tukey", "cauchy", "welsch"])
def test_robust_line_fit_ignores_gross_errors(loss):
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 100.0, 400)
    y = 0.5 * x - 3.0 + rng.normal(0.0, 0.05, x.size)
    bad = rng.choice(x.size, 60, replace=False)             # 15 % gross errors, all one way
    y[bad] += rng.uniform(5.0, 50.0, bad.size)
    fit = robust.robust_lstsq(np.column_stack([x, np.ones_like(x)]), y, loss=loss)
    ls = np.polyfit(x, y, 1)
    assert fit.converged
    tol = 0.02 if loss in ("tukey", "welsch") else 0.2      # redescending losses reject fully
    assert abs(fit.x[0] - 0.5) < tol / 10 and abs(fit.x[1] + 3.0) < tol
    assert abs(ls[1] + 3.0) > 1.0                           # least squares is pulled away
    if loss == "tukey":
        assert set(np.flatnonzero(fit.weights == 0)) == set(bad)


def test_robust_lstsq_rejects_bad_input():
    with pytest.raises(ValueError, match=r"\(N, p\)"):
        robust.robust_lstsq(np.ones((3, 2)), np.ones(4))
    with pytest.raises(ValueError, match="unknown loss"):
        robust.robust_lstsq(np.ones((3, 1)), np.ones(3), loss="tukee")
    with pytest.raises(ValueError, match="finite"):
        robust.robust_lstsq(np.ones((3, 1)), np.array([1.0, np.nan, 2.0]))
