"""The :class:`~shapeverify.cad.summary.ModelSummary` of a STEP or IGES file from OpenCASCADE
alone: what ``shapeverify info`` shows, without building the :class:`~shapeverify.cad.model.Model`.

Building the model samples every trimming loop and bounds every face with the numba kernels,
and the importer process must import numba and load those kernels first (~0.9 s of a new
file's ~2.9 s ``info``, ``benchmarks/results_coldstart.md``).  :func:`read_summary` gives the
same figures with OpenCASCADE's own queries (and numpy), in the importer child
(:func:`shapeverify.cad.occ_worker.summary_isolated`):

* **Faces.** The same faces as :func:`~shapeverify.cad.occ_import.read_cad`: the file is read by
  the same function, each face is converted to a B-spline surface by the same function (a face
  that cannot be converted, or whose surface is invalid, is skipped as there), and its wires'
  pcurves are collected by the same function as the import's trimming loops
  (:func:`~shapeverify.cad._occ_loops._face_wires`: a face without a boundary wire or with an
  edge without a pcurve is skipped).  Only the sampling of the pcurves is left out; a loop is
  counted when the import would keep it (two or more segments, told from the pcurves alone).
  ``faces``, ``rational_faces`` and ``faces_with_holes`` are therefore those of the model.
  (Not reproduced: a face the import skips because sampling its loops raises, e.g. a pcurve
  evaluating to NaN; no such face is known.)
* **Supplemental faces**: those outside the solid, by the import's own rule
  (:func:`~shapeverify.cad.occ_import._supplemental_flags`); the bounds leave them out, as
  :attr:`Model.bounds` does.
* **Unit**: the same reader, the same unit.
* **Bounds**: those of :attr:`Model.bounds` (the trimming loops mapped to 3D plus each
  coordinate's extremes inside each face) computed from OpenCASCADE's geometry: the exact
  extremes of every edge's curve on its face (``BndLib_Add3dCurve::AddOptimal`` of the curve on
  the surface: the boundary the model's loops sample), and, only where a face's conservative
  box (``BRepBndLib::Add``) reaches beyond its edges, the interior extreme found as the model
  finds it: a 24 x 24 grid over the face's parameter box, kept inside the face
  (``IntTools_FClass2d``), polished by Newton steps.  The model samples the boundary within the
  chordal tolerance (0.002 mm) and stops Newton after 6 steps; the edges' extremes here are
  exact, so the bounds agree to about 1e-6 of the model size, not to the bit
  (``tests/test_occ_summary.py`` asserts it on every file).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ..errors import CADImportError, ShapeVerifyError
from .summary import ModelSummary

logger = logging.getLogger(__name__)

__all__ = ["read_summary"]

_GRID = 24          # grid of the interior search per face side (as Model.bounds)
_NEWTON = 12        # Newton steps at most (Model.bounds: 6)


def read_summary(path) -> ModelSummary:
    """The :class:`ModelSummary` of a STEP or IGES file, read in this process by OpenCASCADE
    (no numba).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    ModelSummary
        As ``summarize(read_cad(path))``; the bounds agree to about 1e-6 of the size.

    Raises
    ------
    FileNotFoundError, UnsupportedFormatError, CADImportError, EmptyModelError
        As :func:`~shapeverify.cad.occ_import.read_cad`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from shapeverify.cad.examples import example_part_step
    >>> with tempfile.TemporaryDirectory() as d:
    ...     s = read_summary(example_part_step(pathlib.Path(d) / "panel.step"))
    >>> s.faces, s.rational_faces, s.faces_with_holes, s.unit, round(s.size, 3)
    (1, 0, 1, 'millimetre', 361.057)
    """
    from . import occ_import as oi

    path, fmt = oi._check_path(path)
    try:
        return _summary_here(path, fmt)
    except (ShapeVerifyError, OSError):
        raise
    except Exception as exc:  # noqa: BLE001 - OpenCASCADE raises Standard_Failure & co.
        raise CADImportError(f"{path}: OpenCASCADE could not read the file "
                             f"({type(exc).__name__}: {exc})") from exc


def _summary_here(path: Path, fmt: str) -> ModelSummary:
    from . import occ_import as oi
    from ._occ_loops import _face_wires, _usable_loop

    t0 = time.perf_counter()
    oi._init_ocp()
    shape, unit, scale, _ = oi._read_shape_named(path, fmt)
    t_read = time.perf_counter()
    faces = oi._shape_faces(path, fmt, shape)
    supp_flags = oi._supplemental_flags(shape, faces)
    kept, rational, holed, skipped, why, supp = [], 0, 0, 0, [], []
    for i, face in enumerate(faces):
        try:
            work, surface, conv = oi._face_surface(face, i, path)
            wires = _face_wires(work, face, conv, None, i, path)
            loops = sum(1 for _, pcurves, _, _ in wires if pcurves and _usable_loop(pcurves))
            if loops == 0:
                raise CADImportError(f"{path}: face {i} has no usable trimming loop")
        except Exception as exc:  # noqa: BLE001 - skipped as the import skips it
            logger.debug("%s: face %d left out as the import leaves it out: %s", path, i, exc)
            skipped += 1
            why.append(f"face {i}: " + (str(exc).replace(f"{path}: ", "")
                                        if isinstance(exc, ShapeVerifyError)
                                        else f"{type(exc).__name__}: {exc}"))
            continue
        if supp_flags[i]:
            supp.append(len(kept))
        kept.append(face)
        rational += surface.rational
        holed += loops > 1
    if not kept:
        raise CADImportError(f"{path}: none of the {len(faces)} faces could be converted "
                             f"({'; '.join(why[:3])}{' ...' if len(why) > 3 else ''})")
    n_in_file = oi._missing_faces(path, fmt, len(faces), why)  # issue 33 row 2: info says so
    if why:
        logger.warning("%s: %d of the %d faces in the file were not loaded: %s", path,
                       n_in_file - len(kept), n_in_file, "; ".join(why))
    t_faces = time.perf_counter()
    if len(supp) == len(kept):
        supp = []  # as the import: the solid's faces were all skipped
    part = set(range(len(kept))) - set(supp)
    lo, hi = _bounds([f for k, f in enumerate(kept) if k in part])
    from .number_check import check_extent

    check_extent(path, lo, hi)  # issue 33 fuzz: a finite but absurd number in the file
    size = float(np.linalg.norm(hi - lo))
    logger.info("%s: summary of %d faces (%d left out) from OpenCASCADE alone; read %.2f s, "
                "faces %.2f s, bounds %.2f s", path.name, len(kept), skipped, t_read - t0,
                t_faces - t_read, time.perf_counter() - t_faces)
    return ModelSummary(kind="cad", faces=len(kept), rational_faces=int(rational),
                        faces_with_holes=int(holed), vertices=None, unit=unit,
                        scale_to_mm=float(scale), lo=tuple(float(x) for x in lo),
                        hi=tuple(float(x) for x in hi), size=size, faces_in_file=n_in_file,
                        missing=tuple(why), supplemental=tuple(supp))


# -------------------------------------------------------------------------------------- bounds
def _corners(box) -> np.ndarray:
    box.SetGap(0.0)
    return np.array([box.CornerMin().Coord(), box.CornerMax().Coord()], dtype=np.float64)


def _bounds(faces) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (3,) of the faces: their edges' exact extremes on the faces, plus interior
    extremes where a face may reach beyond its edges."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for face in faces:
        b = _face_bounds(face)
        lo, hi = np.minimum(lo, b[0]), np.maximum(hi, b[1])
    return lo, hi


def _face_bounds(face) -> np.ndarray:
    from OCP.Bnd import Bnd_Box
    from OCP.BndLib import BndLib_Add3dCurve
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.BRepBndLib import BRepBndLib
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    box = Bnd_Box()
    exp = TopExp_Explorer(face, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge(exp.Current())
        exp.Next()
        if BRep_Tool.Degenerated_s(edge):
            continue
        BndLib_Add3dCurve.AddOptimal_s(BRepAdaptor_Curve(edge, face), 0.0, box)
    coarse = Bnd_Box()
    BRepBndLib.Add_s(face, coarse, False)
    c = _corners(coarse)
    slack = BRep_Tool.Tolerance_s(face) + 1e-9 * float(np.abs(c).max())
    if box.IsVoid():
        edges = np.array([np.full(3, np.inf), np.full(3, -np.inf)])
    else:
        edges = _corners(box)
    # sides on which the face may reach beyond its boundary: 0..2 minima, 3..5 maxima
    need = np.flatnonzero(np.concatenate([c[0] + slack < edges[0], c[1] - slack > edges[1]]))
    if need.size == 0:
        return edges
    pts = _interior_extremes(face, need)
    if pts.shape[0] == 0:
        return edges
    return np.array([np.minimum(edges[0], pts.min(axis=0)),
                     np.maximum(edges[1], pts.max(axis=0))])


def _interior_extremes(face, sides: np.ndarray) -> np.ndarray:
    """Points inside the trimmed face at which the coordinates of ``sides`` (0..2: minimum of
    x, y, z; 3..5: maximum) are extreme: the best of a grid, then Newton steps (as
    ``shapeverify.cad.model._face_extremes``)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepTools import BRepTools
    from OCP.gp import gp_Pnt, gp_Pnt2d, gp_Vec
    from OCP.IntTools import IntTools_FClass2d
    from OCP.TopAbs import TopAbs_IN, TopAbs_ON

    surf = BRepAdaptor_Surface(face)
    u0, u1 = surf.FirstUParameter(), surf.LastUParameter()
    v0, v1 = surf.FirstVParameter(), surf.LastVParameter()
    a0, a1, b0, b1 = BRepTools.UVBounds_s(face)
    a0, a1, b0, b1 = max(a0, u0), min(a1, u1), max(b0, v0), min(b1, v1)
    classifier = IntTools_FClass2d(face, BRep_Tool.Tolerance_s(face))

    def inside(u, v) -> bool:
        return classifier.Perform(gp_Pnt2d(u, v)) in (TopAbs_IN, TopAbs_ON)

    uu, vv = np.meshgrid(np.linspace(a0, a1, _GRID), np.linspace(b0, b1, _GRID))
    grid = np.column_stack([uu.ravel(), vv.ravel()])
    xyz = np.array([surf.Value(float(u), float(v)).Coord() for u, v in grid])
    known = {}  # grid index -> inside the face?

    def inside_grid(k: int) -> bool:
        if k not in known:
            known[k] = inside(float(grid[k, 0]), float(grid[k, 1]))
        return known[k]

    cell = np.array([a1 - a0, b1 - b0]) / (_GRID - 1)
    p, du, dv, duu, dvv, duv = gp_Pnt(), gp_Vec(), gp_Vec(), gp_Vec(), gp_Vec(), gp_Vec()
    out = []
    for side in sides:
        coord, sense = int(side) % 3, (1.0 if side < 3 else -1.0)  # minimise sense * coord
        # the grid point inside the face with the least sense * coord: classify the points
        # in that order until one is inside (the model classifies all of them first)
        k = next((int(k) for k in np.argsort(sense * xyz[:, coord], kind="stable")
                  if inside_grid(int(k))), None)
        if k is None:
            return np.zeros((0, 3))
        uv, best = grid[k].copy(), sense * xyz[k, coord]
        for _ in range(_NEWTON):
            surf.D2(uv[0], uv[1], p, du, dv, duu, dvv, duv)
            g = sense * np.array([du.Coord()[coord], dv.Coord()[coord]])
            h11, h22 = sense * duu.Coord()[coord], sense * dvv.Coord()[coord]
            h12 = sense * duv.Coord()[coord]
            det = h11 * h22 - h12 * h12
            if not (h11 > 0 and det > 0):
                break  # not near a minimum of sense * coordinate
            step = np.clip(np.array([h22 * g[0] - h12 * g[1], h11 * g[1] - h12 * g[0]]) / det,
                           -cell, cell)
            trial = np.array([np.clip(uv[0] - step[0], u0, u1), np.clip(uv[1] - step[1], v0, v1)])
            val = sense * surf.Value(trial[0], trial[1]).Coord()[coord]
            if not (val < best and inside(trial[0], trial[1])):
                break
            uv, best = trial, val
            if np.all(np.abs(step) <= 1e-12 * np.maximum(cell, 1e-300)):
                break
        out.append(surf.Value(uv[0], uv[1]).Coord())
    return np.array(out, dtype=np.float64)
