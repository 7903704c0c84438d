"""Datum alignments on a near-symmetric plate (issue 27 item 2): where the datum features allow
several placements of the scan, the alignment tries them, picks by the datum fit and warns that
two fit alike -- never a silent copy.  The scan is made independently of the project's sampler
(OpenCASCADE's tessellation sampled by area, as in test_plan_nist)."""

from __future__ import annotations

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.cad.examples import chamfered_plate_step
from shapeverify.characteristics import align
from shapeverify.registration.rigid import pose_error
from test_plan_nist import _occ_mesh, _scan

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    path = chamfered_plate_step(tmp_path_factory.mktemp("plate") / "plate.step")
    from model_cache import cached_prepared

    prep = cached_prepared(path, spacing=1.0)  # built once per run (tests/model_cache.py)
    V, T = _occ_mesh(path)
    scan, T_true = _scan(V, T, 30_000, 0.02, 3)
    return prep, scan, T_true


def test_symmetric_plate_datums_pick_by_the_datum_fit_and_warn_of_the_copy(plate):
    prep, scan, T_true = plate
    # top (face:2), the x = 0 side (face:0), the y = 0 side (face:1): the plate turned 180 deg
    # about its normal fits the scan alike (only the chamfer tells the ends apart)
    al = align(scan, prep, {"type": "datums", "primary": "face:2", "secondary": "face:0",
                            "tertiary": "face:1"})
    e = pose_error(al.T_model_scan, T_true)
    assert np.degrees(np.linalg.norm(e[:3])) < 0.01 and np.linalg.norm(e[3:]) < 0.01, al.details
    rows = al.details["placements"]
    assert len(rows) >= 2 and any(r.get("degrees_from_chosen", 0) > 179 for r in rows)
    assert any("fits alike" in w for w in al.details["warnings"]), al.details
    assert al.details["converged"]


def test_the_callers_start_chooses_among_copies_that_fit_alike(plate):
    prep, scan, T_true = plate
    al = align(scan, prep, {"type": "datums", "primary": "face:2", "secondary": "face:0",
                            "tertiary": "face:1"}, init=T_true)
    e = pose_error(al.T_model_scan, T_true)
    assert np.degrees(np.linalg.norm(e[:3])) < 0.01 and np.linalg.norm(e[3:]) < 0.01
    assert al.details["placement"] == "start" and not al.details["warnings"]


def test_a_datum_not_seen_makes_the_inspection_an_error_with_the_reason(plate):
    prep, scan, T_true = plate
    X = scan @ T_true[:3, :3].T + T_true[:3, 3]
    cut = scan[X[:, 0] > 2.0]                      # the x = 0 side (datum B) not scanned
    plan = {"alignment": {"type": "datums", "primary": "face:2", "secondary": "face:0",
                          "tertiary": "face:1"},
            "characteristics": [{"name": "TOP", "type": "flatness", "feature": "face:2",
                                 "tol": 0.2}]}
    res = sv.inspect(prep, cut, tolerance=0.1, plan=plan)
    assert res.verdict == "error", res.reasons
    assert any("face:0" in r and "not seen" in r for r in res.reasons), res.reasons
    assert res.characteristics[0].verdict == "undecided"


def test_best_fit_on_the_chamfered_plate_does_not_take_the_turned_copy_silently(tmp_path):
    """Pins: a ``best_fit`` plan on the chamfered plate (1 mm random sampling, random pose) took
    the copy turned 180 degrees about the plate's normal, without a warning, in 5 of 40 runs of
    benchmarks/check_uncertainty.py (runs 2 and 24 among them): the global search returned only
    the copy, or the placements were compared at their rough poses.  The chamfer tells the copies
    apart: the right pose, no warning."""
    import independent_scans as isc
    import uncertainty_runs as ur

    case = ur.Plate(tmp_path)
    for seed in (2, 24):
        # the scan and pose of check_uncertainty.py's plate run ``seed``
        rng = np.random.default_rng(seed)
        P = isc.scan(case.V, case.T, "random", ur.SPACING, rng, noise=ur.NOISE)
        Tp = ur._random_pose(rng)
        al = align(ur._apply(Tp, P), case.prep, {"type": "best_fit"}, rng=seed)
        e = pose_error(al.T_model_scan, np.linalg.inv(Tp))
        assert np.degrees(np.linalg.norm(e[:3])) < 0.01 and np.linalg.norm(e[3:]) < 0.01, (
            seed, e, al.details.get("warnings"))
        assert not al.details.get("warnings"), al.details["warnings"]
