"""A Fortran-ordered phase map compiles nothing (issue 32 item 3): ``shapeverify unwrap`` of a
``.npy`` written in Fortran order (MATLAB, ``np.asfortranarray``) compiled
``weighted_divergence`` and ``weighted_laplacian`` again after the warm-up (methods ls, wls,
lp): the map kept its order through the boundary's ``astype`` and reached the kernels as an
F-ordered array, which numba compiles apart from a C-ordered one.  The boundary
(``check_phase_map``, ``check_map_like``) now hands the kernels C-ordered float64.

Checked two ways: no compile event in the call, and -- as an F-ordered overload compiled once
is cached and then loads without compiling -- the call gave no kernel of the phase package a
non-C-ordered array (the signatures numba's dispatchers hold in this process, before and
after)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from shapeverify.phase import unwrap, wrap
from shapeverify.phase.regularised import DATA_METHODS
from shapeverify.warmup import compile_notices


def _maps():
    y, x = np.mgrid[0:37, 0:45]
    true = 0.006 * (x - 20.0) ** 2 + 0.004 * (y - 15.0) ** 2 + 0.1 * x
    mask = np.ones(true.shape, bool)
    mask[:5, :7] = False
    quality = 0.5 + 0.5 * np.cos(0.1 * x) ** 2
    return true, wrap(true), mask, quality


def _non_c_signatures() -> set:
    """(kernel, signature) of every phase kernel called in this process with an array that is
    not C-ordered (numba's layout 'F' or 'A')."""
    got = set()
    for name, mod in list(sys.modules.items()):
        if not name.startswith("shapeverify.phase") or mod is None:
            continue
        for attr, obj in list(vars(mod).items()):
            if hasattr(obj, "py_func") and hasattr(obj, "signatures"):
                for sig in obj.signatures:
                    if any(getattr(t, "layout", "C") != "C" for t in sig):
                        got.add((f"{name}.{attr}", str(sig)))
    return got


@pytest.mark.parametrize("masked", [False, True])
@pytest.mark.parametrize("method", sorted(DATA_METHODS))
def test_a_fortran_ordered_phase_map_compiles_no_kernel_the_c_ordered_one_did_not(method, masked):
    true, psi, mask, quality = _maps()
    if not masked:
        mask = np.ones(psi.shape, bool)
    extra = {} if DATA_METHODS[method][1] is None else {"quality": quality}
    given = mask if masked else None           # the command line without --mask: None
    c = unwrap(psi, method=method, mask=given, **extra)             # loads or compiles: C order
    fortran = {k: np.asfortranarray(v) for k, v in extra.items()}
    before = _non_c_signatures()
    with compile_notices(lambda text: None) as stats:
        f = unwrap(np.asfortranarray(psi), method=method,
                   mask=None if given is None else np.asfortranarray(given), **fortran)
    assert stats["n"] == 0, f"{method}: numba compiled {stats['n']} kernel(s) for F order"
    assert not _non_c_signatures() - before
    # the same answer, and a right one: congruent with psi, the true phase up to 2 pi k
    np.testing.assert_array_equal(np.isnan(f), ~mask)
    np.testing.assert_allclose(f[mask], c[mask], rtol=0, atol=1e-9)
    k = (f[mask] - true[mask]) / (2 * np.pi)
    assert np.allclose(k, np.round(k[0]), atol=1e-6)
