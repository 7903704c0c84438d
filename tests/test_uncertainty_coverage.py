"""The stated U (k = 2) covers the error in most runs (issue 27 item 6): a 20-run Monte-Carlo
version of ``benchmarks/check_uncertainty.py`` (200 runs, results_uncertainty.md).

The bundled panel is a sheet: its Ø36 hole is seen only at its rim.  Scans made independently
of the project's sampler (OpenCASCADE's tessellation sampled uniformly by area, 1 mm, 0.02 mm
noise along the normal), measured at the true pose as the plan's hole characteristic measures
(:func:`measure_hole` with the closest CAD points).  Before the largest-empty-circle estimator
the diameter read -0.39 .. +0.26 mm at 1 mm (the +0.255 of issue 27's held-back panel).

Threshold: with U right (95.45 % coverage) the number of covering runs of 20 is binomial; the
check accepts from its 1 % quantile (16 of 20, :func:`uncertainty_runs.min_coverage_count`), so
a right U fails it with a probability of 0.3 %.
"""
from __future__ import annotations

import numpy as np
import pytest

import independent_scans as isc
from uncertainty_runs import min_coverage_count

pytestmark = pytest.mark.slow
RUNS = 20


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    from shapeverify.cad.examples import example_part_step
    from shapeverify.characteristics.features import model_features

    path = example_part_step(tmp_path_factory.mktemp("panel") / "panel.step")
    from model_cache import cached_prepared

    prep = cached_prepared(path, spacing=1.0)  # built once per run (tests/model_cache.py)
    V, T, _ = isc.tessellate(isc.read_shape(path), 0.005)
    f = [g for g in model_features(prep.model) if g.kind == "hole"][0]
    near = np.linalg.norm(V[T].mean(axis=1)[:, :2] - f.center[:2], axis=1) < 0.5 * f.diameter + 30
    return prep, V, T[near], f


@pytest.mark.parametrize("sampler", ["random", "grid"])
def test_rim_only_hole_U_covers_diameter_and_position_error(panel, sampler):
    from shapeverify.characteristics.holes import measure_hole, position_coverage

    prep, V, T, f = panel
    kc = position_coverage(2.0)
    cov_d, cov_p, errs = [], [], []
    for seed in range(RUNS):
        rng = np.random.default_rng(500 + seed)
        X = isc.scan(V, T, sampler, 1.0, rng, noise=0.02)
        cl = prep.closest(X, exact=True)
        hm = measure_hole(X, f.center, f.axis, f.diameter, face=prep.model.faces[f.face],
                          deviations=cl.distances, normals=cl.normals)
        assert hm.method == "empty circle", hm.method
        dd = hm.diameter - f.diameter
        d = hm.center - f.center
        pos = float(np.linalg.norm(d - (d @ f.axis) * f.axis))
        errs.append((dd, pos))
        cov_d.append(abs(dd) <= 2.0 * hm.u_diameter)
        # the plan's position: value 2 |offset|, U = 2 k_2D u (a 2-D offset, holes.position_coverage)
        cov_p.append(2.0 * pos <= 2.0 * kc * hm.u_center)
    need = min_coverage_count(RUNS)
    assert sum(cov_d) >= need and sum(cov_p) >= need, (sum(cov_d), sum(cov_p), need, errs)
    # and the diameter error is small at 1 mm (it was -0.39 .. +0.26 mm); the position's largest
    # empty circle has a heavier tail (up to 0.15 mm in 30 runs, benchmarks/results_uncertainty)
    e = np.array(errs)
    assert np.abs(e[:, 0]).max() <= 0.1, e
