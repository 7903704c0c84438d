"""Phase unwrapping core: wrap conventions, 1-D, path following, minimum norm, masks, bad input."""

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from shapeverify import phase
from shapeverify.phase import (residues, unwrap, unwrap_1d, unwrap_filtered, unwrap_lp, unwrap_ls,
                               unwrap_quality, unwrap_wls, wrap)

TWO_PI = 2 * np.pi


def offset_multiple(phi, true, where=None):
    """The constant k with phi == true + 2 pi k on `where`; asserts it is one constant."""
    d = (phi - true) if where is None else (phi - true)[where]
    k = np.round(d / TWO_PI)
    assert np.allclose(d, TWO_PI * k, atol=1e-9), "result is not congruent with the truth"
    ks = np.unique(k)
    return ks


def wrong_fraction(phi, true, where=None):
    """Fraction of pixels whose 2 pi multiple differs from the most common one."""
    d = (phi - true) if where is None else (phi - true)[where]
    k = np.round(d / TWO_PI)
    vals, counts = np.unique(k, return_counts=True)
    return 1.0 - counts.max() / k.size


def smooth_field(h=96, w=112, scale=1.0):
    y, x = np.mgrid[0:h, 0:w].astype(float)
    return scale * (12 * np.exp(-((x - 0.6 * w) ** 2 + (y - 0.4 * h) ** 2) / (2 * (0.25 * w) ** 2))
                    + 0.08 * x - 0.05 * y + 3 * np.sin(x / 17.0) * np.cos(y / 23.0))


# ------------------------------------------------------------------ wrap conventions (eqs. 1-2)

def test_wrap_eq1_eq2_ranges_and_boundary():
    x = np.linspace(-40, 40, 100_001)
    w1 = wrap(x)
    w2 = wrap(x, convention="modulo")
    assert w1.min() > -np.pi and w1.max() <= np.pi
    assert w2.min() >= -np.pi and w2.max() < np.pi
    # congruent with the input
    for w in (w1, w2):
        k = (x - w) / TWO_PI
        assert np.allclose(k, np.round(k), atol=1e-9)
    # eq. (1) equals atan2(sin, cos) away from the boundary; eq. (1) and (2) agree there too
    away = np.abs(np.abs(w1) - np.pi) > 1e-6
    assert np.allclose(w1[away], np.arctan2(np.sin(x[away]), np.cos(x[away])), atol=1e-9)
    assert np.allclose(w1[away], w2[away], rtol=0, atol=1e-12)
    # the boundary: pi + 2 pi n -> pi (eq. 1) and -pi (eq. 2)
    b = np.pi + TWO_PI * np.arange(-3, 4)
    assert np.all(wrap(b) == np.pi)
    assert np.all(wrap(b, convention="modulo") == -np.pi)
    assert float(wrap(-np.pi)) == np.pi
    assert np.isnan(wrap(np.nan))
    with pytest.raises(ValueError, match="convention"):
        wrap(1.0, convention="degrees")


# ------------------------------------------------------------------ 1-D (thesis Ch. 4.1)

def test_unwrap_1d_matches_numpy_and_thesis_figures():
    rng = np.random.default_rng(0)
    u = np.linspace(0, 1, 400)
    phi = 6 * np.pi * u ** 2 + 0.3 * np.sin(20 * u)                  # Fig. 6: continuous
    out = unwrap_1d(wrap(phi))
    assert np.allclose(out - out[0], phi - phi[0])
    psi = rng.uniform(-np.pi, np.pi, 300)
    assert np.allclose(unwrap_1d(psi), np.unwrap(psi))
    # Fig. 7: a jump larger than pi is lost (the result differs from the original after it)
    jump = phi + np.where(u > 0.5, 1.3 * np.pi, 0.0)
    out = unwrap_1d(wrap(jump))
    d = out - jump
    assert np.isclose(d[-1] - d[0], -TWO_PI)
    for bad in (np.zeros((3, 3)), np.array([]), np.array([0.0, np.nan])):
        with pytest.raises(ValueError):
            unwrap_1d(bad)


# ------------------------------------------------------------------ property: unwrap(wrap(x)) = x + 2 pi k

@st.composite
def smooth_fields(draw):
    h = draw(st.integers(8, 40))
    w = draw(st.integers(8, 40))
    c = draw(st.lists(st.floats(-1, 1), min_size=6, max_size=6))
    amp = draw(st.floats(0.5, 40.0))
    y, x = np.mgrid[0:h, 0:w].astype(float)
    u, v = x / w, y / h
    f = amp * (c[0] * u + c[1] * v + c[2] * u * v + c[3] * u ** 2 + c[4] * v ** 2
               + c[5] * np.sin(3 * u + 2 * v))
    offset = draw(st.floats(-100, 100))
    return f + offset


@pytest.mark.parametrize("method", ["auto", "quality", "ls", "wls"])
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(field=smooth_fields())
def test_unwrap_wrap_is_identity_up_to_constant(method, field):
    gx = np.abs(np.diff(field, axis=1)).max()
    gy = np.abs(np.diff(field, axis=0)).max()
    assume(max(gx, gy) < 0.9 * np.pi)          # smooth: every neighbour difference below pi
    phi = unwrap(wrap(field), method=method)
    ks = offset_multiple(phi, field)
    assert len(ks) == 1


# ------------------------------------------------------------------ path following

def test_quality_path_following_exact_and_uses_quality_map():
    true = smooth_field()
    psi = wrap(true)
    assert np.count_nonzero(residues(psi)) == 0
    for f in (unwrap_quality, unwrap_filtered):
        assert len(offset_multiple(f(psi), true)) == 1
    # a user quality map is accepted and, on residue-free data, changes nothing
    q = np.random.default_rng(1).random(true.shape)
    assert len(offset_multiple(unwrap_quality(psi, quality=q), true)) == 1


def test_pseudo_correlation_quality_map():
    rng = np.random.default_rng(8)
    psi = np.full((20, 30), 1.0)
    psi[:, 15:] = rng.uniform(-np.pi, np.pi, (20, 15))
    q = phase.pseudo_correlation(psi, window=3)
    assert np.allclose(q[:, :13], 1.0)
    assert q[:, 17:].mean() < 0.5
    m = np.ones(psi.shape, bool)
    m[0, 0] = False
    assert phase.pseudo_correlation(psi, mask=m)[0, 0] == 0.0
    with pytest.raises(ValueError, match="window"):
        phase.pseudo_correlation(psi, window=2)


def test_residues_of_a_vortex():
    y, x = np.mgrid[0:21, 0:21].astype(float)
    psi = np.arctan2(y - 10.5, x - 9.5)       # one phase singularity inside loop (10, 9)
    r = residues(psi)
    assert np.count_nonzero(r) == 1 and abs(int(r[10, 9])) == 1


def test_agreement_with_scikit_image_on_noisy_fields():
    skr = pytest.importorskip("skimage.restoration")
    rng = np.random.default_rng(2)
    true = smooth_field(160, 176, scale=2.0)
    # moderate noise: both methods get every pixel right -> identical up to a constant
    psi = wrap(true + 0.5 * rng.standard_normal(true.shape))
    ours = unwrap(psi)
    sk = skr.unwrap_phase(psi)
    assert np.count_nonzero(residues(psi)) > 0
    assert len(offset_multiple(ours, sk)) == 1
    assert len(offset_multiple(unwrap_quality(psi), sk)) == 1
    # heavy noise: the default is at least as good as scikit-image against the truth
    psi = wrap(true + 0.9 * rng.standard_normal(true.shape))
    ours_wrong = wrong_fraction(unwrap(psi), true)
    sk_wrong = wrong_fraction(skr.unwrap_phase(psi), true)
    assert ours_wrong <= sk_wrong
    assert ours_wrong < 5e-3


def test_auto_handles_steps_below_pi_and_dense_fringes():
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:150, 0:160].astype(float)
    # a 2.8 rad step (less than pi: recoverable from the data) under noise
    true = 0.05 * x + 8 * np.exp(-((x - 80) ** 2 + (y - 75) ** 2) / 2000) + 2.8 * (x > 80)
    psi = wrap(true + 0.6 * rng.standard_normal(true.shape))
    assert wrong_fraction(unwrap(psi), true) == 0.0
    assert wrong_fraction(unwrap(psi), true) <= wrong_fraction(unwrap_quality(psi), true)
    # fringes too dense to smooth (2 rad/pixel): auto uses the raw residues (no smoothing) and
    # agrees with plain reliability sorting up to a constant
    true = 2.0 * x + 0.6 * y
    psi = wrap(true + 0.3 * rng.standard_normal(true.shape))
    assert len(offset_multiple(unwrap(psi), unwrap_quality(psi))) == 1
    assert wrong_fraction(unwrap(psi), true) < 1e-3


def test_masks_regions_and_nan():
    true = smooth_field(100, 120)
    y, x = np.mgrid[0:100, 0:120]
    mask = ((x - 60) ** 2 + (y - 50) ** 2 > 15 ** 2)             # annulus-like: hole in the middle
    rng = np.random.default_rng(3)
    psi = wrap(true)
    psi[~mask] = rng.uniform(-np.pi, np.pi, (~mask).sum())       # garbage in the hole
    for method in phase.METHODS[:-1]:
        phi = unwrap(psi, method=method, mask=mask)
        assert np.all(np.isnan(phi[~mask])) and np.all(np.isfinite(phi[mask]))
        assert len(offset_multiple(phi, true, mask)) == 1, method
    # NaN pixels with mask=None are masked (and never hang)
    psin = psi.copy()
    psin[~mask] = np.nan
    phi = unwrap(psin)
    assert np.array_equal(np.isnan(phi), ~mask)
    assert len(offset_multiple(phi, true, mask)) == 1
    # two regions separated by a masked column: each correct up to its own constant
    m2 = np.ones_like(mask)
    m2[:, 55:58] = False
    phi = unwrap_quality(wrap(true), mask=m2)
    assert len(offset_multiple(phi[:, :55], true[:, :55])) == 1
    assert len(offset_multiple(phi[:, 58:], true[:, 58:])) == 1


# ------------------------------------------------------------------ minimum-norm methods

def test_least_squares_recovers_smooth_field():
    true = smooth_field(64, 80)
    psi = wrap(true)
    for f in (unwrap_ls, unwrap_wls, unwrap_lp):
        assert len(offset_multiple(f(psi), true)) == 1, f.__name__
    # the non-congruent LS solution of consistent gradients is the field itself (+ constant)
    smooth = unwrap_ls(psi, congruent=False)
    d = smooth - true
    assert np.allclose(d, d.mean(), atol=1e-8)
    # weights are accepted and do not change a consistent solution
    w = 0.2 + np.random.default_rng(4).random(true.shape)
    smooth_w = unwrap_wls(psi, weights=w, congruent=False, tol=1e-10)
    assert np.allclose(smooth_w - true, (smooth_w - true).mean(), atol=1e-6)


def test_dct_poisson_solver_solves_neumann_laplacian():
    from shapeverify.phase._kernels import weighted_laplacian
    rng = np.random.default_rng(5)
    rho = rng.standard_normal((23, 31))
    rho -= rho.mean()
    phi = phase.solve_poisson_dct(rho)
    lap = weighted_laplacian(phi, np.ones((23, 30)), np.ones((22, 31)), np.empty((23, 31)))
    assert np.allclose(lap, rho, atol=1e-12)


def test_weighted_beats_unweighted_on_a_corrupt_patch():
    true = smooth_field(96, 96)
    y, x = np.mgrid[0:96, 0:96]
    bad = (np.abs(x - 30) < 6) & (np.abs(y - 55) < 10)
    psi = wrap(true)
    psi[bad] = np.random.default_rng(6).uniform(-np.pi, np.pi, bad.sum())
    good = ~bad
    ls_wrong = wrong_fraction(unwrap_ls(psi), true, good)
    wls_wrong = wrong_fraction(unwrap_wls(psi, weights=good.astype(float)), true, good)
    assert ls_wrong > 0                # LS smears the patch's residues over its surroundings
    assert wls_wrong == 0.0


def test_minimum_lp_norm_beats_least_squares_on_a_tear():
    # a discontinuity that ends inside the field: the jump grows from 0 (row 90) to 5 rad (row 0);
    # where it exceeds pi the wrapped gradients are wrong and a residue sits at its tip
    h, w = 120, 120
    y, x = np.mgrid[0:h, 0:w].astype(float)
    true = 0.05 * x + 0.03 * y + np.clip(5.0 * (90 - y) / 90, 0, None) * (x >= 60)
    psi = wrap(true)
    assert np.count_nonzero(residues(psi)) == 1
    ls_wrong = wrong_fraction(unwrap_ls(psi), true)
    lp_wrong = wrong_fraction(unwrap_lp(psi), true)
    assert ls_wrong > 0.01
    assert lp_wrong == 0.0
    assert wrong_fraction(unwrap_lp(psi, p=1.0), true) < ls_wrong


# ------------------------------------------------------------------ bad input

def test_bad_input_raises_clear_errors():
    psi = wrap(smooth_field(20, 30))
    with pytest.raises(ValueError, match="2-D"):
        unwrap(psi[0])
    with pytest.raises(ValueError, match="2-D"):
        unwrap(np.stack([psi, psi]))
    with pytest.raises(ValueError, match="mask shape"):
        unwrap(psi, mask=np.ones((30, 20), bool))
    p = psi.copy()
    p[3, 4] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        unwrap(p, mask=np.ones_like(psi, bool))            # NaN where the mask says valid
    m = np.ones_like(psi, bool)
    m[3, 4] = False
    assert np.isnan(unwrap(p, mask=m)[3, 4])                # NaN outside the mask is fine
    p[5, 5] = np.inf
    with pytest.raises(ValueError, match="infinite"):
        unwrap(p)
    with pytest.raises(ValueError, match="no valid pixel"):
        unwrap(psi, mask=np.zeros_like(psi, bool))
    with pytest.raises(ValueError, match="no valid pixel"):
        unwrap(np.full((5, 5), np.nan))
    with pytest.raises(ValueError, match="unknown unwrapping method"):
        unwrap(psi, method="snaphu")
    with pytest.raises(ValueError, match="needs a reference"):
        unwrap(psi, method="nearest")
    with pytest.raises(ValueError, match="unweighted"):
        unwrap(psi, method="ls", quality=np.ones_like(psi))
    with pytest.raises(ValueError, match="quality shape"):
        unwrap(psi, quality=np.ones((3, 3)))
    with pytest.raises(ValueError, match=">= 0"):
        unwrap(psi, method="wls", quality=-np.ones_like(psi))
    with pytest.raises(ValueError, match="boolean"):
        unwrap(psi, mask=np.full(psi.shape, 0.5))
    with pytest.raises(ValueError, match="real-valued"):
        unwrap(psi.astype(complex))
    with pytest.raises(ValueError, match="window"):
        unwrap_filtered(psi, window=4)
    with pytest.raises(ValueError, match="p must be"):
        unwrap_lp(psi, p=2.0)
