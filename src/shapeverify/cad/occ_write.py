"""Write our NURBS curves and surfaces to STEP or IGES through OpenCASCADE (OCP).

A :class:`~shapeverify.cad.nurbs.NurbsSurface` becomes a ``Geom_BSplineSurface`` and one
untrimmed face; a 3-D :class:`~shapeverify.cad.nurbs.NurbsCurve` becomes a ``Geom_BSplineCurve``
and one edge (a 2-D curve is written in the plane z = 0).  Lengths are written as millimetres.

OCP is imported lazily, inside the functions, so that importing this module is cheap.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .nurbs import NurbsCurve, NurbsSurface

logger = logging.getLogger(__name__)

__all__ = ["write_nurbs", "to_occ"]

_FORMATS = {".step": "step", ".stp": "step", ".igs": "iges", ".iges": "iges"}


def _knots_mults(U: np.ndarray):
    """Distinct knots and multiplicities (OCC's representation of a knot vector)."""
    from OCP.collections import Array1_double, Array1_int

    distinct, mults = [], []
    for u in np.asarray(U, np.float64):
        if distinct and u == distinct[-1]:
            mults[-1] += 1
        else:
            distinct.append(float(u))
            mults.append(1)
    K = Array1_double(1, len(distinct))
    Mu = Array1_int(1, len(mults))
    for i, (u, m) in enumerate(zip(distinct, mults), start=1):
        K.SetValue(i, u)
        Mu.SetValue(i, m)
    return K, Mu


def to_occ(shape):
    """Our NURBS -> ``Geom_BSplineSurface`` / ``Geom_BSplineCurve`` (1-based OCC arrays).

    Raises
    ------
    TypeError
        Not a NurbsCurve or NurbsSurface.
    ValueError
        A curve that is neither 2-D nor 3-D.
    """
    from OCP.Geom import Geom_BSplineCurve, Geom_BSplineSurface
    from OCP.gp import gp_Pnt
    from OCP.collections import Array1_double, Array1_gp_Pnt, Array2_double, Array2_gp_Pnt

    if isinstance(shape, NurbsSurface):
        P = shape.control
        nu, nv = P.shape[:2]
        poles = Array2_gp_Pnt(1, nu, 1, nv)
        for i in range(nu):
            for j in range(nv):
                poles.SetValue(i + 1, j + 1, gp_Pnt(*map(float, P[i, j])))
        Ku, Mu = _knots_mults(shape.knots_u)
        Kv, Mv = _knots_mults(shape.knots_v)
        if shape.rational:
            W = Array2_double(1, nu, 1, nv)
            for i in range(nu):
                for j in range(nv):
                    W.SetValue(i + 1, j + 1, float(shape.weights[i, j]))
            return Geom_BSplineSurface(poles, W, Ku, Kv, Mu, Mv, shape.degree_u, shape.degree_v)
        return Geom_BSplineSurface(poles, Ku, Kv, Mu, Mv, shape.degree_u, shape.degree_v)
    if isinstance(shape, NurbsCurve):
        P = shape.control
        if P.shape[1] == 2:
            P = np.column_stack([P, np.zeros(len(P))])
        elif P.shape[1] != 3:
            raise ValueError(f"only 2-D and 3-D curves can be written, got dimension {P.shape[1]}")
        n = P.shape[0]
        poles = Array1_gp_Pnt(1, n)
        for i in range(n):
            poles.SetValue(i + 1, gp_Pnt(*map(float, P[i])))
        K, M = _knots_mults(shape.knots)
        if shape.rational:
            W = Array1_double(1, n)
            for i in range(n):
                W.SetValue(i + 1, float(shape.weights[i]))
            return Geom_BSplineCurve(poles, W, K, M, shape.degree)
        return Geom_BSplineCurve(poles, K, M, shape.degree)
    raise TypeError(f"expected a NurbsCurve or NurbsSurface, got {type(shape).__name__}")


def write_nurbs(shape, path) -> Path:
    """Write one NURBS surface (as a face) or curve (as an edge) to STEP or IGES.

    Parameters
    ----------
    shape : NurbsSurface or NurbsCurve
    path : str or os.PathLike
        ``.step`` / ``.stp`` or ``.igs`` / ``.iges``.

    Returns
    -------
    Path of the written file.

    Raises
    ------
    ValueError
        Unknown extension.
    OSError
        OpenCASCADE could not build the shape or write the file.
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.IGESControl import IGESControl_Writer
    from OCP.Interface import Interface_Static
    from OCP.Message import Message, Message_PrinterOStream
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    p = Path(path)
    fmt = _FORMATS.get(p.suffix.lower())
    if fmt is None:
        raise ValueError(f"cannot write {p.name!r}: use .step, .stp, .igs or .iges")
    Message.DefaultMessenger_s().RemovePrinters(Message_PrinterOStream.get_type_descriptor_s())
    geom = to_occ(shape)
    if isinstance(shape, NurbsSurface):
        mk = BRepBuilderAPI_MakeFace(geom, 1e-7)
    else:
        mk = BRepBuilderAPI_MakeEdge(geom)
    if not mk.IsDone():
        what = "face" if isinstance(shape, NurbsSurface) else "edge"
        raise OSError(f"OpenCASCADE could not build a {what} from the NURBS data")
    topo = mk.Shape()
    if fmt == "step":
        Interface_Static.SetCVal_s("write.step.unit", "MM")
        w = STEPControl_Writer()
        if w.Transfer(topo, STEPControl_AsIs) != IFSelect_RetDone:
            raise OSError(f"STEP transfer failed for {p}")
        status = w.Write(str(p))
    else:
        w = IGESControl_Writer("MM", 0)
        if not w.AddShape(topo):
            raise OSError(f"IGES transfer failed for {p}")
        w.ComputeModel()
        status = IFSelect_RetDone if w.Write(str(p)) else None
    if status != IFSelect_RetDone:
        raise OSError(f"OpenCASCADE could not write {p}")
    logger.info("wrote %s (%s)", p, type(shape).__name__)
    return p
