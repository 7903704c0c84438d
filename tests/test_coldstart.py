"""Cold start (issue 16 item 7): each kernel is compiled for one flavour of its arguments (no
literal-int copies), and the one flavour gives the same bits the several did."""

from __future__ import annotations

import numpy as np
import pytest

from shapeverify.cad import _kernels as K
from shapeverify.cad.examples import wavy_panel
from shapeverify.nearest import _surface_kernels as SK
from shapeverify.nearest.exact import power_tables


@pytest.fixture(scope="module")
def panel():
    return wavy_panel()


def _cached_flavours(dispatcher) -> list:
    """The argument types of every specialisation in the kernel's on-disk cache index (all the
    processes that used this cache since the source last changed; loaded kernels do not list
    their callees in ``dispatcher.signatures``)."""
    try:
        index = dispatcher._cache._cache_file._load_index()  # numba's cache internals
    except Exception as exc:  # noqa: BLE001
        pytest.skip(f"numba's cache index is not readable here: {exc}")
    if not index:
        pytest.skip("numba does not cache here (no index written)")
    return [key[0] for key in index]


def _literal(sig) -> bool:
    from numba.core import types

    return any(isinstance(t, types.Literal) for t in sig)


def test_surface_kernels_are_compiled_without_literal_degrees_or_orders(panel):
    from shapeverify.cad.nurbs import NurbsSurface

    rng = np.random.default_rng(3)
    surfaces = [panel.faces[0].surface]
    for p, q in ((2, 3), (4, 1)):
        nu, nv = p + 3, q + 4
        ku = np.concatenate([[0.0] * p, np.linspace(0, 1, nu - p + 1), [1.0] * p])
        kv = np.concatenate([[0.0] * q, np.linspace(0, 1, nv - q + 1), [1.0] * q])
        surfaces.append(NurbsSurface(p, q, ku, kv, rng.normal(size=(nu, nv, 3)),
                                     rng.uniform(0.5, 2, (nu, nv))))
    for s in surfaces:
        (u0, u1), (v0, v1) = s.domain
        for order in (0, 1, 2):
            for n in (10, 25_000):  # 25,000 took a copy compiled for degree 3 before
                s.derivatives(rng.uniform(u0, u1, n), rng.uniform(v0, v1, n), order)
    assert not hasattr(K, "surface_derivs_bicubic")
    for kernel in (K._surface_loop, K.taylor_table, K._basis_taylor):
        sigs = _cached_flavours(kernel)
        assert sigs and not any(_literal(s) for s in sigs), (kernel.__name__, sigs)


def test_exact_refinement_compiles_one_eval_call_and_its_orders_agree(panel):
    from shapeverify.nearest import prepare

    prep = prepare(panel, spacing=2.0)
    rng = np.random.default_rng(5)
    mp = prep.points
    idx = rng.integers(0, len(mp.points), 400)
    # near the surface, and beyond its free edges (the boundary path: newton_segment, order 1)
    lo, hi = panel.bounds
    q = np.vstack([mp.points[idx] + rng.normal(scale=0.5, size=(400, 3)),
                   rng.uniform(lo - 20, hi + 20, size=(200, 3))])
    c = prep.closest(q, exact=True)
    assert c.on_boundary.any()  # the boundary path ran
    # order 1 (the boundary path's last evaluation) gives order 2's S, Su, Sv to the bit
    tab = tuple(np.ascontiguousarray(t) for t in power_tables([f.surface for f in panel.faces]))
    for f in range(len(panel.faces)):
        (u0, u1), (v0, v1) = panel.faces[f].surface.domain
        for u, v in rng.uniform((u0, v0), (u1, v1), size=(20, 2)):
            d1 = SK._eval_call(tab, f, u, v, 1)
            d2 = SK._eval_call(tab, f, u, v, 2)
            assert d1[:9] == d2[:9] and d1[9:] == (0.0,) * 9
    # every flavour compiled since the source changed (refine_cad's and newton_segment's calls
    # too, in whichever process compiled them): one, with an int64 order
    sigs = _cached_flavours(SK._eval_call)
    assert len(sigs) == 1 and not _literal(sigs[0]), sigs
