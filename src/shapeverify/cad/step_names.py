"""Face names of a STEP file (the names CAD systems give faces: ``ADVANCED_FACE('top', ...)``).

A STEP face entity carries a name (its first attribute); most exporters leave it empty (``''``)
or write ``'NONE'``, but some CAD systems and scripts name the faces a drawing refers to
(datum faces, sealing faces).  :func:`read_step_named` reads such a file through OpenCASCADE's
XCAF reader with sub-shape names switched on (``STEPCAFControl_Reader`` in name mode, static
parameter ``read.stepcaf.subshapes.name`` = 1, OCCT >= 7.6): every named face becomes a
sub-shape label of its part with a ``TDataStd_Name`` attribute.  :func:`face_names` then gives
each of the importer's faces its name by *shape identity*, never by file order: a labelled
face is looked up in an ``IndexedMap`` of the importer's faces (OpenCASCADE's ``IsSame``:
same topological face, same location); a face of a part placed several times in an assembly
(the label holds the part's face without the instance's location) gets the name on every
instance (same underlying face, ``IsPartner``).

:func:`has_face_names` decides, from the file's text, whether that route is needed at all:
a file whose face entities have no names is read exactly as before (``STEPControl_Reader``),
so its model is unchanged bit for bit.

The plain reader's own route (``XSControl_TransferReader.EntityFromShapeResult`` per face)
works too but scans the whole transfer map for each face (94 s for 3,000 faces, measured);
the XCAF route costs one document transfer (0.14 s for the names of the same 3,000 faces).
"""
from __future__ import annotations

import logging
import mmap
import os
import re
from pathlib import Path

logger = logging.getLogger(__name__)

__all__ = ["has_face_names", "read_step_named", "face_names", "NO_NAME"]

#: names that exporters write for an unnamed face (compared case-insensitively, stripped)
NO_NAME = frozenset({"", "none", "$"})

# ADVANCED_FACE('name', ...) or FACE_SURFACE('name', ...); STEP strings escape ' as ''.
# Each pattern starts with a literal (re's fast prefix search: 0.07 s for an 8 MB file, against
# 1.4 s for one case-insensitive alternation); keywords are upper case in Part 21 files.
_FACE_NAMES = ((re.compile(rb"_FACE\s*\(\s*'((?:[^']|'')*)'"), b"ADVANCED"),
               (re.compile(rb"FACE_SURFACE\s*\(\s*'((?:[^']|'')*)'"), b""))


def _is_name(raw: str) -> bool:
    return raw.strip().lower() not in NO_NAME


def has_face_names(path) -> bool:
    """True when some face entity of the STEP file at ``path`` has a real name (not ``''`` or
    ``'NONE'``).  Reads the file's text (memory-mapped); False for an unreadable file."""
    try:
        with open(os.fspath(path), "rb") as fh:
            if os.fstat(fh.fileno()).st_size == 0:
                return False
            with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
                for pattern, before in _FACE_NAMES:
                    for m in pattern.finditer(mm):
                        k = m.start()
                        if mm[k - len(before):k] == before and _is_name(
                                m.group(1).decode("latin-1")):
                            return True
    except (OSError, ValueError):
        return False
    return False


def read_step_named(path: Path):
    """Read a STEP file with the XCAF reader, face names on.

    Returns
    -------
    (STEPControl_Reader, TDocStd_Document, read status)
        The underlying reader (for the units and ``OneShape``) and the document holding the
        names; the caller checks the status and calls :func:`transfer`.
    """
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document

    STEPCAFControl_Controller.Init_s()          # defines the read.stepcaf.* parameters
    if not Interface_Static.SetIVal_s("read.stepcaf.subshapes.name", 1):
        logger.debug("this OpenCASCADE has no read.stepcaf.subshapes.name; no face names")
    caf = STEPCAFControl_Reader()
    caf.SetNameMode(True)
    for mode in ("SetColorMode", "SetLayerMode", "SetPropsMode", "SetGDTMode", "SetMatMode",
                 "SetViewMode", "SetSHUOMode"):
        if hasattr(caf, mode):
            getattr(caf, mode)(False)
    status = caf.ReadFile(os.fspath(path))
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    return caf, doc, status


def transfer(caf, doc):
    """Transfer the file into the document (names and shapes); return ``caf.Reader()``."""
    if not caf.Transfer(doc):
        raise RuntimeError("the XCAF transfer of the STEP file failed")
    return caf.Reader()


def _named_faces(doc):
    """(face shape, name) for every face sub-shape label of the document with a name."""
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDF import TDF_ChildIterator
    from OCP.TopAbs import TopAbs_FACE
    from OCP.XCAFDoc import XCAFDoc_DocumentTool, XCAFDoc_ShapeTool
    from OCP.collections import Sequence_TDF_Label

    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    labels = Sequence_TDF_Label()
    tool.GetShapes(labels)
    out = []
    for i in range(1, labels.Length() + 1):
        it = TDF_ChildIterator(labels.Value(i), True)
        while it.More():
            sub = it.Value()
            it.Next()
            shape = XCAFDoc_ShapeTool.GetShape_s(sub)
            if shape.IsNull() or shape.ShapeType() != TopAbs_FACE:
                continue
            attr = TDataStd_Name()
            if sub.FindAttribute(TDataStd_Name.GetID_s(), attr):
                name = attr.Get().ToExtString()
                if _is_name(name):
                    out.append((shape, name.strip()))
    return out


def face_names(doc, faces) -> tuple:
    """The name of each face in ``faces`` (a list of ``TopoDS_Face``), or None.

    Matched by shape identity (``IsSame``, then ``IsPartner`` for faces of a part instanced
    with a location in an assembly), never by position in the file.

    Returns
    -------
    tuple of (str or None)
        One entry per face of ``faces``.
    """
    from OCP.TopLoc import TopLoc_Location
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap

    exact, partner = ShapeMap(), ShapeMap()
    at_exact, at_partner = {}, {}
    bare = TopLoc_Location()
    for i, f in enumerate(faces):
        at_exact.setdefault(exact.Add(f), []).append(i)
        at_partner.setdefault(partner.Add(f.Located(bare)), []).append(i)
    names = [None] * len(faces)
    exact_named = set()
    pending = []
    for shape, name in _named_faces(doc):
        k = exact.FindIndex(shape)
        if k > 0:
            for i in at_exact[k]:
                names[i] = name
                exact_named.add(i)
        else:
            pending.append((shape, name))
    for shape, name in pending:  # a part's face placed by an assembly instance
        k = partner.FindIndex(shape.Located(bare))
        for i in at_partner.get(k, []) if k > 0 else []:
            if i not in exact_named:
                names[i] = name
    n = sum(x is not None for x in names)
    logger.debug("STEP face names: %d of %d faces named", n, len(faces))
    return tuple(names)
