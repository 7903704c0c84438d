"""The fast closest-point path (issue 18 item 1, issue 16 items 3/7): the vectorised ring of a
walk step, the named-tuple query kernel, and one compiled version of each query kernel.

Oracles: a plain numpy evaluation of the ring (same float64 operations), scipy's cKDTree for
the nearest model point, the kernel's own answers on one thread for two threads.
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from scipy.spatial import cKDTree

from shapeverify.cad.examples import wavy_panel
from shapeverify.nearest import _kernels as K
from shapeverify.nearest import load_prepared, prepare, set_workers
from shapeverify.nearest.dvg import views

FIELDS = ("points", "normals", "distances", "face", "uv", "index", "on_boundary")


@pytest.fixture(scope="module")
def panel():
    """The two-face wavy panel (120 x 90 mm) at 1 mm: about 11,000 model points."""
    return prepare(wavy_panel(), spacing=1.0, reach=4.0)


def _scan_like(prep, n, rng):
    """Model points moved sideways by up to a spacing and along the normal by up to 1.5 mm."""
    mp = prep.points
    i = rng.integers(0, len(mp), n)
    side = rng.uniform(-1, 1, (n, 2)) * prep.spacing
    return (mp.points[i] + side[:, :1] * mp.tangent_u[i] + side[:, 1:] * mp.tangent_v[i]
            + rng.uniform(-1.5, 1.5, (n, 1)) * mp.normals[i])


@njit(cache=True, nogil=True)
def _rings(Q, seeds, rf, rh, rs, out_k, out_d):
    for i in range(Q.shape[0]):
        k, d = K._ring(Q[i, 0], Q[i, 1], Q[i, 2], seeds[i], rf, rh, rs)
        out_k[i] = k
        out_d[i] = d


def test_vector_ring_is_bit_identical_to_the_scalar_ring(panel):
    """The 8-wide ring (one load, shuffles, float64 lanes) gives the very values and slot of
    ``for k: d = (r0 - s x)^2 + (r1 - s y)^2 + (r2 - s z)^2; first smallest``."""
    rng = np.random.default_rng(18)
    rf, _, rh, rs = views(panel._fast.rec)
    n = panel.n_points
    seeds = rng.integers(0, n, 20_000)
    # near the seed (the walk's case) and far from it (ties and large values)
    q = rf[seeds, :3] + rng.normal(0, 1.0, (seeds.size, 3)) * rng.choice([0.01, 1, 30], (seeds.size, 1))
    q = np.ascontiguousarray(q)
    k, d = np.empty(seeds.size, np.int64), np.empty(seeds.size)
    _rings(q, seeds, rf, rh, rs, k, d)
    s = rs[seeds, K.QSTEP].astype(np.float64)[:, None]
    off = rh[seeds, K.OFF:K.OFF + 3 * K.K].reshape(-1, K.K, 3).astype(np.float64)
    r = q - rf[seeds, :3]
    e0 = r[:, None, 0] - s * off[:, :, 0]
    e1 = r[:, None, 1] - s * off[:, :, 1]
    e2 = r[:, None, 2] - s * off[:, :, 2]
    ref = e0 * e0 + e1 * e1 + e2 * e2
    np.testing.assert_array_equal(k, np.argmin(ref, axis=1))
    np.testing.assert_array_equal(d, ref.min(axis=1))


def test_fast_answer_is_the_true_nearest_model_point_and_identical_on_two_threads(panel):
    """Scan-like, random and far queries: the nearest model point is cKDTree's (to 1e-9 mm)
    for >= 99.9 % of them and never farther than 0.05 spacings; the complete answer is
    identical on 1 and 2 threads (enough queries for two chunks)."""
    rng = np.random.default_rng(7)
    lo, hi = panel.points.points.min(axis=0) - 5, panel.points.points.max(axis=0) + 5
    q = np.concatenate([_scan_like(panel, 30_000, rng), rng.uniform(lo, hi, (6_000, 3)),
                        panel.points.points[:500] + rng.normal(0, 20, (500, 3))])
    d_kd, _ = cKDTree(panel.points.points).query(q)
    try:
        set_workers(1)
        one = panel.closest(q)
        set_workers(2)
        two = panel.closest(q)
    finally:
        set_workers(None)
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(one, f), getattr(two, f), err_msg=f)
    d_sv = np.linalg.norm(q - panel.points.points[one.index], axis=1)
    excess = d_sv - d_kd
    assert np.mean(excess <= 1e-9) >= 0.999
    assert excess.max() <= 0.05 * panel.spacing
    # the complete answer agrees with itself: |q - foot| = |distance|, unit normals
    np.testing.assert_allclose(np.linalg.norm(q - one.points, axis=1), np.abs(one.distances),
                               atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(one.normals, axis=1), 1.0, atol=1e-12)


def test_query_kernels_compile_once_for_prepared_loaded_and_read_only_input(panel, tmp_path):
    """A fresh prepare, ``prep.points`` (which freezes its arrays), a saved and loaded .svm
    (path and bytes) and read-only queries all use one compiled version of each kernel."""
    q = _scan_like(panel, 3000, np.random.default_rng(3))
    far = q[:50] + 40.0                        # beyond the reach: the kd-tree fallback
    frozen = np.concatenate([q, far])
    frozen.setflags(write=False)
    panel.closest(q)
    _ = panel.points
    a = panel.closest(frozen)
    panel._fast.nearest(frozen)
    panel.save(tmp_path / "p.svm")
    for loaded in (load_prepared(tmp_path / "p.svm"),
                   load_prepared((tmp_path / "p.svm").read_bytes())):
        _ = loaded.points
        b = loaded.closest(frozen)
        for f in FIELDS:
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    assert len(K.query_block.signatures) == 1, K.query_block.signatures
    assert len(K.answer_known.signatures) == 1, K.answer_known.signatures
    # callees: compiled (or loaded with their caller) at most once
    for kernel in (K.walk, K.leaf_nearest):
        assert len(kernel.signatures) <= 1, (kernel.__name__, kernel.signatures)
