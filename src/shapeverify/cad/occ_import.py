"""STEP and IGES import through OpenCASCADE (OCP): every face becomes a trimmed NURBS :class:`Face`.

This module holds all of the project's OpenCASCADE code for reading CAD files; everything
downstream works on the numpy data of :class:`shapeverify.cad.model.Model`.

What :func:`read_cad` does, per face (thesis §7.3):

* **Surface.** A B-spline face is taken as it is; any other face (plane, cylinder, cone, sphere,
  torus, surface of revolution or extrusion, offset surface, ...) is converted with
  ``BRepBuilderAPI_NurbsConvert``, and its trimming curves come from the converted face so that they
  live in the converted surface's parameters.  Periodic B-splines are made non-periodic (or cut to
  the face's parameter range when the face straddles the period's seam).  The control points,
  weights and full knot vectors (multiplicities expanded) become a :class:`NurbsSurface`.
* **Trimming loops.** The face's wires, outer wire first (``BRepTools.OuterWire_s``), each a chain
  of the edges' 2D curves on the surface (pcurves) in wire order.  Every pcurve is sampled
  adaptively: an interval is split while the 3D deviation at its parameter midpoint -- between the
  edge and the straight 3D chord, and between the edge and the image of the straight (u, v) chord
  -- exceeds ``chord_tol`` (default 0.002 mm).  Degenerated edges (the 2D image of a pole) are kept.
* **Orientation.** ``reversed`` is True for faces whose orientation is ``TopAbs_REVERSED``.
* **Free edges.** A segment is free when its edge belongs to this face only (``TopExp`` edge -> face
  map; seam and degenerated edges are never free) *and* no other edge, of any face, passes within
  the gap tolerance of the segment's midpoint (``max(gap_tol, 1e-5 * model size, 2 * the edge's
  tolerance)``).  The second test matters for IGES files, whose faces are usually not sewn: every
  edge of an unsewn model belongs to one face only, and a seam is two separate edges, although
  nearly all of them touch another edge.

Face names: a STEP file whose face entities are named (``ADVANCED_FACE('datum_A', ...)``) is
read through the XCAF reader and each face gets its name by shape identity
(:mod:`shapeverify.cad.step_names`, ``Model.face_names``); other files are read as before.

Units: OpenCASCADE's readers convert the file's coordinates to the session length unit, which this
module pins to millimetres; the model records the unit the file declared and its size in mm
(``scale_to_mm``).  The geometry held in the model is therefore always in mm.

References
----------
Bergström (2011), thesis §7.3; Piegl & Tiller, The NURBS Book, 2nd ed., ch. 2-4 (knot vectors);
OpenCASCADE Technology 7.x/8.x reference manual (STEPControl, IGESControl, BRep_Tool, TopExp).
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

import numpy as np

from ..errors import CADImportError, EmptyModelError, ShapeVerifyError, UnsupportedFormatError
from .model import Face, Model
from ._occ_loops import _array1, _clear_touching, _edge_face_map, _face_loops  # tests patch _face_loops here
from .nurbs import NurbsSurface

logger = logging.getLogger(__name__)

__all__ = ["read_cad", "CAD_SUFFIXES"]

#: file suffix -> format read by :func:`read_cad`
CAD_SUFFIXES = {".step": "step", ".stp": "step", ".igs": "iges", ".iges": "iges"}

# STEP length-unit names as OpenCASCADE reports them (SI prefix + metre, or a conversion-based
# unit's name) -> millimetres per unit
_SI_PREFIX_MM = {"": 1e3, "exa": 1e21, "peta": 1e18, "tera": 1e15, "giga": 1e12, "mega": 1e9,
                 "kilo": 1e6, "hecto": 1e5, "deca": 1e4, "deka": 1e4, "deci": 1e2, "centi": 10.0,
                 "milli": 1.0, "micro": 1e-3, "nano": 1e-6, "pico": 1e-9}
_NAMED_MM = {"inch": 25.4, "in": 25.4, "foot": 304.8, "ft": 304.8, "mile": 1609344.0,
             "yard": 914.4, "mil": 0.0254, "micron": 1e-3, "microinch": 2.54e-5,
             "mm": 1.0, "cm": 10.0, "m": 1e3, "km": 1e6}
_PLURAL = {"inches": "inch", "feet": "foot", "miles": "mile", "yards": "yard", "mils": "mil",
           "microns": "micron"}

# boundaries of two faces closer than this fraction of the model size count as touching
_OCP_READY = False


def _init_ocp() -> None:
    """Silence OpenCASCADE's console output and pin its session length unit to mm (once)."""
    global _OCP_READY
    if _OCP_READY:
        return
    from OCP.Interface import Interface_Static
    from OCP.Message import Message, Message_PrinterOStream

    Message.DefaultMessenger_s().RemovePrinters(Message_PrinterOStream.get_type_descriptor_s())
    Interface_Static.SetCVal_s("xstep.cascade.unit", "MM")
    _OCP_READY = True


# ------------------------------------------------------------------------------------ reading
def _check_path(path) -> tuple[Path, str]:
    p = Path(path)
    fmt = CAD_SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        raise UnsupportedFormatError(
            f"{p}: unsupported CAD file extension {p.suffix!r}; read_cad reads "
            f"{', '.join(sorted(CAD_SUFFIXES))}")
    if not p.exists():
        raise FileNotFoundError(2, "CAD file not found", str(p))
    if not p.is_file():
        raise CADImportError(f"{p}: not a regular file")
    if p.stat().st_size == 0:
        raise CADImportError(f"{p}: the file is empty (0 bytes)")
    if fmt == "iges":
        _check_iges_terminated(p)
    if not _NUMBERS_CHECKED_BY_CALLER:
        from .number_check import check_numbers

        check_numbers(p, fmt)  # a NaN or 1e400 makes OpenCASCADE loop for ever (issue 33 row 4)
    return p, fmt


#: True in the importer child process: its caller checked the numbers before sending the path
_NUMBERS_CHECKED_BY_CALLER = False


def _check_iges_terminated(p: Path) -> None:
    """An IGES file ends with its Terminate line ('T' in column 73); OpenCASCADE silently reads
    what it can of a truncated file, so check that the end is there."""
    with open(p, "rb") as fh:
        fh.seek(max(0, p.stat().st_size - 400))
        tail = fh.read().decode("latin-1").rstrip("\r\n\x00 \t\x1a")
    last = tail.splitlines()[-1] if tail else ""
    if len(last) < 73 or last[72] != "T":
        raise CADImportError(f"{p}: not a readable IGES file (it does not end with the "
                             "Terminate section); is it truncated or corrupt?")


def _step_unit(reader, path=None) -> tuple[str, float]:
    from OCP.collections import Sequence_TCollection_AsciiString as Seq

    lengths, angles, solids = Seq(), Seq(), Seq()
    reader.FileUnits(lengths, angles, solids)
    names = sorted({lengths.Value(i).ToCString() for i in range(1, lengths.Length() + 1)})
    if path is not None and (not names or names == [""]):
        # OpenCASCADE names no unit for some complex unit entities (NIST CTC 05's inch)
        from .step_units import length_unit_of_file

        found = length_unit_of_file(path)
        if found is not None:
            return found
    if not names:
        logger.warning("STEP file declares no length unit; assuming mm")
        return "mm", 1.0
    if len(names) > 1:
        logger.warning("STEP file declares several length units %s; reporting the first "
                       "(OpenCASCADE converts each representation to mm)", names)
    name = names[0]
    key = name.lower().replace("meter", "metre")
    key = _PLURAL.get(key, key)
    if key.endswith("metre") and key[:-5] in _SI_PREFIX_MM:
        scale = _SI_PREFIX_MM[key[:-5]]
    else:
        scale = _NAMED_MM.get(key, float("nan"))
    if not np.isfinite(scale):
        logger.warning("STEP length unit %r not recognised; OpenCASCADE converted the geometry "
                       "to mm but its factor is unknown (scale_to_mm = nan)", name)
    return name, scale


def _iges_unit(reader) -> tuple[str, float]:
    from OCP.UnitsMethods import UnitsMethods

    g = reader.IGESModel().GlobalSection()
    flag = g.UnitFlag()
    name = g.UnitName().ToCString() if g.UnitName() is not None else ""
    if flag == 3:  # unit named in the global section; OpenCASCADE computed its value
        scale = float(g.UnitValue()) * float(g.CascadeUnit())
    else:
        scale = float(UnitsMethods.GetLengthFactorValue_s(flag))
    return (name or f"IGES unit flag {flag}"), scale


def _read_shape(path: Path, fmt: str):
    """Read a STEP/IGES file; return (shape, unit name, mm per unit)."""
    return _read_shape_named(path, fmt)[:3]


def _read_shape_named(path: Path, fmt: str):
    """Read a STEP/IGES file; return (shape, unit name, mm per unit, names document or None).

    A STEP file whose faces carry names is read through the XCAF reader
    (:mod:`shapeverify.cad.step_names`); the document then holds the names.  Should that
    transfer fail, the file is read again without names (a warning says so)."""
    from . import step_names

    return _read_shape_with(path, fmt, fmt == "step" and step_names.has_face_names(path))


def _read_shape_plain(path: Path, fmt: str):
    return _read_shape_with(path, fmt, False)


def _read_shape_with(path: Path, fmt: str, names: bool):
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.IGESControl import IGESControl_Reader
    from OCP.STEPControl import STEPControl_Reader

    from . import step_names

    caf = doc = None
    try:
        if names:
            caf, doc, status = step_names.read_step_named(path)
            reader = caf.Reader()
        else:
            reader = STEPControl_Reader() if fmt == "step" else IGESControl_Reader()
            status = reader.ReadFile(os.fspath(path))
    except Exception as exc:  # OCP raises Standard_Failure subclasses on some broken files
        raise CADImportError(f"{path}: not a readable {fmt.upper()} file ({exc})") from exc
    if status != IFSelect_RetDone:
        raise CADImportError(
            f"{path}: not a readable {fmt.upper()} file (OpenCASCADE reader status "
            f"{status.name.replace('IFSelect_Ret', '')}); is the file corrupt or truncated?")
    n_roots = reader.NbRootsForTransfer()
    if n_roots == 0:
        raise EmptyModelError(f"{path}: the {fmt.upper()} file holds no shapes")
    unit, scale = _step_unit(reader, path) if fmt == "step" else _iges_unit(reader)
    if caf is not None:
        try:
            reader = step_names.transfer(caf, doc)
        except Exception as exc:  # noqa: BLE001 - the names are extra: read without them
            logger.warning("%s: the face names could not be read (%s); reading without them",
                           path, exc)
            return _read_shape_plain(path, fmt)
    try:
        if caf is None:
            reader.TransferRoots()
        shape = reader.OneShape()
    except Exception as exc:
        raise CADImportError(f"{path}: OpenCASCADE could not convert the {fmt.upper()} "
                             f"entities to shapes ({exc})") from exc
    if shape is None or shape.IsNull():
        raise CADImportError(f"{path}: none of the {n_roots} root entities of the "
                             f"{fmt.upper()} file could be converted to a shape; "
                             "is the file truncated or corrupt?")
    return shape, unit, scale, doc


# ----------------------------------------------------------------------------------- surfaces
def _to_bspline_face(face, index: int, path: Path):
    """(face whose surface is a Geom_BSplineSurface, that surface, converted?)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert
    from OCP.Geom import Geom_BSplineSurface
    from OCP.TopoDS import TopoDS

    surf = BRep_Tool.Surface_s(face)
    if isinstance(surf, Geom_BSplineSurface):
        return face, surf, None
    try:
        conv = BRepBuilderAPI_NurbsConvert(face, True)
        work = TopoDS.Face(conv.Shape())
    except Exception as exc:  # noqa: BLE001 - OpenCASCADE raises Standard_Failure & co.
        basis = _trimmed_bspline_basis(surf)
        if basis is None:
            raise
        # NIST CTC02 faces 35 and 361: a Geom_RectangularTrimmedSurface over a U-periodic
        # B-spline, trimmed from u = -1.8e-15 (a hair before the period's start);
        # BRepBuilderAPI_NurbsConvert raises Standard_OutOfRange (NCollection_Array1::at) on it.
        # The trimmed surface shares its basis's parametrisation, so the face's own pcurves
        # and the basis B-spline describe the face exactly, without a conversion.
        logger.info("%s: face %d: BRepBuilderAPI_NurbsConvert failed (%s: %s); using the "
                    "B-spline basis of its trimmed surface", path, index,
                    type(exc).__name__, exc)
        return face, basis, None
    surf = BRep_Tool.Surface_s(work)
    if not isinstance(surf, Geom_BSplineSurface):
        raise CADImportError(f"{path}: face {index} ({type(surf).__name__}) could not be "
                             "converted to a B-spline surface")
    return work, surf, conv


def _trimmed_bspline_basis(surf):
    """The Geom_BSplineSurface under a (nested) Geom_RectangularTrimmedSurface, cut to the trim's
    range where that range lies strictly inside a non-periodic direction, else None."""
    from OCP.Geom import Geom_BSplineSurface, Geom_RectangularTrimmedSurface

    trims = []
    while isinstance(surf, Geom_RectangularTrimmedSurface):
        trims.append(surf.Bounds())
        surf = surf.BasisSurface()
    if not trims or not isinstance(surf, Geom_BSplineSurface):
        return None
    basis = surf.Copy()
    u0, u1, v0, v1 = basis.Bounds()
    a0, a1, b0, b1 = trims[-1]
    tol_u, tol_v = 1e-9 * max(1.0, u1 - u0), 1e-9 * max(1.0, v1 - v0)
    cut_u = not basis.IsUPeriodic() and (a0 > u0 + tol_u or a1 < u1 - tol_u)
    cut_v = not basis.IsVPeriodic() and (b0 > v0 + tol_v or b1 < v1 - tol_v)
    if cut_u or cut_v:
        basis.Segment(max(a0, u0) if cut_u else u0, min(a1, u1) if cut_u else u1,
                      max(b0, v0) if cut_v else v0, min(b1, v1) if cut_v else v1)
    return basis


def _nurbs_surface(surf, face) -> NurbsSurface:
    """Geom_BSplineSurface -> NurbsSurface (non-periodic, full knot vectors)."""
    from OCP.BRepTools import BRepTools

    if surf.IsUPeriodic() or surf.IsVPeriodic():
        surf = surf.Copy()
        u0, u1, v0, v1 = surf.Bounds()
        a0, a1, b0, b1 = BRepTools.UVBounds_s(face)
        tol_u, tol_v = 1e-9 * max(1.0, u1 - u0), 1e-9 * max(1.0, v1 - v0)
        inside_u = a0 >= u0 - tol_u and a1 <= u1 + tol_u
        inside_v = b0 >= v0 - tol_v and b1 <= v1 + tol_v
        if (surf.IsUPeriodic() and not inside_u) or (surf.IsVPeriodic() and not inside_v):
            # the face straddles the seam of the period: cut the surface to the face's range
            su = (a0, a1) if surf.IsUPeriodic() and not inside_u else (u0, u1)
            sv = (b0, b1) if surf.IsVPeriodic() and not inside_v else (v0, v1)
            wide = ((surf.IsUPeriodic() and su[1] - su[0] > surf.UPeriod() * (1 + 1e-9))
                    or (surf.IsVPeriodic() and sv[1] - sv[0] > surf.VPeriod() * (1 + 1e-9)))
            if not wide:  # wider than a period, Segment raises: _unwrap_periods extends it
                surf.Segment(su[0], su[1], sv[0], sv[1])
        if surf.IsUPeriodic():
            surf.SetUNotPeriodic()
        if surf.IsVPeriodic():
            surf.SetVNotPeriodic()
    nu, nv = surf.NbUPoles(), surf.NbVPoles()
    poles = surf.Poles()
    ctrl = np.array([[poles.Value(i, j).Coord() for j in range(1, nv + 1)]
                     for i in range(1, nu + 1)], dtype=np.float64)
    weights = None
    if surf.IsURational() or surf.IsVRational():
        weights = np.array([[surf.Weight(i, j) for j in range(1, nv + 1)]
                            for i in range(1, nu + 1)], dtype=np.float64)
    nurbs = NurbsSurface(surf.UDegree(), surf.VDegree(), _array1(surf.UKnotSequence()),
                         _array1(surf.VKnotSequence()), ctrl, weights)
    return _unwrap_periods(nurbs, _pcurve_range(face))


def _pcurve_range(face) -> tuple[tuple[float, float], tuple[float, float]]:
    """((u_min, u_max), (v_min, v_max)) of the face's pcurves, sampled (``UVBounds`` of
    B-spline pcurves can be loose: it bounds their poles)."""
    from OCP.BRepAdaptor import BRepAdaptor_Curve2d
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    pts = []
    exp = TopExp_Explorer(face, TopAbs_EDGE)
    while exp.More():
        c = BRepAdaptor_Curve2d(TopoDS.Edge(exp.Current()), face)
        for t in np.linspace(c.FirstParameter(), c.LastParameter(), 65):
            pts.append(c.Value(float(t)).Coord())
        exp.Next()
    if not pts:
        return (np.inf, -np.inf), (np.inf, -np.inf)
    P = np.asarray(pts, np.float64)
    return (float(P[:, 0].min()), float(P[:, 0].max())), (float(P[:, 1].min()),
                                                          float(P[:, 1].max()))


def _unwrap_periods(surface: NurbsSurface, uv_range) -> NurbsSurface:
    """The surface repeated over whole periods of a closed direction so that its domain holds
    the face's pcurves (``uv_range``, from :func:`_pcurve_range`); unchanged when they fit.

    A face on a sphere whose seam is a slanted circle through the pole (NIST FTC 07's corner
    blends: pcurves over u in [-pi/2, 2 pi]) spans more than one period: ``Segment`` raised
    (the face was skipped) or the loops ran off a one-period domain and were clipped (their
    vertices 0.7 mm off the face).  The clamped B-spline closed across the direction is joined
    to copies of itself shifted by its width (knot multiplicity p at the joins, the shared
    row of poles; a copy's weights scaled to the shared row's), which is exactly the periodic
    surface continued."""
    knots = [np.asarray(surface.knots_u, np.float64), np.asarray(surface.knots_v, np.float64)]
    deg = [surface.degree_u, surface.degree_v]
    ctrl = np.asarray(surface.control, np.float64)
    w = None if surface.weights is None else np.asarray(surface.weights, np.float64)
    changed = False
    for axis in (0, 1):
        lo, hi = surface.domain[axis]
        width = hi - lo
        r0, r1 = uv_range[axis]
        tol = 1e-7 * width
        if not (width > 0 and np.isfinite(r0) and (r0 < lo - tol or r1 > hi + tol)
                and r1 - r0 > width * (1 + 1e-6)):
            continue  # within one period: _seam_shift moves an offset wire back (CTC 02, 05)
        c = np.moveaxis(ctrl, axis, 0)
        ww = None if w is None else np.moveaxis(w, axis, 0)
        size = float(np.ptp(c.reshape(-1, 3), axis=0).max())
        if np.abs(c[0] - c[-1]).max() > 1e-9 * max(size, 1e-300):
            continue  # not closed across this direction: nothing to continue
        ratio = 1.0
        if ww is not None:
            ratio_row = ww[-1] / ww[0]
            if np.abs(ratio_row - ratio_row[0]).max() > 1e-9 * abs(ratio_row[0]):
                continue
            ratio = float(ratio_row[0])
        p = deg[axis]
        k = knots[axis]
        if np.ptp(k[1:p + 1]) > tol or np.ptp(k[-p - 1:-1]) > tol:
            continue  # not clamped: the end rows are not the surface's edges
        # SetUNotPeriodic leaves one knot beyond each end (multiplicity p at the ends): on the
        # domain the first and last knots play no part, so the surface is the clamped one
        inner = k[p + 1:len(k) - p - 1]
        k0 = int(np.floor((r0 - lo) / width + 1e-9))
        k1 = int(np.ceil((r1 - lo) / width - 1e-9))
        if k1 - k0 > 8:
            continue  # a pcurve wandering over many periods is damage, not a seam
        new_k = [np.full(p + 1, lo + k0 * width)]
        rows, wrows = [c[:1]], ([] if ww is None else [ww[:1] * ratio ** k0])
        for j in range(k0, k1):
            new_k.append(inner + j * width)
            new_k.append(np.full(p if j < k1 - 1 else p + 1, lo + (j + 1) * width))
            rows.append(c[1:])
            if ww is not None:
                wrows.append(ww[1:] * ratio ** j)
        knots[axis] = np.concatenate(new_k)
        ctrl = np.moveaxis(np.concatenate(rows), 0, axis)
        if ww is not None:
            w = np.moveaxis(np.concatenate(wrows), 0, axis)
        changed = True
        logger.debug("closed surface continued over periods %d..%d along axis %d", k0, k1, axis)
    if not changed:
        return surface
    return NurbsSurface(surface.degree_u, surface.degree_v, knots[0], knots[1], ctrl, w)


def _shape_faces(path: Path, fmt: str, shape) -> list:
    """The faces of a shape (``TopExp_Explorer`` order); raises when there are none."""
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    from .face_count import declared_faces

    faces = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        faces.append(TopoDS.Face(exp.Current()))
        exp.Next()
    if not faces:
        try:
            declared, _ = declared_faces(path, fmt)
        except (OSError, ValueError):
            declared = 0
        if declared:
            raise CADImportError(f"{path}: the {fmt.upper()} file declares {declared} face(s) but "
                                 "OpenCASCADE could read none of them; is the file damaged or "
                                 "truncated? export it again from the CAD system")
        raise EmptyModelError(f"{path}: the {fmt.upper()} file holds no faces (only "
                              f"{shape.ShapeType().name.replace('TopAbs_', '').lower()} "
                              "geometry without surfaces)")
    return faces


def _face_surface(face, index: int, path: Path):
    """(face whose surface is a B-spline, its :class:`NurbsSurface`, the converter or None);
    raises :class:`CADImportError` when the face cannot be converted (it is then skipped)."""
    work, gsurf, conv = _to_bspline_face(face, index, path)
    try:
        surface = _nurbs_surface(gsurf, work)
    except ValueError as exc:
        raise CADImportError(f"{path}: face {index} has an invalid B-spline surface: "
                             f"{exc}") from exc
    from .number_check import MAX_MODEL_COORDINATE

    big = float(np.max(np.abs(surface.control))) if surface.control.size else 0.0
    if not big <= MAX_MODEL_COORDINATE:  # issue 33 fuzz: 1E+300 in a control point made the
        # edge sampling subdivide without end (memory without bound, the process OOM-killed)
        raise CADImportError(f"{path}: face {index} has a control point at {big:.3g} mm, beyond "
                             f"+-{MAX_MODEL_COORDINATE:g} mm (a million km): a damaged number in "
                             "the file? Export it again from the CAD system")
    return work, surface, conv


def read_cad(path, *, chord_tol: float = 0.002, gap_tol: float = 0.02, isolated: bool = True,
             timeout: float | None = None) -> Model:
    """Read a STEP (.step/.stp) or IGES (.igs/.iges) file into a trimmed-NURBS :class:`Model`.

    Parameters
    ----------
    path : str or Path
    chord_tol : float, optional
        Largest 3D deviation (mm) allowed between a face's true boundary and its sampled trimming
        polyline (default 0.002 mm).
    gap_tol : float, optional
        Edges that pass within ``gap_tol`` mm of another edge (or within 1e-5 of the model size, or
        twice the edge's own tolerance, whichever is largest) are taken to be shared even if the
        file does not say so (unsewn IGES faces); default 0.02 mm.  0 trusts the file's topology.
    isolated : bool, optional
        Run OpenCASCADE in the importer child process (:mod:`shapeverify.cad.occ_worker`, the
        default), so that a crash of the native library on a damaged file raises
        :class:`CADImportError` instead of killing this process.  ``False`` imports in this
        process (faster by the start of the child on a first import; for debugging).
    timeout : float, optional
        With ``isolated``: seconds after which the import is stopped (default:
        :func:`shapeverify.cad.occ_worker.default_time_limit`, 120 s + 30 s per MB).

    Returns
    -------
    Model
        ``kind="cad"``, one :class:`Face` per face of the file (``TopExp_Explorer`` order), in mm;
        ``unit`` and ``scale_to_mm`` give the length unit the file declared;
        ``n_faces_in_file`` the faces the file declares and ``skipped_faces`` why any of them
        is missing (each is also named in a logged warning).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    UnsupportedFormatError
        If the extension is not .step/.stp/.igs/.iges.
    CADImportError
        If the file is empty, corrupt, truncated, holds a number that is not a finite double
        (:mod:`shapeverify.cad.number_check`), the import exceeds its time limit, none of its faces can be converted, OpenCASCADE
        raises, or the importer crashes (the message names the file and the signal).
    EmptyModelError
        If the file holds no shapes, or shapes without faces (only wires or points).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from shapeverify.cad.examples import example_part_step
    >>> with tempfile.TemporaryDirectory() as d:
    ...     model = read_cad(example_part_step(pathlib.Path(d) / "panel.step"))
    >>> len(model.faces), model.n_faces_in_file, model.unit, model.scale_to_mm
    (1, 1, 'millimetre', 1.0)
    """
    if not (chord_tol > 0 and np.isfinite(chord_tol)):
        raise ValueError(f"chord_tol must be a positive number of mm, got {chord_tol!r}")
    if not (gap_tol >= 0 and np.isfinite(gap_tol)):
        raise ValueError(f"gap_tol must be a non-negative number of mm, got {gap_tol!r}")
    if timeout is not None and not (timeout > 0):
        raise ValueError(f"timeout must be a positive number of seconds or None, got {timeout!r}")
    path, fmt = _check_path(path)
    if isolated:
        from .occ_worker import read_cad_isolated

        return read_cad_isolated(path, chord_tol=chord_tol, gap_tol=gap_tol, timeout=timeout)
    try:
        return _read_cad_here(path, fmt, chord_tol, gap_tol)
    except (ShapeVerifyError, OSError):
        raise
    except Exception as exc:  # noqa: BLE001 - OpenCASCADE raises Standard_Failure & co.
        raise CADImportError(f"{path}: OpenCASCADE could not read the file "
                             f"({type(exc).__name__}: {exc})") from exc


def _open_seams(path: Path, fmt: str, all_free) -> list:
    """One line per face with boundary segments that meet no other face, when the STEP file
    declares closed shells and no open ones (a solid has no free edges: measured, none in the
    shared NIST parts and the wavy cube); [] otherwise (IGES, surface models)."""
    if fmt != "step" or not any(any(f.any() for f in fr) for fr in all_free):
        return []
    try:
        data = path.read_bytes()
    except OSError:
        return []
    if b"CLOSED_SHELL" not in data or b"OPEN_SHELL" in data:
        return []
    return [f"face {i}: {n} boundary segment{'s' if n > 1 else ''} meet no other face"
            for i, fr in enumerate(all_free) for n in (int(sum(int(f.sum()) for f in fr)),)
            if n]


def _supplemental_flags(shape, faces) -> list:
    """One bool per face of ``faces``: True for a face that belongs to no solid of a shape that
    has a solid (supplemental geometry: an open shell or a free face beside the part's solid,
    NIST FTC 10's 18 faces, CTC 04's 'Fill.1'); all False when no face is in a solid (a
    surface model: every face is the part)."""
    from OCP.collections import (
        IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as FaceSolids)
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID
    from OCP.TopExp import TopExp

    m = FaceSolids()
    TopExp.MapShapesAndUniqueAncestors_s(shape, TopAbs_FACE, TopAbs_SOLID, m)
    in_solid = [m.Contains(f) and m.FindFromKey(f).Size() > 0 for f in faces]
    if not any(in_solid):
        return [False] * len(faces)
    return [not x for x in in_solid]


def _missing_faces(path: Path, fmt: str, n_read: int, skipped: list) -> int:
    """The faces the file declares (:func:`~shapeverify.cad.face_count.declared_faces`, at
    least the ``n_read`` OpenCASCADE found); appends to ``skipped`` a line per declared face
    OpenCASCADE did not turn into a face."""
    from .face_count import declared_faces

    try:
        declared, notes = declared_faces(path, fmt)
    except (OSError, ValueError) as exc:  # the count is advice; the import stands without it
        logger.debug("%s: could not count the faces the file declares: %s", path, exc)
        declared, notes = n_read, []
    n_in_file = max(declared, n_read)
    if n_in_file > n_read:
        untransferred = n_in_file - n_read
        skipped.extend(notes[:untransferred])
        if untransferred > len(notes):
            skipped.append(f"{untransferred - len(notes)} face(s) declared in the file that "
                           "OpenCASCADE could not turn into faces (broken or missing entities)")
    return n_in_file


def _read_cad_here(path: Path, fmt: str, chord_tol: float, gap_tol: float) -> Model:
    """The import itself, in this process."""
    t_start = time.perf_counter()
    _init_ocp()
    from OCP.TopAbs import TopAbs_REVERSED

    from .summary import face_ranges

    shape, unit, scale, names_doc = _read_shape_named(path, fmt)
    t_read = time.perf_counter()
    faces = _shape_faces(path, fmt, shape)
    edge_faces = _edge_face_map(shape)
    supp_flags = _supplemental_flags(shape, faces)
    if names_doc is not None:
        from .step_names import face_names
        file_names = face_names(names_doc, faces)
    else:
        file_names = (None,) * len(faces)
    kept_names, supplemental = [], []

    surfaces, rev, all_uv, all_xyz, all_free, all_tol, all_edge = [], [], [], [], [], [], []
    edge_base = 0
    n_converted = 0
    skipped = []
    for i, face in enumerate(faces):
        try:
            work, surface, conv = _face_surface(face, i, path)
            uv, xyz, fr, tl, ed = _face_loops(work, face, conv, surface, edge_faces, chord_tol,
                                              i, path)
        except Exception as exc:  # noqa: BLE001 - one bad face does not spoil the others
            why = str(exc).replace(f"{path}: ", "") if isinstance(exc, ShapeVerifyError) \
                else f"{type(exc).__name__}: {exc}"
            skipped.append(f"face {i}: {why}")
            continue
        n_converted += conv is not None
        all_edge.append([e + edge_base for e in ed])
        edge_base += 1 + max(int(e.max()) for e in ed)
        if supp_flags[i]:
            supplemental.append(len(surfaces))  # its index among the faces kept
        surfaces.append(surface)
        kept_names.append(file_names[i])
        rev.append(face.Orientation() == TopAbs_REVERSED)
        all_uv.append(uv)
        all_xyz.append(xyz)
        all_free.append(fr)
        all_tol.append(tl)
    t_faces = time.perf_counter()
    if not surfaces:
        raise CADImportError(f"{path}: none of the {len(faces)} faces could be converted "
                             f"({'; '.join(skipped[:3])}{' ...' if len(skipped) > 3 else ''})")

    n_in_file = _missing_faces(path, fmt, len(faces), skipped)
    if skipped:
        logger.warning("%s: %d of the %d faces in the file were not loaded: %s", path,
                       n_in_file - len(surfaces), n_in_file, "; ".join(skipped))

    if gap_tol > 0:
        _clear_touching(all_xyz, all_free, all_edge, all_tol, gap_tol)
    if supplemental and len(supplemental) == len(surfaces):
        supplemental = []  # the faces of the solid were all skipped: keep what there is
    if supplemental:
        logger.info("%s: %d supplemental face(s) outside the solid (open shells or free "
                    "faces: %s) keep their numbers but are not part of the surface inspected",
                    path.name, len(supplemental), face_ranges(supplemental))
    seams = _open_seams(path, fmt, all_free)
    if seams:
        logger.warning("%s: the file declares closed shells (solids) but the model has open "
                       "seams: %s", path, "; ".join(seams))
    model = Model(faces=tuple(Face(s, tuple(uv), tuple(fr), r)
                              for s, uv, fr, r in zip(surfaces, all_uv, all_free, rev)),
                  unit=unit, scale_to_mm=scale, source=str(path), kind="cad",
                  n_faces_in_file=n_in_file, skipped_faces=tuple(skipped),
                  face_names=tuple(kept_names) if any(n is not None for n in kept_names)
                  else None, open_seams=tuple(seams), supplemental=tuple(supplemental))
    t_end = time.perf_counter()
    n_seg = sum(lp.shape[0] for uv in all_uv for lp in uv)
    n_free = sum(int(f.sum()) for fr in all_free for f in fr)
    logger.info("%s: %d faces (%d converted to NURBS), unit %s (%g mm), %d trim segments "
                "(%d on free edges); read %.2f s, faces %.2f s, total %.2f s",
                path.name, len(surfaces), n_converted, unit, scale, n_seg, n_free,
                t_read - t_start, t_faces - t_read, t_end - t_start)
    from .number_check import check_extent

    b = model.bounds  # cached: computed here anyway (the importer sends it with the model)
    check_extent(path, b[0], b[1])  # issue 33 fuzz: a finite but absurd number in the file
    return model
