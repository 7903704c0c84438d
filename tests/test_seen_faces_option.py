"""``faces="seen"`` (issue 30: a partial measurement could never pass): the option is accepted
everywhere faces are, picks the faces the scan covered, says so, and is refused with a pointer
for a reference without faces."""
from __future__ import annotations

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.cad.examples import wavy_panel
from shapeverify.inspection import inspect_registered


class _Pose:
    T_model_scan = np.eye(4)
    rms, iterations, converged, inlier_fraction = 0.0, 1, True, 1.0


@pytest.fixture(scope="module")
def prep():
    return sv.prepare(wavy_panel(split=True), spacing=2.0)


def test_options_accept_seen_as_faces():
    assert sv.InspectionOptions(tolerance=0.1, faces=" Seen ").faces == "seen"
    assert sv.InspectionOptions(tolerance=0.1, faces="seen").view_kwargs()["faces"] == "seen"


def test_seen_faces_are_the_faces_the_scan_covered(prep):
    """A scan of one of the panel's two faces only (the model points of face 0, exactly on the
    CAD): faces="seen" keeps face 0 alone, the coverage is of it (about all of it), the reason
    names it; inspecting all faces covers about half the panel."""
    pts, face = prep.points.points, prep.points.face
    scan = pts[face == 0]
    res = inspect_registered(prep, scan, _Pose(), tolerance=0.1, faces="seen")
    assert res.coverage.faces == (0,)
    assert res.coverage.fraction > 0.95
    share = np.mean(face == 0)
    assert any("limited to the 1 face the scan saw" in r and f"{100 * share:.0f} %" in r
               and "face 0;" in r and "not measured" in r for r in res.reasons), res.reasons
    whole = inspect_registered(prep, scan, _Pose(), tolerance=0.1)
    assert whole.coverage.faces is None
    assert abs(whole.coverage.fraction - share) < 0.05


def test_seen_faces_of_a_mesh_reference_point_to_inspect_partial():
    from partial_view_proxies import gear_model

    mesh = sv.prepare(gear_model(), spacing=0.05)
    with pytest.raises(ValueError, match=r"inspect_partial\(prep, scan, seen=True\)"):
        inspect_registered(mesh, mesh.points.points[:500], _Pose(), tolerance=0.05, faces="seen")
