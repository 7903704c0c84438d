"""PMI attached to edges: the feature an edge bounds, by OpenCASCADE topology.

A feature control frame or dimension of an AP242 file may point at an edge instead of a face
(NIST CTC 02: the rim circle of a hole for its position, perpendicularity and diameter).
:func:`edge_record` describes one referenced edge -- its curve type, the faces it bounds
(``TopExp.MapShapesAndAncestors``), a circle's centre, axis and radius, a few points -- and
:func:`edge_feature` maps the edges of one PMI item to the faces of the feature they bound:

* a **circular edge** one of whose faces is a cylinder of the circle's radius on the circle's
  axis (a hole's or boss's rim) stands for that cylinder: the face and every face connected to it
  on the same cylinder (a wall split in halves);
* any other edge is not mapped, and the reason names the faces it lies between (their surface
  types), or -- for an edge that bounds no face of the part (a line drawn on a face) -- the faces
  it lies on.

Face numbers are those of the file's ``TopExp_Explorer`` order (:mod:`shapeverify.cad.pmi`).
"""
from __future__ import annotations

import numpy as np

__all__ = ["edge_record", "edge_feature", "circle_of", "faces_along"]

#: relative tolerance of "same radius", "on the axis" (of the radius) and "parallel axes"
_REL = 1e-4


def _surface_kind(face) -> tuple[str, tuple | None]:
    """(surface type name, (centre, axis, radius) of a cylinder or None)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cylinder

    s = BRepAdaptor_Surface(face)
    t = s.GetType()
    name = t.name.replace("GeomAbs_", "")
    if t != GeomAbs_Cylinder:
        return name, None
    c = s.Cylinder()
    ax = c.Axis()
    return name, (np.array(ax.Location().Coord()), np.array(ax.Direction().Coord()),
                  float(c.Radius()))


def _same_cylinder(cyl, centre, axis, radius) -> bool:
    c, a, r = cyl
    if abs(r - radius) > _REL * radius:
        return False
    if np.linalg.norm(np.cross(a, axis)) > _REL:
        return False
    q = centre - c
    return float(np.linalg.norm(q - (q @ a) * a)) <= _REL * radius


def _points(edge, n: int = 9) -> list:
    from OCP.BRepAdaptor import BRepAdaptor_Curve

    c = BRepAdaptor_Curve(edge)
    t = np.linspace(c.FirstParameter(), c.LastParameter(), n)
    return [list(c.Value(float(x)).Coord()) for x in t]


def _faces_on(edge, faces, tol: float) -> list:
    """Faces (indices) that every sample point of an edge lies on (within ``tol``)."""
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.Bnd import Bnd_Box
    from OCP.gp import gp_Pnt

    P = np.array(_points(edge, 5))
    lo, hi = P.min(axis=0) - tol, P.max(axis=0) + tol
    out = []
    for i, f in enumerate(faces):
        box = Bnd_Box()
        BRepBndLib.Add_s(f, box)
        a, b = np.array(box.CornerMin().Coord()), np.array(box.CornerMax().Coord())
        if np.any(a > hi) or np.any(b < lo):
            continue
        ok = True
        for p in P:
            v = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex()
            d = BRepExtrema_DistShapeShape(v, f)
            if not d.IsDone() or d.Value() > tol:
                ok = False
                break
        if ok:
            out.append(i)
    return out


def _point_faces(p, faces, boxes, tol: float) -> list:
    """Faces (indices) within ``tol`` of the point ``p``."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    v = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex()
    out = []
    for i, f in enumerate(faces):
        a, b = boxes[i]
        if np.any(a - tol > p) or np.any(b + tol < p):
            continue
        d = BRepExtrema_DistShapeShape(v, f)
        if d.IsDone() and d.Value() <= tol:
            out.append(i)
    return out


def faces_along(edges, faces, n: int = 17, tol: float | None = None) -> tuple[list, list]:
    """(faces, points on none): the faces that hold the points of ``edges`` (``n`` points of
    each), each point on at least one of them -- a curve drawn across several faces (a circle
    around a boss split in two halves) -- and the sample points that lie on no face (within
    ``tol``: 10 edge tolerances, at least 1e-4 mm)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepBndLib import BRepBndLib
    from OCP.Bnd import Bnd_Box
    from OCP.TopoDS import TopoDS

    boxes = []
    for f in faces:
        box = Bnd_Box()
        BRepBndLib.Add_s(f, box)
        boxes.append((np.array(box.CornerMin().Coord()), np.array(box.CornerMax().Coord())))
    on, off = [], []
    for e in edges:
        e = TopoDS.Edge(e)
        t = tol if tol is not None else max(1e-4, 10 * BRep_Tool.Tolerance_s(e))
        for p in _points(e, n):
            fs = _point_faces(np.asarray(p), faces, boxes, t)
            if not fs:
                off.append([round(float(x), 6) for x in p])
            on.extend(f for f in fs if f not in on)
    return sorted(on), off


def circle_of(records: list) -> tuple[dict | None, str]:
    """({centre, axis, radius} of edges that are arcs of one circle, '') or (None, why not)."""
    if not records or any(r["curve"] != "Circle" for r in records):
        kinds = sorted({r["curve"] for r in records}) or ["no edge"]
        return None, f"its curve is not a circle ({', '.join(kinds)})"
    c0, a0, r0 = (np.asarray(records[0]["centre"]), np.asarray(records[0]["axis"]),
                  float(records[0]["radius"]))
    for r in records[1:]:
        if (abs(float(r["radius"]) - r0) > _REL * r0
                or np.linalg.norm(np.cross(np.asarray(r["axis"]), a0)) > _REL
                or np.linalg.norm(np.asarray(r["centre"]) - c0) > _REL * r0):
            return None, "its edges are arcs of different circles"
    return {"centre": c0.tolist(), "axis": a0.tolist(), "radius": r0}, ""


def edge_record(edge, index, edge_faces, faces) -> dict:
    """A referenced edge as plain data.

    Parameters
    ----------
    edge : TopoDS_Shape
        The edge (``TopAbs_EDGE``) a PMI item references.
    index : shapeverify.cad.pmi._FaceIndex
        Face numbering of the document's shape.
    edge_faces : IndexedDataMap of edge -> faces
        ``TopExp.MapShapesAndUniqueAncestors`` of the shape's edges to its faces.
    faces : list
        The shape's faces (``TopExp_Explorer`` order).

    Returns
    -------
    dict
        ``curve`` (OpenCASCADE's curve type: Circle, Line, BSplineCurve ...), ``faces`` (the
        faces it bounds), ``kinds`` (their surface types), ``cylinders`` ({face: [centre,
        axis, radius]} of those that are cylinders), ``points`` (9 points along it), and for a
        circle ``centre``, ``axis``, ``radius``; ``on_faces``: for an edge that bounds no face,
        the faces it lies on.
    """
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Circle
    from OCP.TopoDS import TopoDS

    e = TopoDS.Edge(edge)
    c = BRepAdaptor_Curve(e)
    rec = {"curve": c.GetType().name.replace("GeomAbs_", ""), "faces": [], "kinds": [],
           "cylinders": {}, "points": _points(e)}
    if c.GetType() == GeomAbs_Circle:
        circ = c.Circle()
        rec["centre"] = list(circ.Location().Coord())
        rec["axis"] = list(circ.Axis().Direction().Coord())
        rec["radius"] = float(circ.Radius())
    k = edge_faces.FindIndex(e)
    if k > 0:
        for f in edge_faces.FindFromIndex(k):
            fi, _ = index.of(f)
            for i in fi:
                if i in rec["faces"]:
                    continue
                kind, cyl = _surface_kind(TopoDS.Face(f))
                rec["faces"].append(i)
                rec["kinds"].append(kind)
                if cyl is not None:
                    rec["cylinders"][i] = [cyl[0].tolist(), cyl[1].tolist(), cyl[2]]
    if not rec["faces"]:
        from OCP.BRep import BRep_Tool

        rec["on_faces"] = _faces_on(e, faces, max(1e-4, 10 * BRep_Tool.Tolerance_s(e)))
        if rec["on_faces"]:
            n = _section_normal(np.asarray(rec["points"]), faces[rec["on_faces"][0]])
            if n is not None:
                rec["section_normal"] = n.tolist()
    return rec


def _section_normal(P: np.ndarray, face):
    """The normal of the plane that holds the points of a line drawn on ``face`` and the face's
    normal at its middle (the section of a profile of a line), or None when the points are
    not on one straight line or the line runs along the normal."""
    from OCP.BRep import BRep_Tool
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.GeomLProp import GeomLProp_SLProps
    from OCP.gp import gp_Pnt

    t = P[-1] - P[0]
    L = float(np.linalg.norm(t))
    if L == 0.0:
        return None
    t = t / L
    q = P - P[0]
    if float(np.linalg.norm(q - np.outer(q @ t, t), axis=1).max()) > 1e-6 * max(L, 1.0):
        return None
    surf = BRep_Tool.Surface_s(face)
    mid = P[len(P) // 2]
    proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, mid)), surf)
    if proj.NbPoints() == 0:
        return None
    u, v = proj.LowerDistanceParameters()
    props = GeomLProp_SLProps(surf, u, v, 1, 1e-9)
    if not props.IsNormalDefined():
        return None
    fn = np.array(props.Normal().Coord())
    n = np.cross(t, fn)
    if float(np.linalg.norm(n)) < 1e-6:
        return None
    return n / np.linalg.norm(n)


def _cylinder_wall(start: int, cyl, faces, edge_faces, index) -> list:
    """``start`` and every face connected to it (through shared edges) on the same cylinder."""
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    centre, axis, radius = (np.asarray(cyl[0]), np.asarray(cyl[1]), float(cyl[2]))
    wall, todo = [start], [start]
    while todo:
        f = faces[todo.pop()]
        exp = TopExp_Explorer(f, TopAbs_EDGE)
        while exp.More():
            k = edge_faces.FindIndex(exp.Current())
            exp.Next()
            if k <= 0:
                continue
            for g in edge_faces.FindFromIndex(k):
                for j in index.of(g)[0]:
                    if j in wall:
                        continue
                    _, c2 = _surface_kind(TopoDS.Face(g))
                    if c2 is not None and _same_cylinder(c2, centre, axis, radius):
                        wall.append(j)
                        todo.append(j)
    return sorted(wall)


def _rim_around(r) -> int | None:
    """The cylinder face a non-circular edge between one cylinder and one plane runs around
    (a rim the plane cuts a little aslant: NIST FTC 07 DIM15's B-spline edge of its ⌀22.225
    cylinder, 0.39 mm of axial run over half a turn): its points on that cylinder, turning 90°
    or more about its axis, within a tenth of its radius along it; else None."""
    if sorted(r["kinds"]) != ["Cylinder", "Plane"] or len(r["cylinders"]) != 1:
        return None
    (i, (c, a, rad)), = r["cylinders"].items()
    c, a, P = np.asarray(c, float), np.asarray(a, float), np.asarray(r["points"], float)
    q = P - c
    h = q @ a
    radial = q - np.outer(h, a)
    if np.ptp(h) > 0.1 * rad or np.max(np.abs(np.linalg.norm(radial, axis=1) - rad)) > 1e-3 * rad:
        return None
    e1 = radial[0] / np.linalg.norm(radial[0])
    ang = np.sort(np.arctan2(radial @ np.cross(a, e1), radial @ e1) % (2 * np.pi))
    gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
    return int(i) if 2 * np.pi - gaps.max() >= np.pi / 2 else None


def edge_feature(records: list, faces, edge_faces, index) -> tuple[list, str, str]:
    """(faces, how, '') of the feature the edges of one PMI item bound, or ([], '', reason).

    ``how`` says where the faces came from (for the plan entry's ``pmi``)."""
    out, hows = [], []
    for r in records:
        if r["curve"] == "Circle":
            centre, axis, radius = (np.asarray(r["centre"]), np.asarray(r["axis"]), r["radius"])
            hit = [i for i, cyl in r["cylinders"].items()
                   if _same_cylinder((np.asarray(cyl[0]), np.asarray(cyl[1]), cyl[2]),
                                     centre, axis, radius)]
            if hit:
                wall = _cylinder_wall(hit[0], r["cylinders"][hit[0]], faces, edge_faces, index)
                out.extend(f for f in wall if f not in out)
                hows.append(f"circular edge (\u2300{2 * radius:.6g}) of the cylinder it bounds")
                continue
        rim = _rim_around(r) if r["curve"] != "Circle" else None
        if rim is not None:
            cyl = r["cylinders"][rim]
            wall = _cylinder_wall(rim, cyl, faces, edge_faces, index)
            out.extend(f for f in wall if f not in out)
            hows.append(f"edge ({r['curve']}) around the \u2300{2 * cyl[2]:.6g} cylinder it "
                        "bounds, where a plane cuts it")
            continue
        if r["faces"]:
            between = " and ".join(f"face {f} ({k})" for f, k in zip(r["faces"], r["kinds"]))
            what = ("a circular edge" if r["curve"] == "Circle" else
                    f"an edge ({r['curve']})")
            return [], "", (f"it is attached to {what} between {between}: not the rim of a "
                            "cylinder, and the file does not say which face it controls")
        on = r.get("on_faces") or []
        where = (f"drawn on face {', '.join(map(str, on))}" if on else
                 "that bounds no face of the part")
        return [], "", f"it is attached to an edge ({r['curve']}) {where}, not to faces"
    if not out:
        return [], "", "it is attached to no edge"
    return out, "; ".join(dict.fromkeys(hows)), ""
