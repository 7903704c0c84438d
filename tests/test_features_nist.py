"""Features of the real NIST PMI test parts (issue 27 item 1): `info --features` reads every
file, and the holes equal OpenCASCADE's own circular inner loops and concave cylindrical faces.

OpenCASCADE is read directly here (the reference); the library reads it only through cad/.
"""
from __future__ import annotations

import numpy as np
import pytest

NIST = ("nist_ctc_01_asme1_rd.stp", "nist_ctc_01_asme1_ap242-e1.stp",
        "nist_ctc_02_asme1_ap242-e1.stp", "nist_ftc_06_asme1_ap242-e1.stp",
        "nist_ftc_06_asme1_rd.stp", "nist_ftc_08_asme1_ap242-e1.stp",
        "nist_ftc_08_asme1_rc.stp")
TOL = 1e-6          # mm: centre, axis-line distance and diameter
COVER = np.deg2rad(200.0)


def _occ_shape(path):
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    r = STEPControl_Reader()
    assert r.ReadFile(str(path)) == IFSelect_RetDone
    r.TransferRoots()
    return r.OneShape()


def _xyz(p):
    return np.array([p.X(), p.Y(), p.Z()])


def occ_holes(path):
    """OpenCASCADE's holes: circular inner wires (all edges on one circle: centre, axis,
    diameter, on a planar face or not) and concave cylindrical faces grouped by axis line and
    radius that together span more than 200 degrees (u range of the faces)."""
    from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Surface
    from OCP.BRepTools import BRepTools
    from OCP.GeomAbs import GeomAbs_Circle, GeomAbs_Cylinder, GeomAbs_Plane
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED, TopAbs_WIRE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    shape = _occ_shape(path)
    loops, cyls = [], []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face(exp.Current())
        exp.Next()
        ad = BRepAdaptor_Surface(face)
        if ad.GetType() == GeomAbs_Cylinder:
            c = ad.Cylinder()
            pos = c.Position()
            concave = pos.Direct() == (face.Orientation() == TopAbs_REVERSED)
            if concave:
                u0, u1, _, _ = BRepTools.UVBounds_s(face)
                cyls.append((_xyz(pos.Location()), _xyz(pos.Direction()), c.Radius(), u1 - u0))
        outer = BRepTools.OuterWire_s(face)
        wexp = TopExp_Explorer(face, TopAbs_WIRE)
        while wexp.More():
            wire = wexp.Current()
            wexp.Next()
            if wire.IsSame(outer):
                continue
            circles, pts = [], []
            eexp = TopExp_Explorer(wire, TopAbs_EDGE)
            while eexp.More():
                cu = BRepAdaptor_Curve(TopoDS.Edge(eexp.Current()))
                eexp.Next()
                pts += [_xyz(cu.Value(t)) for t in
                        np.linspace(cu.FirstParameter(), cu.LastParameter(), 64)]
                if circles is not None and cu.GetType() == GeomAbs_Circle:
                    ci = cu.Circle()
                    circles.append((_xyz(ci.Location()), _xyz(ci.Axis().Direction()),
                                    ci.Radius()))
                else:
                    circles = None
            if circles:
                c0, a0, r0 = circles[0]
                if all(np.linalg.norm(c - c0) <= TOL and abs(r - r0) <= TOL and
                       np.linalg.norm(np.cross(a, a0)) <= 1e-9 for c, a, r in circles):
                    loops.append((c0, a0, 2 * r0, ad.GetType() == GeomAbs_Plane, TOL))
            elif len(pts) >= 6:
                # edges that are B-splines (NIST FTC 06 AP242): the circle through OCP's own
                # curve points, known only to the curve's departure from a circle
                fit = _circle3(np.array(pts))
                if fit is not None:
                    c0, a0, r0, form = fit
                    if form <= 1e-4 * r0 and r0 < 1e3:   # (a 96 m "circle" is straight)
                        loops.append((c0, a0, 2 * r0, ad.GetType() == GeomAbs_Plane,
                                      max(TOL, 4 * form)))
    groups = []
    for p, a, r, span in cyls:
        for g in groups:
            q, b, s, _ = g[0]
            d = p - q
            if abs(r - s) <= TOL and np.linalg.norm(np.cross(a, b)) <= 1e-9 and \
                    np.linalg.norm(d - (d @ b) * b) <= TOL:
                g.append((p, a, r, span))
                break
        else:
            groups.append([(p, a, r, span)])
    walls = [(g[0][0], g[0][1], 2 * g[0][2]) for g in groups
             if min(sum(x[3] for x in g), 2 * np.pi) > COVER]
    return loops, walls


def _circle3(P):
    """Least-squares circle through 3-D points (scipy): (centre, unit normal, radius, max
    residual) or None for points on a line."""
    from scipy.optimize import least_squares

    c = P.mean(axis=0)
    _, sv, vt = np.linalg.svd(P - c)
    if sv[1] <= 1e-9 * sv[0]:
        return None
    n = vt[2]
    Q = np.column_stack([(P - c) @ vt[0], (P - c) @ vt[1]])
    A = np.column_stack([2 * Q, np.ones(len(Q))])
    (x0, y0, k), *_ = np.linalg.lstsq(A, (Q ** 2).sum(1), rcond=None)
    r0 = np.sqrt(k + x0 * x0 + y0 * y0)
    centre0 = c + x0 * vt[0] + y0 * vt[1]

    def res(x):
        ce, nn, r = x[:3], x[3:6] / np.linalg.norm(x[3:6]), x[6]
        d = P - ce
        h = d @ nn
        return np.r_[np.hypot(np.linalg.norm(d - np.outer(h, nn), axis=1) - r, h)]

    def res2(x):
        ce, nn, r = x[:3], x[3:6] / np.linalg.norm(x[3:6]), x[6]
        d = P - ce
        h = d @ nn
        rad = np.linalg.norm(d - np.outer(h, nn), axis=1)
        return np.r_[rad - r, h]

    sol = least_squares(res2, np.r_[centre0, n, r0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    ce, nn, r = sol.x[:3], sol.x[3:6] / np.linalg.norm(sol.x[3:6]), sol.x[6]
    return ce, nn, r, float(np.max(np.abs(res(sol.x))))


def _on_line(c, p, a, tol=TOL):
    d = np.asarray(c) - p
    return np.linalg.norm(d - (d @ a) * a) <= tol


def _same(h, p, a, dia, tol=TOL):
    return (abs(h.diameter - dia) <= tol and np.linalg.norm(np.cross(h.axis, a)) <= 1e-9 + tol
            and _on_line(h.center, p, a, tol))


def _check_file(path):
    from model_cache import cached_model

    from shapeverify.characteristics.features import model_features

    # load_model's import and its model_features, built once per code version for every NIST
    # module (tests/model_cache.py)
    model = cached_model(path, features=True)
    holes = [f for f in model_features(model) if f.kind == "hole"]
    loops, walls = occ_holes(path)
    problems = []
    for c, a, dia, planar, tol in loops:
        m = [h for h in holes if _same(h, c, a, dia, tol)]
        if not m:
            problems.append(f"OCP circular loop at {np.round(c, 4)} D{dia:.6f} has no hole")
        elif planar and not any(np.linalg.norm(h.center - c) <= tol for h in m):
            problems.append(f"OCP loop centre {np.round(c, 6)} != {[h.center for h in m]}")
    for p, a, dia in walls:
        if not any(_same(h, p, a, dia) for h in holes):
            problems.append(f"OCP concave cylinder on {np.round(p, 4)}/{np.round(a, 4)} "
                            f"D{dia:.6f} has no hole")
    for h in holes:
        if not (any(_same(h, c, a, dia, tol) for c, a, dia, _, tol in loops) or
                any(_same(h, p, a, dia) for p, a, dia in walls)):
            problems.append(f"{h.id} at {np.round(h.center, 4)} D{h.diameter:.6f} is neither "
                            "an OCP circular loop nor a concave cylinder")
    return len(holes), len(loops), len(walls), problems


@pytest.mark.slow
@pytest.mark.parametrize("name", NIST)
def test_nist_holes_equal_opencascades_circular_loops_and_concave_cylinders(shared_data, name):
    """Pins issue 27: 26 of 30 NIST files failed `info --features` (a parameter 1e-15..3e-11
    outside [0, pi]; a non-circular inner loop raised), side-wall and counterbored holes whose
    rim is no circular inner loop were missing."""
    n, nl, nw, problems = _check_file(shared_data / "cad" / "nist" / name)
    assert n > 0 and nl + nw > 0
    assert not problems, "\n".join(problems[:20]) + f"\n({len(problems)} problems)"


@pytest.mark.slow
def test_info_features_exits_0_on_every_nist_file_and_lists_notes(shared_data, tmp_path,
                                                                   monkeypatch):
    import json

    from model_cache import load_model_stand_in
    from typer.testing import CliRunner

    import shapeverify.cad.load
    from shapeverify.cli import app

    # the command's import is load_model's, read from the suite's cache (tests/model_cache.py:
    # bitwise the same model; the other tests here and the NIST modules import the same files)
    monkeypatch.setattr(shapeverify.cad.load, "load_model", load_model_stand_in)
    for name in NIST:
        out = tmp_path / (name + ".json")
        res = CliRunner().invoke(app, ["info", str(shared_data / "cad" / "nist" / name),
                                       "--features", "--json", str(out)])
        assert res.exit_code == 0, (name, res.output[-2000:])
        rows = json.loads(out.read_text())
        assert any(r["kind"] == "hole" for r in rows), name
        for r in rows:
            if r["kind"] in ("slot", "pocket", "other"):
                assert r["outline"] and len(r["outline"][0]) == 3 and r["length"] > 0, r["id"]
