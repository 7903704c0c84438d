"""The reference model: trimmed NURBS faces (or a mesh, or a point cloud), in millimetres.

:class:`Face` is one trimmed face of a CAD model (thesis §7.3): a :class:`NurbsSurface`, its
trimming loops in (u, v) and its orientation.  :class:`Model` holds the faces of a part (or, for a
mesh or point-cloud reference, its vertices) with the unit the source file declared.
:class:`ModelPoints` is the sampled form of a model that the closest-point search works on.

The objects own plain numpy data only: OpenCASCADE is used at import time
(:mod:`shapeverify.cad.occ_import`) and never afterwards.

Example
-------
>>> import numpy as np
>>> from shapeverify.cad.nurbs import NurbsSurface
>>> plane = NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1],
...                      np.array([[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]], float))
>>> outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
>>> face = Face(plane, (outer,), (np.ones(4, bool),), reversed=False)
>>> face.contains([[0.5, 0.5], [1.5, 0.5]]).tolist()
[True, False]
>>> face.normal([[0.5, 0.5]]).round(12).tolist()
[[0.0, 0.0, 1.0]]
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .._arrays import readonly as _readonly
from .nurbs import NurbsSurface
from .trim import TrimDomain, check_loops

__all__ = ["Face", "Model", "ModelKind", "ModelPoints"]


class ModelKind(enum.StrEnum):
    """What a :class:`Model` holds.  A ``str`` enum: ``ModelKind.CAD == "cad"``, and it prints and
    serialises as its plain value."""

    CAD = "cad"        # trimmed NURBS faces
    MESH = "mesh"      # a triangle mesh
    POINTS = "points"  # a point cloud


_KINDS = tuple(k.value for k in ModelKind)


def _uv_array(uv) -> np.ndarray:
    p = np.asarray(uv, dtype=np.float64)
    if p.ndim == 1 and p.shape[0] == 2:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"uv must have shape (N, 2), got {p.shape}")
    return p


@dataclass(frozen=True, eq=False, repr=False)
class Face:
    """One trimmed NURBS face.

    Parameters
    ----------
    surface : NurbsSurface
    loops : tuple of (k, 2) float64
        ``loops[0]`` is the outer boundary, ``loops[1:]`` the holes; closed polylines in (u, v)
        with the closing segment implied (last vertex != first).
    loop_free : tuple of (k,) bool
        ``loop_free[i][j]`` is True when segment j -> j+1 of loop i lies on a free edge of the model
        (the part's outer boundary), False on an edge shared with another face.
    reversed : bool
        True when the outward normal is -(Su x Sv).

    Raises
    ------
    ValueError
        On a surface that is not a NurbsSurface, malformed loops, or ``loop_free`` arrays whose
        lengths differ from the loops'.
    """

    surface: NurbsSurface
    loops: tuple
    loop_free: tuple
    reversed: bool = False

    def __post_init__(self):
        if not isinstance(self.surface, NurbsSurface):
            raise ValueError(f"surface must be a NurbsSurface, got {type(self.surface).__name__}")
        loops = check_loops(self.loops)
        free = tuple(np.asarray(f) for f in self.loop_free)
        if len(free) != len(loops):
            raise ValueError(f"loop_free has {len(free)} entries for {len(loops)} loops")
        for i, (lp, f) in enumerate(zip(loops, free)):
            if f.shape != (lp.shape[0],):
                raise ValueError(f"loop_free[{i}] must have shape ({lp.shape[0]},) (one flag per "
                                 f"segment of loop {i}), got {f.shape}")
        object.__setattr__(self, "loops", loops)
        object.__setattr__(self, "loop_free", tuple(_readonly(f.astype(bool)) for f in free))
        object.__setattr__(self, "reversed", bool(self.reversed))

    @cached_property
    def trim(self) -> TrimDomain:
        """The trimmed parameter domain (built on first use)."""
        return TrimDomain(self.loops)

    @property
    def uv_bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((u0, u1), (v0, v1)): bounding box of the trimming loops."""
        return self.trim.bounds

    def contains(self, uv) -> np.ndarray:
        """(N,) bool: which parameter points (N, 2) lie on the trimmed face (even-odd rule)."""
        return self.trim.contains(uv)

    def evaluate(self, uv) -> np.ndarray:
        """(N, 3) surface points at parameters uv (N, 2) (the trims are not applied)."""
        p = self._on_domain(_uv_array(uv))
        return self.surface.evaluate(p[:, 0], p[:, 1])

    def normal(self, uv) -> np.ndarray:
        """(N, 3) outward unit normals at parameters uv (N, 2): Su x Sv, flipped if reversed."""
        p = self._on_domain(_uv_array(uv))
        n = self.surface.normal(p[:, 0], p[:, 1])
        return -n if self.reversed else n

    def _on_domain(self, p: np.ndarray) -> np.ndarray:
        """p with the values past the surface's domain but within the face's own trims' box
        put on the domain's edge: a STEP file's pcurves can run past their surface (NIST FTC 07:
        1e-5 .. 2e-3 of the width on many faces, 0.35 rad on a sphere patch by its pole after
        ``BRepBuilderAPI_NurbsConvert``), and its loops were evaluated clipped at the import.
        Values beyond the trims' box are left, for the surface to refuse."""
        (u0, u1), (v0, v1) = self.surface.domain
        if not p.size or (p[:, 0].min() >= u0 and p[:, 0].max() <= u1
                          and p[:, 1].min() >= v0 and p[:, 1].max() <= v1):
            return p
        (a0, a1), (b0, b1) = self.uv_bounds
        q = p.copy()
        for k, lo, hi, ta, tb in ((0, u0, u1, a0, a1), (1, v0, v1, b0, b1)):
            x = q[:, k]
            tol = 1e-9 * max(hi - lo, tb - ta)
            inside = (x >= min(lo, ta) - tol) & (x <= max(hi, tb) + tol)
            q[inside, k] = np.clip(x[inside], lo, hi)
        return q

    def __repr__(self) -> str:
        s = self.surface
        n_seg = sum(lp.shape[0] for lp in self.loops)
        n_free = sum(int(f.sum()) for f in self.loop_free)
        return (f"Face(degree=({s.degree_u}, {s.degree_v}), control={s.control.shape[:2]}, "
                f"rational={s.rational}, loops={len(self.loops)}, segments={n_seg}, "
                f"free_segments={n_free}, reversed={self.reversed})")


def _opt_array(a, dtype, name: str, ncols: int = 3):
    if a is None:
        return None
    arr = np.asarray(a, dtype=dtype)
    if arr.ndim != 2 or arr.shape[1] != ncols:
        raise ValueError(f"{name} must have shape (n, {ncols}), got {arr.shape}")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains non-finite values")
    return _readonly(arr)


def _face_extremes(face: Face, n_grid: int = 24, newton_steps: int = 6) -> np.ndarray:
    """3D points of a face at which each coordinate is (nearly) extreme, plus its boundary."""
    surf = face.surface
    (u0, u1), (v0, v1) = surf.domain
    loops = np.concatenate(face.loops)
    loops = np.column_stack([np.clip(loops[:, 0], u0, u1), np.clip(loops[:, 1], v0, v1)])
    (a0, a1), (b0, b1) = face.uv_bounds
    a0, a1, b0, b1 = max(a0, u0), min(a1, u1), max(b0, v0), min(b1, v1)
    g = np.stack(np.meshgrid(np.linspace(a0, a1, n_grid), np.linspace(b0, b1, n_grid)),
                 axis=-1).reshape(-1, 2)
    g = g[face.contains(g)]
    out = [surf.evaluate(loops[:, 0], loops[:, 1])]
    if g.shape[0] == 0:
        return out[0]
    xyz = surf.evaluate(g[:, 0], g[:, 1])
    # start points: the grid's extreme point for each coordinate and sense
    start = np.concatenate([np.argmin(xyz, axis=0), np.argmax(xyz, axis=0)])
    uv = g[start].copy()
    coord = np.tile(np.arange(3), 2)
    sense = np.repeat([1.0, -1.0], 3)  # minimise sense * coordinate
    best = sense * xyz[start, coord]
    cell = np.array([(a1 - a0), (b1 - b0)]) / (n_grid - 1)
    rows = np.arange(6)
    for _ in range(newton_steps):
        d = surf.derivatives(uv[:, 0], uv[:, 1], order=2)
        grad = sense[:, None] * np.stack([d[rows, 1, 0, coord], d[rows, 0, 1, coord]], axis=1)
        h11 = sense * d[rows, 2, 0, coord]
        h22 = sense * d[rows, 0, 2, coord]
        h12 = sense * d[rows, 1, 1, coord]
        det = h11 * h22 - h12 * h12
        ok = (h11 > 0) & (det > 0)  # a minimum of sense * coordinate
        step = np.zeros_like(uv)
        with np.errstate(divide="ignore", invalid="ignore"):
            step[:, 0] = np.where(ok, (h22 * grad[:, 0] - h12 * grad[:, 1]) / det, 0.0)
            step[:, 1] = np.where(ok, (h11 * grad[:, 1] - h12 * grad[:, 0]) / det, 0.0)
        step = np.clip(step, -cell, cell)
        trial = uv - step
        trial[:, 0] = np.clip(trial[:, 0], u0, u1)
        trial[:, 1] = np.clip(trial[:, 1], v0, v1)
        val = sense * surf.evaluate(trial[:, 0], trial[:, 1])[rows, coord]
        accept = (val < best) & face.contains(trial)
        uv[accept] = trial[accept]
        best[accept] = val[accept]
    out.append(surf.evaluate(uv[:, 0], uv[:, 1]))
    return np.concatenate(out)


@dataclass(frozen=True, eq=False, repr=False)
class Model:
    """A reference model in millimetres.

    Parameters
    ----------
    faces : tuple of Face
        One entry per CAD face (empty for a mesh or a point cloud).
    unit : str
        The length unit the source file declared (e.g. ``"mm"``, ``"inch"``, ``"metre"``).
    scale_to_mm : float
        Millimetres per source-file unit; the geometry held here is already converted.
    source : str
        Where the model came from (a file path, or a description).
    kind : ModelKind or {"cad", "mesh", "points"}
        Stored as a :class:`ModelKind` (which compares equal to the strings).
    vertices : (V, 3) float64 or None
        Mesh vertices, or the points of a point-cloud model.
    triangles : (T, 3) int32 or None
        Mesh triangles (indices into ``vertices``).
    cloud_normals : (V, 3) float64 or None
        Normals of a point-cloud model, when the file had them.
    n_faces_in_file : int or None
        How many faces the source CAD file declares (None: not known, e.g. a model built in
        code, a mesh, or a ``.svmodel`` written before this field existed).  More than
        ``len(faces)`` when faces could not be read (see ``skipped_faces`` and
        :attr:`n_missing_faces`).
    skipped_faces : tuple of str
        One line per face of the file that is not in ``faces``, saying which and why
        (e.g. ``"face 3: no usable trimming loop"`` or ``"#17: referenced by CLOSED_SHELL #16
        but not in the file"``); empty when every face was read.
    open_seams : tuple of str
        Where a model whose file declares only closed shells (solids) has boundary segments
        that meet no other face (an open seam: a missing or unsewn neighbour), one line per
        face (e.g. ``"face 3: 12 boundary segments meet no other face"``); empty otherwise.
        Such a model is incomplete like one with missing faces
        (:mod:`shapeverify.cad.completeness`).
    face_names : tuple of (str or None), or None
        The name of each face in ``faces`` as the CAD file gives it (STEP face entity names,
        e.g. ``"datum_A"``), None for an unnamed face; None when no face has a name (the
        usual case).  Inspection plans may name faces by these names.
    supplemental : tuple of int
        Indices (into ``faces``) of supplemental geometry: faces of a file that holds a solid
        (or solids) which belong to no solid -- open shells and free faces a designer adds for
        construction or annotation (NIST FTC 10: 18 faces 1.25-1.69 mm off the solid; CTC 04:
        an open shell 'Fill.1').  They keep their numbers (PMI ties datum targets and thread
        curves to them) but are not the part: a scan never sees them, so they are left out of
        the model points, the closest-point structure, registration, deviations and coverage
        (:meth:`part_faces`).  Empty for a file without a solid (a surface model: every face
        is the part).

    Raises
    ------
    ValueError
        On an unknown kind, wrongly shaped arrays, or data missing for the kind.
    """

    faces: tuple = ()
    unit: str = "mm"
    scale_to_mm: float = 1.0
    source: str = ""
    kind: ModelKind = ModelKind.CAD
    vertices: np.ndarray | None = None
    triangles: np.ndarray | None = None
    cloud_normals: np.ndarray | None = None
    n_faces_in_file: int | None = None
    skipped_faces: tuple = ()
    face_names: tuple | None = None
    open_seams: tuple = ()
    supplemental: tuple = ()

    def __post_init__(self):
        if self.kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {self.kind!r}")
        object.__setattr__(self, "kind", ModelKind(self.kind))
        faces = tuple(self.faces)
        for i, f in enumerate(faces):
            if not isinstance(f, Face):
                raise ValueError(f"faces[{i}] must be a Face, got {type(f).__name__}")
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "unit", str(self.unit))
        object.__setattr__(self, "scale_to_mm", float(self.scale_to_mm))
        object.__setattr__(self, "source", str(self.source))
        if self.n_faces_in_file is not None:
            n = int(self.n_faces_in_file)
            if n < len(faces):
                raise ValueError(f"n_faces_in_file ({n}) is less than the {len(faces)} faces held")
            object.__setattr__(self, "n_faces_in_file", n)
        object.__setattr__(self, "skipped_faces", tuple(str(s) for s in self.skipped_faces))
        object.__setattr__(self, "open_seams", tuple(str(s) for s in self.open_seams))
        if self.face_names is not None:
            names = tuple(None if n is None else str(n) for n in self.face_names)
            if len(names) != len(faces):
                raise ValueError(f"face_names has {len(names)} entries for {len(faces)} faces "
                                 "(one name or None per face)")
            object.__setattr__(self, "face_names",
                               names if any(n is not None for n in names) else None)
        supp = tuple(sorted({int(i) for i in self.supplemental}))
        if supp and not (0 <= supp[0] and supp[-1] < len(faces)):
            raise ValueError(f"supplemental face indices must be in [0, {len(faces)}), got "
                             f"{list(supp)}")
        if supp and len(supp) == len(faces):
            raise ValueError("every face is supplemental: a model needs at least one face of "
                             "the part")
        object.__setattr__(self, "supplemental", supp)
        object.__setattr__(self, "vertices", _opt_array(self.vertices, np.float64, "vertices"))
        object.__setattr__(self, "triangles", _opt_array(self.triangles, np.int32, "triangles"))
        object.__setattr__(self, "cloud_normals",
                           _opt_array(self.cloud_normals, np.float64, "cloud_normals"))
        if self.kind == "cad" and (self.vertices is not None or self.triangles is not None):
            raise ValueError("a 'cad' model holds faces, not vertices/triangles")
        if self.kind in ("mesh", "points") and self.vertices is None:
            raise ValueError(f"a {self.kind.value!r} model needs vertices")
        if self.kind == "mesh" and self.triangles is None:
            raise ValueError("a 'mesh' model needs triangles")
        if self.triangles is not None and self.triangles.size and (
                self.triangles.min() < 0 or self.triangles.max() >= self.vertices.shape[0]):
            raise ValueError(f"triangles index outside [0, {self.vertices.shape[0]})")
        if self.cloud_normals is not None and self.cloud_normals.shape != self.vertices.shape:
            raise ValueError(f"cloud_normals must have the shape of vertices "
                             f"{self.vertices.shape}, got {self.cloud_normals.shape}")

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounding box [min, max] in mm.

        For CAD faces: the trimming loops mapped to 3D, plus each coordinate's extremes inside
        each face, found on a 24 x 24 grid and polished with a few Newton steps; the faces of
        the part only (:meth:`part_faces`: supplemental geometry left out).
        """
        if self.kind != "cad":
            pts = self.vertices
        else:
            pts = np.concatenate([_face_extremes(self.faces[i]) for i in self.part_faces()]) \
                if self.faces else np.zeros((0, 3))
        if pts.shape[0] == 0:
            raise ValueError("an empty model has no bounds")
        b = np.stack([pts.min(axis=0), pts.max(axis=0)])
        b.setflags(write=False)
        return b

    def part_faces(self) -> tuple:
        """Indices of the faces that are the part (all but :attr:`supplemental`), ascending."""
        if not self.supplemental:
            return tuple(range(len(self.faces)))
        skip = set(self.supplemental)
        return tuple(i for i in range(len(self.faces)) if i not in skip)

    @property
    def n_missing_faces(self) -> int:
        """Faces the source file declares that are not in the model (0 when not known)."""
        return 0 if self.n_faces_in_file is None else self.n_faces_in_file - len(self.faces)

    @property
    def size(self) -> float:
        """Bounding-box diagonal in mm."""
        return float(np.linalg.norm(self.bounds[1] - self.bounds[0]))

    def sample(self, spacing: float, rng=None, *, half_extents: bool = True) -> ModelPoints:
        """Model points about ``spacing`` mm apart (see :func:`shapeverify.cad.sampling.sample_model`)."""
        from .sampling import sample_model
        return sample_model(self, spacing, rng, half_extents=half_extents)

    def save(self, path) -> None:
        """Write the model to one file (see :func:`shapeverify.cad.persist.save_model`)."""
        from .persist import save_model
        return save_model(self, path)

    def __repr__(self) -> str:
        what = (f"faces={len(self.faces)}" if self.kind == "cad" else
                f"vertices={self.vertices.shape[0]}"
                + (f", triangles={self.triangles.shape[0]}" if self.triangles is not None else ""))
        if self.n_missing_faces:
            what += f" (of {self.n_faces_in_file} in the file)"
        if self.supplemental:
            what += f", supplemental={len(self.supplemental)}"
        return (f"Model(kind={self.kind.value!r}, {what}, unit={self.unit!r}, "
                f"scale_to_mm={self.scale_to_mm:g}, source={self.source!r})")


@dataclass(frozen=True, eq=False, repr=False)
class ModelPoints:
    """Points sampled on a model, with the local frame the closest-point search needs.

    Parameters
    ----------
    points : (N, 3) float64
    normals : (N, 3) float64, outward unit normals
    face : (N,) int32, face index (triangle index for a mesh, -1 for a point cloud)
    uv : (N, 2) float64, surface parameters (0 for meshes and point clouds)
    tangent_u, tangent_v : (N, 3) float64, unit tangents; with the normal an orthonormal frame
    half_extent : (N, 2) float64, extent of each point's patch along tangent_u / tangent_v
    boundary : (N,) bool, within one spacing of a free edge
    spacing : float, the sampling spacing in mm

    Raises
    ------
    ValueError
        If the arrays do not all describe the same N points with the shapes above.
    """

    points: np.ndarray
    normals: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    tangent_u: np.ndarray
    tangent_v: np.ndarray
    half_extent: np.ndarray
    boundary: np.ndarray
    spacing: float = field(default=0.0)

    def __post_init__(self):
        pts = np.asarray(self.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
        n = pts.shape[0]
        spec = {"points": (np.float64, (n, 3)), "normals": (np.float64, (n, 3)),
                "face": (np.int32, (n,)), "uv": (np.float64, (n, 2)),
                "tangent_u": (np.float64, (n, 3)), "tangent_v": (np.float64, (n, 3)),
                "half_extent": (np.float64, (n, 2)), "boundary": (np.bool_, (n,))}
        for name, (dtype, shape) in spec.items():
            a = np.asarray(getattr(self, name))
            if a.shape != shape:
                raise ValueError(f"{name} must have shape {shape} (N = {n} points), got {a.shape}")
            object.__setattr__(self, name, _readonly(a.astype(dtype, copy=False)))
        object.__setattr__(self, "spacing", float(self.spacing))

    def __len__(self) -> int:
        return self.points.shape[0]

    def __repr__(self) -> str:
        return (f"ModelPoints(n={len(self)}, spacing={self.spacing:g}, "
                f"faces={np.unique(self.face).size}, boundary={int(self.boundary.sum())})")
