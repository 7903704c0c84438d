"""Position of a hole's axis in two parallel planes (``zone: planes`` with ``direction``; ASME
Y14.5-2009 §7.7.3, bidirectional positional tolerancing) -- NIST CTC 03 'Position.8' (e2 GT10,
e1 GT7) was unsupported: the zone's direction across the axis is not in the semantic PMI; the
file draws the frame on the dimension line of the hole's size across it along y
(:mod:`shapeverify.cad.step_frame_direction`).  Answers checked against brute force here."""
from __future__ import annotations

import gzip
import shutil
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from shapeverify.characteristics import gdt
from shapeverify.characteristics.schema import Position
from test_position_max_projected import _CAD, _ctx, _hole_points

DATA = Path(__file__).parent / "data" / "nist_extra"


def _brute_planes(ends, centre, axis, u, n=20001):
    """Width of the narrowest pair of planes normal to ``u`` (the part of it across
    ``axis``), centred on the true axis (``centre``, ``axis``), holding every point of the
    axis segment between ``ends``: dense points on the segment, each one's distance from the
    true axis measured in the plane through it normal to ``u``'s across-part."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    w = np.asarray(u, float) - (np.asarray(u, float) @ a) * a
    w /= np.linalg.norm(w)
    t = np.linspace(0.0, 1.0, n)[:, None]
    P = ends[0] + t * (ends[1] - ends[0])
    # the true-position plane through the axis with normal w: signed distance of each point
    return 2.0 * float(np.max(np.abs((P - centre) @ w)))


@pytest.mark.parametrize("offset,tilt,u", [
    ((0.3, 0.0), 0.0, (0.0, 1.0, 0.0)),      # off along x: nothing along y
    ((0.0, 0.3), 0.0, (0.0, 1.0, 0.0)),      # off along y: 2 x 0.3
    ((0.1, -0.2), 0.01, (0.0, 1.0, 0.0)),    # tilted towards +x, off in both
    ((0.1, -0.2), 0.01, (1.0, 0.0, 0.0)),
    ((0.1, -0.2), 0.01, (1.0, 1.0, 0.0)),    # an oblique direction
])
def test_axis_planes_value_is_the_brute_force_width(monkeypatch, offset, tilt, u):
    X, N = _hole_points(10.0, offset=offset, tilt=tilt)
    ctx = _ctx(X, N, _CAD, monkeypatch)
    r = gdt.eval_position(Position(type="position", name="P", features=["face:0"], tol=0.45,
                                   zone="planes", direction=list(u)), ctx)
    row = r.details["features"][0]
    ends = np.asarray(row["ends"])
    # the ends: the perfect wall's own axis over its length (independent of the fit)
    a = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    p0 = np.array([offset[0], offset[1], 0.0])
    truth = np.stack([p0 - 20.0 / np.cos(tilt) * a, p0])
    assert np.abs(np.sort(ends, axis=0) - np.sort(truth, axis=0)).max() < 1e-6
    want = _brute_planes(truth, _CAD.center, _CAD.axis, u)
    assert r.measured == pytest.approx(want, abs=1e-6)
    assert r.verdict == ("pass" if want <= 0.45 else "fail")


def test_axis_planes_passes_an_offset_across_the_zone_that_a_diameter_zone_fails(monkeypatch):
    """0.3 off along x, zone 0.2 along y: the planes zone holds it (0), a ⌀0.2 zone does not."""
    X, N = _hole_points(10.0, offset=(0.3, 0.0))
    ctx = _ctx(X, N, _CAD, monkeypatch)
    planes = gdt.eval_position(Position(type="position", name="P", features=["face:0"],
                                        tol=0.2, zone="planes", direction=[0, 1, 0]), ctx)
    dia = gdt.eval_position(Position(type="position", name="P", features=["face:0"], tol=0.2),
                            ctx)
    assert planes.measured == pytest.approx(0.0, abs=1e-6) and planes.verdict == "pass"
    assert dia.measured == pytest.approx(0.6, abs=1e-6) and dia.verdict == "fail"


def test_axis_planes_takes_the_mmc_bonus_of_the_measured_size(monkeypatch):
    """Made 10.2 (MMC 10), 0.15 off along y, zone 0.1: value 0.3, limit 0.1 + 0.2 = 0.3."""
    X, N = _hole_points(10.2, offset=(0.0, 0.15))
    ctx = _ctx(X, N, _CAD, monkeypatch)
    r = gdt.eval_position(Position(type="position", name="P", features=["face:0"], tol=0.1,
                                   zone="planes", direction=[0, 1, 0], material="M",
                                   size={"lower": 0.0, "upper": 0.5}), ctx)
    assert r.measured == pytest.approx(0.3, abs=1e-6)
    assert r.upper == pytest.approx(0.1 + 0.2, abs=1e-6)


def test_axis_planes_refuses_a_direction_along_the_axis(monkeypatch):
    X, N = _hole_points(10.0)
    ctx = _ctx(X, N, _CAD, monkeypatch)
    with pytest.raises(ValueError, match="not across the axis"):
        gdt.eval_position(Position(type="position", name="P", features=["face:0"], tol=0.1,
                                   zone="planes", direction=[0, 0.1, 1]), ctx)


def test_axis_planes_schema_needs_direction_with_planes_only():
    with pytest.raises(ValidationError):
        Position(type="position", name="P", features=["face:0"], tol=0.1, zone="planes")
    with pytest.raises(ValidationError):
        Position(type="position", name="P", features=["face:0"], tol=0.1, direction=[0, 1, 0])


@pytest.mark.parametrize("edition", ["e1", "e2"])
def test_ctc03_position8_direction_is_read_from_the_dimension_line_it_is_drawn_on(
        tmp_path, edition):
    """CTC 03's ⌀38.1 hole (axis (-63.0174, 331.5208), z): its 'Position.8' frame sits on the
    dimension line of the hole's size drawn along y; 'Position.6' (the ⌀ frame) on none."""
    from shapeverify.cad.step_frame_direction import frame_dimension_direction

    gz = DATA / f"nist_ctc_03_asme1_ap242-{edition}.stp.gz"
    p = tmp_path / gz.name[:-3]
    with gzip.open(gz, "rb") as src, open(p, "wb") as dst:
        shutil.copyfileobj(src, dst)
    c, a, r = [-63.0174, 331.5208, 77.15], [0.0, 0.0, 1.0], 19.05
    u, how = frame_dimension_direction(p, "Position.8", c, a, r)
    assert u is not None, how
    assert np.allclose(u, [0.0, 1.0, 0.0], atol=1e-9)
    u6, why = frame_dimension_direction(p, "Position.6", c, a, r)
    assert u6 is None and "not drawn on the dimension line" in why
    # another hole (radius or place) does not match that drawing
    assert frame_dimension_direction(p, "Position.8", [-63.0174, 331.5208 + 1.0, 77.15], a,
                                     r)[0] is None
