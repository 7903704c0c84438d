"""Semantic PMI of a STEP AP242 file (datums, geometric tolerances, dimensions), read through
OpenCASCADE's XCAF document.

:func:`read_pmi` reads the file with ``STEPCAFControl_Reader`` in GD&T mode (``SetGDTMode``),
walks the document's ``XCAFDoc_DimTolTool`` (``GetDatumLabels``, ``GetGeomToleranceLabels``,
``GetDimensionLabels``) and turns each ``XCAFDimTolObjects_*Object`` into plain Python data:

* a **geometric tolerance**: its type (OpenCASCADE's name without the enum prefix:
  ``Position``, ``ProfileOfSurface``, ``Perpendicularity`` ...), zone value (mm), type of
  value (``Diameter`` for a cylindrical zone), zone modifier (``Projected``, ``Runout``,
  ``NonUniform``) and its value, material modifier (``M``/``L``), other modifiers, and the
  datum reference frame (each datum's letter, its order -- 1 primary, 2 secondary, 3 tertiary
  -- and its modifiers; ``GetDatumOfTolerLabels``);
* a **dimension**: type (``Size_Diameter``, ``Location_LinearDistance`` ...), nominal, the
  limits of deviation ``lower``/``upper`` (mm; OpenCASCADE gives the lower deviation as its
  magnitude, so ``lower = -GetLowerTolValue()``), qualifier, modifiers, or a range;
* a **datum** (one entry per letter; OpenCASCADE writes one datum label per use in a datum
  reference frame): letter, the faces of its datum feature, its datum targets (type, number,
  faces, and ``at``/``direction``/``xdirection``/``length``/``width``: :func:`_target_params`).

Every item is tied to the faces it controls by **shape identity**: the faces of
``GetRefShapeLabel`` (a solid or shell stands for its faces) are looked up with ``IsSame``
(then ``IsPartner`` for a part placed by an assembly) among the faces of the document's shape
in ``TopExp_Explorer`` order -- the enumeration of :mod:`shapeverify.cad.occ_import`
(``_shape_faces``), from which the model's face numbers come.  Each referenced face also gets
its vertices (mm), so that the caller can check the numbering against the imported model.
A datum that XCAF leaves without a shape because the file ties it to its faces by an
``ITEM_IDENTIFIED_REPRESENTATION_USAGE`` whose item the reader does not read (a
``SET_REPRESENTATION_ITEM``) is attached from the STEP entities (:mod:`.pmi_iiru`; ``attached``
says so); one set up from datum targets of a type XCAF does not read (a ``'circular curve'``,
NIST FTC 06's G and H) gets them from the STEP entities (:func:`.pmi_iiru.resolve_curve_targets`);
one that cannot be attached keeps ``unattached``, the reason.  A datum target attached to an
edge (a line drawn on a face: FTC 06's J and K) keeps the edge's record (``edges``:
:func:`.pmi_edges.edge_record`, with the face it lies on).

Each tolerance and dimension keeps the name the file gives it (``name``: ``Position.3``).  A
tolerance or dimension that the file's text declares but XCAF does not return (one tied to
supplemental geometry only: NIST CTC 04's ``Position.3``) is listed in ``unread`` with the
entity and why (:mod:`.pmi_text`).

The read runs in the project's importer child process (:mod:`shapeverify.cad.occ_worker`), so
that a crash of OpenCASCADE on a damaged file raises :class:`~shapeverify.errors.CADImportError`
instead of killing the caller.  Lengths in mm (the session unit is pinned to mm, and the
reader converts the PMI values with the geometry).
"""
from __future__ import annotations

import logging
import os
from pathlib import Path

from ..errors import CADImportError, UnsupportedFormatError
from .pmi_construction import attach_construction_sides
from .pmi_text import unread_pmi_of_file

logger = logging.getLogger(__name__)

__all__ = ["read_pmi", "read_pmi_here"]

_GT_PREFIX = "XCAFDimTolObjects_GeomToleranceType_"
_DIM_PREFIX = "XCAFDimTolObjects_DimensionType_"


def read_pmi(path, *, timeout: float | None = 600.0, isolated: bool = True) -> dict:
    """The semantic PMI of a STEP file (see the module docstring for the fields).

    Parameters
    ----------
    path : str or Path
        A STEP file (.stp/.step), AP242 with semantic PMI for a non-empty answer.
    timeout : float, optional
        Seconds after which the importer process is stopped (default 600).
    isolated : bool, optional
        Read in the importer child process (default); False reads in this process.

    Returns
    -------
    dict
        ``source``, ``n_faces`` (faces of the shape, ``TopExp_Explorer`` order),
        ``datums``, ``tolerances``, ``dimensions`` (lists of dicts, each with ``id``,
        ``kind``, ``type`` and ``faces``: face indices in that order) and ``face_vertices``
        ({face index: list of vertex points (mm)} for every face an item names).

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    UnsupportedFormatError
        Not a STEP file (IGES carries no semantic PMI).
    CADImportError
        OpenCASCADE cannot read the file, crashes or takes longer than ``timeout``.
    """
    p = Path(path)
    if p.suffix.lower() not in (".stp", ".step"):
        raise UnsupportedFormatError(f"{p}: semantic PMI is read from STEP AP242 files "
                                     f"(.stp/.step), not {p.suffix or 'a file without suffix'!r}")
    if not p.exists():
        raise FileNotFoundError(2, "STEP file not found", str(p))
    if not p.is_file() or p.stat().st_size == 0:
        raise CADImportError(f"{p}: not a regular, non-empty file")
    if isolated:
        from .occ_worker import pmi_isolated

        return pmi_isolated(p, timeout=timeout)
    return read_pmi_here(p)


# ------------------------------------------------------------------------------ OCP helpers
def _attr(label, cls):
    """The attribute of class ``cls`` on ``label`` (OCP's ``FindAttribute`` does not hand the
    found handle back to Python, so the label's attributes are iterated)."""
    from OCP.TDF import TDF_AttributeIterator

    it = TDF_AttributeIterator(label)
    while it.More():
        v = it.Value()
        if isinstance(v, cls):
            return v
        it.Next()
    return None


def _labels(fn, *args) -> list:
    from OCP.collections import Sequence_TDF_Label

    seq = Sequence_TDF_Label()
    fn(*args, seq)
    return [seq.Value(i) for i in range(1, seq.Length() + 1)]


def _ref_labels(label) -> tuple[list, list]:
    from OCP.collections import Sequence_TDF_Label
    from OCP.XCAFDoc import XCAFDoc_DimTolTool

    first, second = Sequence_TDF_Label(), Sequence_TDF_Label()
    XCAFDoc_DimTolTool.GetRefShapeLabel_s(label, first, second)
    return ([first.Value(i) for i in range(1, first.Length() + 1)],
            [second.Value(i) for i in range(1, second.Length() + 1)])


def _enum_name(v, prefix: str = "") -> str:
    name = getattr(v, "name", str(v))
    if prefix and name.startswith(prefix):
        return name[len(prefix):]
    return name.rsplit("_", 1)[-1] if "_" in name else name


def _semantic_name(o) -> str:
    """The name the file gives a tolerance or dimension ('Position.3'), or ''."""
    n = o.GetSemanticName()
    return n.ToCString() if n is not None else ""


def _seq(values) -> list:
    try:
        return list(values)
    except TypeError:
        return []


class _FaceIndex:
    """Face index of a shape by identity (``IsSame``; ``IsPartner`` for assembly instances)."""

    def __init__(self, faces):
        from OCP.TopLoc import TopLoc_Location
        from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap

        self.faces = faces
        self.bare = TopLoc_Location()
        self.exact, self.partner = ShapeMap(), ShapeMap()
        self.at_exact, self.at_partner = {}, {}
        for i, f in enumerate(faces):
            self.at_exact.setdefault(self.exact.Add(f), []).append(i)
            self.at_partner.setdefault(self.partner.Add(f.Located(self.bare)), []).append(i)

    def of(self, shape) -> tuple[list, list]:
        """(face indices, kinds of the non-face shapes) of a referenced shape."""
        from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX
        from OCP.TopExp import TopExp_Explorer

        if shape is None or shape.IsNull():
            return [], []
        t = shape.ShapeType()
        if t in (TopAbs_EDGE, TopAbs_VERTEX):
            return [], [_enum_name(t).lower()]
        subs = [shape] if t == TopAbs_FACE else []
        if t != TopAbs_FACE:
            exp = TopExp_Explorer(shape, TopAbs_FACE)
            while exp.More():
                subs.append(exp.Current())
                exp.Next()
        out = []
        for s in subs:
            k = self.exact.FindIndex(s)
            if k > 0:
                out.extend(self.at_exact[k])
                continue
            k = self.partner.FindIndex(s.Located(self.bare))
            if k > 0:
                out.extend(self.at_partner[k])
        return out, []


def _faces_of(labels, index: _FaceIndex) -> tuple[list, list]:
    from OCP.XCAFDoc import XCAFDoc_ShapeTool

    faces, other = [], []
    for lab in labels:
        f, o = index.of(XCAFDoc_ShapeTool.GetShape_s(lab))
        faces.extend(x for x in f if x not in faces)
        other.extend(o)
    return faces, other


def _edges_of(labels) -> list:
    """The edges among the shapes of reference labels."""
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.XCAFDoc import XCAFDoc_ShapeTool

    out = []
    for lab in labels:
        s = XCAFDoc_ShapeTool.GetShape_s(lab)
        if s is not None and not s.IsNull() and s.ShapeType() == TopAbs_EDGE:
            out.append(s)
    return out


class _Edges:
    """Edge references of PMI items -> the faces of the feature they bound
    (:mod:`shapeverify.cad.pmi_edges`)."""

    def __init__(self, shape, faces, index):
        from ._occ_loops import _edge_face_map

        self.faces, self.index = faces, index
        self.map = _edge_face_map(shape)

    def resolve(self, item: dict, labels, key: str = "faces") -> None:
        """Edges of ``labels`` on ``item``: ``edges`` (records), and when ``item[key]`` is empty
        either the bounded feature's faces in ``item[key]`` with ``attached`` (how), or
        ``edge_reason`` (why not)."""
        from .pmi_edges import edge_feature, edge_record

        edges = _edges_of(labels)
        if not edges:
            return
        recs = [edge_record(e, self.index, self.map, self.faces) for e in edges]
        item["edges" if key == "faces" else "edges2"] = recs
        if item[key]:
            return
        fs, how, why = edge_feature(recs, self.faces, self.map, self.index)
        suffix = "" if key == "faces" else "2"
        if fs:
            item[key] = fs
            item["attached" + suffix] = how
        else:
            item["edge_reason" + suffix] = why


def _vertices(face) -> list:
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_VERTEX
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    pts = []
    exp = TopExp_Explorer(face, TopAbs_VERTEX)
    while exp.More():
        p = BRep_Tool.Pnt_s(TopoDS.Vertex(exp.Current()))
        pts.append([p.X(), p.Y(), p.Z()])
        exp.Next()
    return pts


def _target_params(o) -> dict:
    """A datum target's placement and size (mm): ``at`` (the axis' location: the point of a
    point target, the centre of a circle, the middle of a line), ``direction`` (its main
    direction: a line target's direction, a circle's normal), ``xdirection``, ``length``
    (a line's length, a circle's diameter, a rectangle's length) and ``width``; ``{}`` when
    the file gives no parameters (``HasDatumTargetParams``)."""
    if not o.HasDatumTargetParams():
        return {}
    ax = o.GetDatumTargetAxis()
    loc, d, x = ax.Location(), ax.Direction(), ax.XDirection()
    return {"at": [loc.X(), loc.Y(), loc.Z()], "direction": [d.X(), d.Y(), d.Z()],
            "xdirection": [x.X(), x.Y(), x.Z()], "length": float(o.GetDatumTargetLength()),
            "width": float(o.GetDatumTargetWidth())}


def _unique_drf(drf: list) -> list:
    """The datum reference frame in order, one entry per (letter, order): a datum set up from
    several datum targets (A1, A2, A3) comes as one label per target."""
    out: dict = {}
    for d in sorted(drf, key=lambda x: x["order"]):
        e = out.setdefault((d["name"], d["order"]), {**d, "modifiers": []})
        e["modifiers"].extend(m for m in d["modifiers"] if m not in e["modifiers"])
    return list(out.values())


# ------------------------------------------------------------------------------ the read
def _open(path: Path):
    """(document, shape, reader) of a STEP file read with GD&T (and names) on."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document

    STEPCAFControl_Controller.Init_s()
    caf = STEPCAFControl_Reader()
    caf.SetGDTMode(True)
    caf.SetNameMode(True)
    status = caf.ReadFile(os.fspath(path))
    if status != IFSelect_RetDone:
        raise CADImportError(f"{path}: not a readable STEP file (OpenCASCADE reader status "
                             f"{status.name.replace('IFSelect_Ret', '')})")
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    if not caf.Transfer(doc):
        raise CADImportError(f"{path}: OpenCASCADE could not transfer the STEP file into an "
                             "XCAF document (shapes and PMI)")
    shape = caf.Reader().OneShape()
    if shape is None or shape.IsNull():
        raise CADImportError(f"{path}: the STEP file holds no shape to attach PMI to")
    return doc, shape, caf


def _unattached(caf, names) -> dict:
    """{datum letter: how the STEP file attaches the datum} for datums that OpenCASCADE's
    XCAF reader leaves without a shape, read from the STEP entities: the shape aspect its
    ``SHAPE_ASPECT_RELATIONSHIP`` names (a ``PLACED_DATUM_TARGET_FEATURE`` of a type the
    reader does not read, or a datum feature tied to the geometry by an
    ``ITEM_IDENTIFIED_REPRESENTATION_USAGE`` whose item the reader does not resolve)."""
    from OCP.StepAP242 import StepAP242_ItemIdentifiedRepresentationUsage
    from OCP.StepDimTol import StepDimTol_Datum, StepDimTol_DatumTarget
    from OCP.StepRepr import StepRepr_ShapeAspectRelationship

    model = caf.Reader().WS().Model()
    # the entities stay referenced in ``ents``, so OCP hands back the same Python object for
    # the same entity (``Interface_InterfaceModel::Number`` answers 0 through OCP)
    ents = [model.Value(i) for i in range(1, model.NbEntities() + 1)]
    iiru = {}
    for e in ents:
        if isinstance(e, StepAP242_ItemIdentifiedRepresentationUsage):
            d = e.Definition().Value() if e.Definition() is not None else None
            if d is not None:
                iiru.setdefault(id(d), []).append(e)

    def label(x) -> str:
        n = x.Name().ToCString() if x.Name() is not None else ""
        return f"{type(x).__name__.split('_', 1)[-1]} {n!r}" if n else type(x).__name__

    out = {}
    for e in ents:
        if not isinstance(e, StepRepr_ShapeAspectRelationship):
            continue
        b, a = e.RelatedShapeAspect(), e.RelatingShapeAspect()
        if not isinstance(b, StepDimTol_Datum) or a is None:
            continue
        name = b.Identification().ToCString()
        if name not in names or name in out:
            continue
        if isinstance(a, StepDimTol_DatumTarget):
            desc = a.Description().ToCString() if a.Description() is not None else ""
            out[name] = (f"the file sets it up from the datum target {label(a)} of type "
                         f"{desc!r}, which OpenCASCADE's XCAF reader does not read (it reads "
                         "point, line, rectangle, circle and area targets)")
        elif id(a) in iiru:
            out[name] = (f"the file ties its datum feature {label(a)} to faces by an "
                         "ITEM_IDENTIFIED_REPRESENTATION_USAGE whose item (a "
                         "SET_REPRESENTATION_ITEM) OpenCASCADE's XCAF reader does not resolve")
        else:
            out[name] = (f"its datum feature {label(a)} is tied to no geometry in the file (no "
                         "GEOMETRIC_ITEM_SPECIFIC_USAGE or ITEM_IDENTIFIED_REPRESENTATION_USAGE)")
    return out


def _attach_by_usage(caf, path, names, index, datum_list) -> set:
    """The datums of ``names`` attached here to the faces their ITEM_IDENTIFIED_REPRESENTATION_
    USAGE names (:mod:`.pmi_iiru`): ``faces`` and ``attached`` set, or ``usage_reason`` (why
    the usage did not resolve; added to ``unattached``)."""
    from .pmi_iiru import resolve_datums

    try:
        got = resolve_datums(caf, path, names, index)
    except Exception as e:      # a diagnosis beyond XCAF; the read stands without it
        logger.warning("%s: could not follow the usages of datums %s: %s", path.name,
                       sorted(names), e)
        return set()
    done = set()
    for d in datum_list:
        faces, how = got.get(d["name"], (None, ""))
        if faces:
            d["faces"], d["attached"] = list(faces), how
            done.add(d["name"])
        elif how:
            d["usage_reason"] = how
    return done


def _attach_dimension_groups(caf, path, index, dimensions) -> None:
    """``group_faces`` of the linear location dimensions whose two sides are components of one
    composite shape aspect (:func:`.pmi_iiru.dimension_groups`): every face of that composite,
    which the plan measures when the two sides alone do not make the dimension (coplanar)."""
    want = [d for d in dimensions if d["type"] == "Location_LinearDistance"]
    if not want:
        return
    from .pmi_iiru import dimension_groups

    try:
        groups = dimension_groups(caf, index)
    except Exception as e:      # a diagnosis beyond XCAF; the read stands without it
        logger.warning("%s: could not follow the composite shape aspects of dimensions: %s",
                       path.name, e)
        return
    for d in want:
        sides = {frozenset(d["faces"]), frozenset(d["faces2"])}
        hits = [g for fa, fb, g in groups if {frozenset(fa), frozenset(fb)} == sides]
        if len(hits) == 1 and len(hits[0]) > len(d["faces"]) + len(d["faces2"]):
            d["group_faces"] = hits[0]


def _attach_curve_targets(caf, path, names, index, edges, datum_list) -> set:
    """The datums of ``names`` set up from datum targets XCAF does not read (a 'circular
    curve'), their targets read here from the STEP entities (:mod:`.pmi_iiru`): ``targets``
    set and ``type`` DatumTarget; a target that did not resolve keeps ``target_reason``."""
    from .pmi_iiru import resolve_curve_targets

    try:
        got = resolve_curve_targets(caf, names, index, edges.map, edges.faces)
    except Exception as e:      # a diagnosis beyond XCAF; the read stands without it
        logger.warning("%s: could not follow the datum targets of datums %s: %s", path.name,
                       sorted(names), e)
        return set()
    done = set()
    for d in datum_list:
        ts = got.get(d["name"])
        if ts:
            d["targets"] = sorted(ts, key=lambda t: t["number"])
            d["type"] = "DatumTarget"
            done.add(d["name"])
    return done


def _mark_composites(path, tolerances) -> list:
    """Mark the two segments of each composite feature control frame (``composite``:
    :func:`.step_composite.match_composites`; XCAF does not keep the relationship); the
    relationships that could not be matched to the tolerances XCAF read."""
    from .step_composite import composite_relations_of_file, match_composites
    from .step_units import length_unit_of_file

    try:
        rels = composite_relations_of_file(path)
        if not rels:
            return []
        unit = length_unit_of_file(path)
        missed = match_composites(rels, tolerances, unit[1] if unit else 1.0)
    except (OSError, ValueError) as exc:
        logger.warning("%s: could not read the composite tolerances: %s", path.name, exc)
        return []
    for m in missed:
        logger.warning("%s: composite frame %s / %s not matched to the tolerances read: %s",
                       path.name, m["upper"]["name"], m["lower"]["name"], m["reason"])
    return missed


def _unit_slip(path, tolerances) -> None:
    """Tolerance values the file writes in inches with the millimetre unit, read as inches
    (:mod:`.step_unit_slip`: NIST CTC 03 e1)."""
    from .step_unit_slip import apply_unit_slip

    try:
        if apply_unit_slip(path, tolerances):
            logger.warning("%s: the geometric tolerance values are written with the "
                           "millimetre unit but the dimensions in inches; read as inches",
                           path.name)
    except (OSError, ValueError) as exc:
        logger.warning("%s: could not check the tolerance units: %s", path.name, exc)


def _max_tolerances(path, tolerances) -> None:
    """``max_value`` (the frame's "MAX", mm) of the tolerances whose maximum XCAF did not
    read (:mod:`.step_maxtol`)."""
    from .step_maxtol import apply_max_tolerances
    from .step_units import length_unit_of_file

    if not any(t["material"] and t["max_value"] == 0.0 for t in tolerances):
        return
    try:
        unit = length_unit_of_file(path)
        _, odd = apply_max_tolerances(path, tolerances, unit[1] if unit else 1.0)
    except (OSError, ValueError) as exc:
        logger.warning("%s: could not read the maximum tolerances: %s", path.name, exc)
        return
    for gid, why in odd:
        logger.warning("%s: maximum tolerance of %s not read: %s", path.name, gid, why)


def _object(lab, attribute):
    """The XCAF object of a label's ``attribute`` (a datum, tolerance or dimension), or None."""
    a = _attr(lab, attribute)
    return None if a is None else a.GetObject()


def _guarded(failed: list, kind: str, k: int, lab, read, *args):
    """``read(lab, *args)``; if it raises, the label is recorded in ``failed`` (an ``unread``
    entry with the error) and None returned: one PMI record OpenCASCADE or this module cannot
    read never costs the file's others (a file from another CAD system encodes what ours
    never met)."""
    try:
        return read(lab, *args)
    except Exception as exc:        # noqa: BLE001 -- reported in ``unread`` with the error
        typ, name = _label_identity(lab, kind)
        logger.warning("PMI %s label %d (%s %r) could not be read: %s: %s", kind, k, typ, name,
                       type(exc).__name__, exc)
        failed.append({"kind": kind, "type": typ, "name": name, "entity": f"XCAF label {k}",
                       "reason": f"reading this {kind.replace('_', ' ')} failed "
                                 f"({type(exc).__name__}: {exc}); it is not checked: inspect "
                                 "it by hand (an error of shapeverify on this file's encoding: "
                                 "please report it with the file)"})
        return None


def _label_identity(lab, kind: str) -> tuple[str, str]:
    """(type, name) of a PMI label as far as they can be read ('Unknown', '' otherwise)."""
    from OCP.XCAFDoc import XCAFDoc_Datum, XCAFDoc_Dimension, XCAFDoc_GeomTolerance

    try:
        if kind == "datum":
            o = _object(lab, XCAFDoc_Datum)
            return "Datum", o.GetName().ToCString() if o.GetName() is not None else ""
        if kind == "geometric_tolerance":
            o = _object(lab, XCAFDoc_GeomTolerance)
            return _enum_name(o.GetType(), _GT_PREFIX), _semantic_name(o)
        o = _object(lab, XCAFDoc_Dimension)
        return _enum_name(o.GetType(), _DIM_PREFIX), _semantic_name(o)
    except Exception:               # noqa: BLE001 -- the identity is a courtesy
        return "Unknown", ""


def _read_datum(lab, index, edges, faces, datums: dict) -> None:
    """Add one datum label to ``datums`` ({letter: record}; a letter has a label per use)."""
    from OCP.XCAFDoc import XCAFDoc_Datum

    o = _object(lab, XCAFDoc_Datum)
    if o is None:
        return
    name = o.GetName().ToCString() if o.GetName() is not None else ""
    first, _ = _ref_labels(lab)
    fs, other = _faces_of(first, index)
    d = datums.setdefault(name, {"kind": "datum", "type": "Datum", "name": name,
                                 "faces": [], "other": [], "targets": [], "labels": 0})
    d["labels"] += 1
    if o.IsDatumTarget():
        t = {"type": _enum_name(o.GetDatumTargetType()),
             "number": int(o.GetDatumTargetNumber()), "faces": fs, "other": other,
             **_target_params(o)}
        if not fs and "edge" in other:      # a line drawn on a face (NIST FTC 06 J, K)
            from .pmi_edges import edge_record

            t["edges"] = [edge_record(e, index, edges.map, faces) for e in _edges_of(first)]
        d["targets"].append(t)
        return
    if not fs:                  # a datum feature named by its edge (a hole's rim)
        probe = {"faces": []}
        edges.resolve(probe, first)
        fs = probe["faces"]
        for key in ("attached", "edge_reason"):
            if probe.get(key):
                d[key] = probe[key]
    d["faces"].extend(f for f in fs if f not in d["faces"])
    d["other"].extend(other)


def _read_tolerance(lab, k: int, index, edges) -> dict | None:
    """The record of one geometric tolerance label (None: not a tolerance)."""
    from OCP.XCAFDoc import XCAFDoc_Datum, XCAFDoc_DimTolTool, XCAFDoc_GeomTolerance

    o = _object(lab, XCAFDoc_GeomTolerance)
    if o is None:
        return None
    first, _ = _ref_labels(lab)
    fs, other = _faces_of(first, index)
    drf = []
    for dl in _labels(XCAFDoc_DimTolTool.GetDatumOfTolerLabels_s, lab):
        do = _object(dl, XCAFDoc_Datum)
        if do is None:
            continue
        drf.append({"name": do.GetName().ToCString() if do.GetName() is not None else "",
                    "order": int(do.GetPosition()),
                    "modifiers": [_enum_name(m) for m in _seq(do.GetModifiers())]})
    mat = _enum_name(o.GetMaterialRequirementModifier())
    item = {"id": f"GT{k}", "kind": "geometric_tolerance",
            "type": _enum_name(o.GetType(), _GT_PREFIX), "name": _semantic_name(o),
            "value": float(o.GetValue()),
            "value_type": _enum_name(o.GetTypeOfValue()),
            "zone_modifier": _enum_name(o.GetZoneModifier()),
            "zone_modifier_value": float(o.GetValueOfZoneModifier()),
            "material": None if mat == "None" else mat,
            "max_value": float(o.GetMaxValueModifier()),
            "modifiers": [_enum_name(m, "XCAFDimTolObjects_GeomToleranceModif_")
                          for m in _seq(o.GetModifiers())],
            "datums": _unique_drf(drf), "faces": fs, "other": other}
    edges.resolve(item, first)
    return item


def _read_dimension(lab, k: int, index, edges) -> dict | None:
    """The record of one dimension label (None: not a dimension)."""
    from OCP.XCAFDoc import XCAFDoc_Dimension

    o = _object(lab, XCAFDoc_Dimension)
    if o is None:
        return None
    first, second = _ref_labels(lab)
    fs, other = _faces_of(first, index)
    fs2, other2 = _faces_of(second, index)
    item = {"id": f"DIM{k}", "kind": "dimension",
            "type": _enum_name(o.GetType(), _DIM_PREFIX), "name": _semantic_name(o),
            "nominal": float(o.GetValue()), "lower": None, "upper": None,
            "qualifier": _enum_name(o.GetQualifier()),
            "modifiers": [_enum_name(m, "XCAFDimTolObjects_DimensionModif_")
                          for m in _seq(o.GetModifiers())],
            "faces": fs, "faces2": fs2, "other": other + other2}
    if o.IsDimWithPlusMinusTolerance():
        item["lower"], item["upper"] = -float(o.GetLowerTolValue()), float(o.GetUpperTolValue())
    elif o.IsDimWithRange():
        item["lower"] = float(o.GetLowerBound()) - item["nominal"]
        item["upper"] = float(o.GetUpperBound()) - item["nominal"]
    elif o.IsDimWithClassOfTolerance():
        item["class_of_tolerance"] = True
    edges.resolve(item, first)
    edges.resolve(item, second, "faces2")
    return item


def read_pmi_here(path) -> dict:
    """:func:`read_pmi` in this process (what the importer child runs)."""
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    from .occ_import import _init_ocp, _shape_faces

    path = Path(path)
    _init_ocp()
    doc, shape, caf = _open(path)
    faces = _shape_faces(path, "step", shape)
    index = _FaceIndex(faces)
    edges = _Edges(shape, faces, index)
    tool = XCAFDoc_DocumentTool.DimTolTool_s(doc.Main())

    failed: list = []       # labels whose reading raised: listed in ``unread``, never lost
    # datums: one entry per letter (OpenCASCADE writes a datum label per use)
    datums: dict = {}
    for k, lab in enumerate(_labels(tool.GetDatumLabels), start=1):
        _guarded(failed, "datum", k, lab, _read_datum, index, edges, faces, datums)
    datum_list = []
    for k, (name, d) in enumerate(sorted(datums.items())):
        seen, targets = set(), []
        for t in d["targets"]:
            key = (t["type"], t["number"], tuple(t["faces"]))
            if key not in seen:
                seen.add(key)
                targets.append(t)
        d["targets"] = targets
        if targets and not d["faces"]:
            d["type"] = "DatumTarget"
        d["id"] = f"DATUM_{name or k}"
        datum_list.append(d)
    bare = {d["name"] for d in datum_list if not d["faces"] and not d["other"]
            and not d["targets"]}
    if bare:
        bare -= _attach_by_usage(caf, path, bare, index, datum_list)
    if bare:
        bare -= _attach_curve_targets(caf, path, bare, index, edges, datum_list)
    if bare:
        try:
            why = _unattached(caf, bare)
        except Exception as e:          # the reason is a diagnosis; the read stands without it
            logger.warning("%s: could not read how datums %s are attached: %s", path.name,
                           sorted(bare), e)
            why = {}
        for d in datum_list:
            parts = [x for x in (why.get(d["name"]), d.pop("usage_reason", None)) if x]
            if parts:
                d["unattached"] = "; ".join(parts)

    tolerances = [t for k, lab in enumerate(_labels(tool.GetGeomToleranceLabels), start=1)
                  if (t := _guarded(failed, "geometric_tolerance", k, lab, _read_tolerance,
                                    k, index, edges)) is not None]
    dimensions = [d for k, lab in enumerate(_labels(tool.GetDimensionLabels), start=1)
                  if (d := _guarded(failed, "dimension", k, lab, _read_dimension, k, index,
                                    edges)) is not None]
    _attach_dimension_groups(caf, path, index, dimensions)
    _unit_slip(path, tolerances)
    composites_missed = _mark_composites(path, tolerances)
    _max_tolerances(path, tolerances)
    attach_construction_sides(caf, index, dimensions)   # a side on supplemental curves

    used = set()
    for it in datum_list + tolerances + dimensions:
        used.update(it["faces"])
        used.update(it.get("faces2", ()))
        used.update(it.get("group_faces", ()))
        for t in it.get("targets", ()):
            used.update(t["faces"])
            used.update(t.get("on_faces", ()))
            for e in t.get("edges", ()):
                used.update(e.get("on_faces", ()))
    logger.info("%s: PMI %d datums, %d geometric tolerances, %d dimensions on %d of %d faces",
                path.name, len(datum_list), len(tolerances), len(dimensions), len(used),
                len(faces))
    try:
        unread = unread_pmi_of_file(path, tolerances + [f for f in failed if f["kind"] ==
                                                        "geometric_tolerance"],
                                    dimensions + [f for f in failed if f["kind"] == "dimension"])
    except (OSError, ValueError, RecursionError) as e:   # never lose the PMI that was read
        logger.warning("%s: could not compare the PMI read with the file's text: %s",
                       path.name, e)
        unread = []
    from .step_text import clear as _forget_text

    _forget_text()  # the text was parsed once for the four readers (step_text); let it go
    unread = [{k: f[k] for k in ("kind", "type", "name", "entity", "reason")}
              for f in failed] + unread
    return {"source": str(path), "n_faces": len(faces), "datums": datum_list,
            "tolerances": tolerances, "dimensions": dimensions, "unread": unread,
            **({"composites_unmatched": composites_missed} if composites_missed else {}),
            "face_vertices": {i: _vertices(faces[i]) for i in sorted(used)}}
