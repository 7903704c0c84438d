"""CAD features from the topology of a model: holes, openings, planar and cylindrical faces.

* **faces** ``face:i`` (i = index in ``model.faces``): each classified ``plane``, ``cylinder``
  or ``freeform`` by fitting a plane / a cylinder (:mod:`shapeverify.fitting`) to a grid of
  points on the trimmed face (planar when every point is within ``1e-6 * size`` of the plane,
  cylindrical within ``1e-5 * radius``).
* **holes** ``hole:k``: every inner trim loop (``loops[1:]``) of a face whose 3-D points lie on a
  circle or, for a hole cut through a curved sheet, on a right circular cylinder.  The axis is
  the circle's normal (or the cylinder's axis), the diameter that of the circle/cylinder, and the
  centre the point where the axis pierces the face's (untrimmed) surface.  Numbered in the order
  (face index, loop index), so the ids are stable for a given model.  Then the holes that no
  such loop gives (a side-wall hole breaking through an edge, a hole meeting another hole):
  **concave cylindrical faces** (outward normal towards the axis: material outside, a hole and
  not a boss), the faces of one axis line and diameter taken together (a bore made of two
  half-cylinder faces is one hole), kept when together they cover more than 200 degrees about
  the axis (less is a fillet or a slot's end: listed in :func:`feature_notes`); centre the axis
  point at the end of the wall farther from the model's centre, axis pointing out there.  A
  loop hole lists its cylindrical wall faces in ``walls``.
* **openings** ``slot:k`` / ``pocket:k`` / ``other:k``: an inner loop that is not one circle
  (a slot: planar, convex, at least 1.5 times as long as wide; a pocket: another planar
  outline; other: not planar), with its outline (the loop's 3-D points), length and width.  A
  loop whose outline cannot be read is left out with the reason in :func:`feature_notes`; no
  loop raises.

Face names come from ``model.face_names`` when the model carries them (a tuple of str or None
per face); otherwise ``name`` is None.

Example
-------
>>> from shapeverify.cad.examples import wavy_panel
>>> [f.id for f in model_features(wavy_panel())]
['face:0', 'face:1']
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..fitting import fit_circle, fit_cylinder, fit_plane

__all__ = ["Feature", "model_features", "find_feature", "faces_named", "features_table",
           "feature_notes", "hole_center_on_face"]

logger = logging.getLogger(__name__)

_GRID = 16


@dataclass(frozen=True, eq=False)
class Feature:
    """One CAD feature (model frame, mm).

    Attributes
    ----------
    id : str            ``'hole:3'``, ``'face:12'``
    kind : str          ``'hole'``, ``'plane'``, ``'cylinder'``, ``'freeform'``, or for an
                        inner loop that is not a circle ``'slot'``, ``'pocket'``, ``'other'``
    face : int          face index (for a hole: the face whose inner loop it is)
    center : (3,)       hole: centre (axis through the face); plane: centroid of the grid
                        points; cylinder: axis point closest to them; freeform: centroid
    axis : (3,) or None hole/cylinder: unit axis (for a hole oriented like the face's outward
                        normal); plane: unit outward normal
    diameter : float or None   hole/cylinder diameter (mm)
    loop : int or None  index of the hole's loop in ``model.faces[face].loops``
    name : str or None  face name from the CAD file, when known
    form_error : float  largest distance of the face/loop points from the fitted element (mm)
    walls : tuple of int   hole: its concave cylindrical wall faces (when the model has them)
    outline : (k, 3) or None   slot/pocket/other: the loop's points
    length, width : float or None   slot/pocket/other: extents along / across its long axis
    """

    id: str
    kind: str
    face: int
    center: np.ndarray = field(repr=False)
    axis: np.ndarray | None = field(default=None, repr=False)
    diameter: float | None = None
    loop: int | None = None
    name: str | None = None
    form_error: float = 0.0
    walls: tuple = ()
    outline: np.ndarray | None = field(default=None, repr=False)
    length: float | None = None
    width: float | None = None

    def to_dict(self) -> dict:
        """JSON-ready dict: id, kind, face, name, center, axis, diameter, loop, form_error,
        walls (a hole's cylindrical wall faces), and for a slot/pocket/other opening its
        length, width and outline (the loop's 3-D points)."""
        return {"id": self.id, "kind": self.kind, "face": self.face, "name": self.name,
                "center": [float(x) for x in self.center],
                "axis": None if self.axis is None else [float(x) for x in self.axis],
                "diameter": None if self.diameter is None else float(self.diameter),
                "loop": self.loop, "form_error": float(self.form_error),
                "walls": [int(w) for w in self.walls],
                "length": None if self.length is None else float(self.length),
                "width": None if self.width is None else float(self.width),
                "outline": None if self.outline is None else np.round(
                    np.asarray(self.outline, float), 6).tolist()}


def _face_grid(face, n: int = _GRID) -> tuple[np.ndarray, np.ndarray]:
    (a0, a1), (b0, b1) = face.uv_bounds
    g = np.stack(np.meshgrid(np.linspace(a0, a1, n), np.linspace(b0, b1, n)), -1).reshape(-1, 2)
    g = _in_domain(face, g[face.contains(g)])
    if g.shape[0] < 8:  # a thin face: sample its loops' vertices as well
        g = np.concatenate([g, _in_domain(face, np.concatenate(face.loops))])
    return face.evaluate(g), face.normal(g)


def _in_domain(face, uv: np.ndarray) -> np.ndarray:
    """Trim-loop parameters ``uv`` (N, 2) clipped onto the face's surface domain: a STEP file's
    pcurves may run a little past it (NIST FTC 10: v 8e-6 beyond +-23 on a cylinder's face;
    hammer.iges: 6.2e-5 below u = 0), farther than the surface's evaluation accepts."""
    (u0, u1), (v0, v1) = face.surface.domain
    uv = np.asarray(uv, np.float64)
    return np.column_stack([np.clip(uv[:, 0], u0, u1), np.clip(uv[:, 1], v0, v1)])


def _dense_loop(loop: np.ndarray, per_segment: int = 2) -> np.ndarray:
    nxt = np.roll(loop, -1, axis=0)
    t = np.arange(per_segment)[:, None, None] / per_segment
    return (loop[None] * (1 - t) + nxt[None] * t).transpose(1, 0, 2).reshape(-1, 2)


def hole_center_on_face(face, point, axis, uv0=None, iterations: int = 30) -> np.ndarray:
    """Where the line ``point + s * axis`` pierces the (untrimmed) surface of ``face``.

    Newton iterations on ``(S(u, v) - point) x axis = 0`` (least squares in u, v); falls back
    to ``point`` when they do not converge (a line tangent to the surface).
    """
    p = np.asarray(point, np.float64)
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    surf = face.surface
    (u0, u1), (v0, v1) = surf.domain
    if uv0 is None:
        # the trims' (u, v) box can reach a little beyond the surface's domain (hammer.iges:
        # -6.2e-5 below u = 0); the search grid stays inside the domain
        (a0, a1), (b0, b1) = face.uv_bounds
        a0, a1 = max(a0, u0), min(a1, u1)
        b0, b1 = max(b0, v0), min(b1, v1)
        g = np.stack(np.meshgrid(np.linspace(a0, a1, 24), np.linspace(b0, b1, 24)), -1)
        g = g.reshape(-1, 2)
        x = surf.evaluate(g[:, 0], g[:, 1]) - p
        off = np.linalg.norm(x - np.outer(x @ a, a), axis=1)
        uv = g[int(np.argmin(off))].copy()
    else:
        uv = np.asarray(uv0, np.float64).copy()
    for _ in range(iterations):
        d = surf.derivatives(uv[:1], uv[1:], order=1)[0]
        r = d[0, 0] - p
        r = r - (r @ a) * a
        J = np.column_stack([d[1, 0] - (d[1, 0] @ a) * a, d[0, 1] - (d[0, 1] @ a) * a])
        step, *_ = np.linalg.lstsq(J, -r, rcond=None)
        uv = np.array([np.clip(uv[0] + step[0], u0, u1), np.clip(uv[1] + step[1], v0, v1)])
        if np.linalg.norm(step) < 1e-14 * (1 + np.abs(uv).max()):
            break
    q = surf.evaluate(uv[:1], uv[1:])[0]
    off = (q - p) - ((q - p) @ a) * a
    if np.linalg.norm(off) > 1e-6 * (1 + np.linalg.norm(q)):
        return p
    return p + ((q - p) @ a) * a


def _hole(face, loop: np.ndarray, size: float):
    # the loop's vertices lie on the trimming curve (an imported loop is sampled to chord_tol);
    # points between them, in (u, v), lie inside the circle by the sagitta (0.001 mm for a
    # 5 mm hole read from STEP: more than the circle test allows), so only a loop too short
    # to fit is densified
    uv = _in_domain(face, loop if loop.shape[0] >= 12 else _dense_loop(loop))
    X = face.evaluate(uv)
    if X.shape[0] < 6:
        return None
    try:
        circ = fit_circle(X)
    except ValueError:  # points on a line: not a circle
        return None
    err = float(np.max(np.abs(circ.residuals)))
    tol = 1e-4 * circ.radius + 1e-7 * size
    axis, radius, centre = circ.normal, circ.radius, circ.center
    nrm = face.normal(uv).mean(axis=0)
    if not err <= tol:
        # a hole in a sloped or curved face has a rim that is not a plane circle: fit the
        # cylinder from several starts (the rim's best plane normal, the face's normal around
        # the hole, the points' principal directions) -- from the plane normal alone the fit
        # can stop in a tilted local minimum (0.009 mm off for a drilled 24 mm hole)
        best = None
        for hint in (circ.normal, nrm / max(np.linalg.norm(nrm), 1e-300), None):
            try:
                cyl = fit_cylinder(X, axis=hint)
            except ValueError:
                continue
            cerr = float(np.max(np.abs(cyl.residuals)))
            if best is None or cerr < best[1]:
                best = (cyl, cerr)
        if best is None:
            return None
        cyl, cerr = best
        if not cerr <= tol or cyl.radius > size:
            return None
        axis, radius, err = cyl.axis, cyl.radius, cerr
        centre = cyl.point + ((X - cyl.point) @ axis).mean() * axis
    # orient the axis like the face's outward normal around the hole
    if axis @ nrm < 0:
        axis = -axis
    centre = hole_center_on_face(face, centre, axis)
    return centre, axis, 2.0 * float(radius), err


def _opening(face, loop: np.ndarray, size: float):
    """An inner loop that is not one circle: ``(kind, centre, axis, length, width, outline,
    form_error)`` with kind ``'slot'`` (a planar, convex outline at least 1.5 times as long as
    wide), ``'pocket'`` (another planar outline) or ``'other'`` (a loop that is not planar)."""
    loop = _in_domain(face, loop)
    X = face.evaluate(loop)
    if X.shape[0] < 3:
        raise ValueError(f"the loop has {X.shape[0]} vertices")
    nrm = face.normal(loop).mean(axis=0)
    nrm = nrm / max(np.linalg.norm(nrm), 1e-300)
    try:
        pl = fit_plane(X)
        perr = float(np.max(np.abs(pl.residuals)))
    except ValueError:
        pl, perr = None, np.inf
    if pl is None or not perr <= 1e-6 * size + 1e-9:
        c = X.mean(axis=0)
        span = float(np.ptp(X @ np.linalg.svd(X - c, full_matrices=False)[2][0]))
        return "other", c, nrm, span, None, X, 0.0 if pl is None else perr
    axis = pl.normal if pl.normal @ nrm >= 0 else -pl.normal
    from .holes import plane_basis

    e1, e2 = plane_basis(axis)
    q = X - pl.point
    xy = np.column_stack([q @ e1, q @ e2])
    c2 = xy.mean(axis=0)
    _, _, vt = np.linalg.svd(xy - c2, full_matrices=False)
    uv = (xy - c2) @ vt.T
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    length, width = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    mid = c2 + 0.5 * (lo + hi) @ vt
    centre = pl.point + mid[0] * e1 + mid[1] * e2
    x, y = xy[:, 0], xy[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    try:
        from scipy.spatial import ConvexHull

        hull = float(ConvexHull(xy).volume)
    except Exception:  # noqa: BLE001 - qhull's errors on degenerate input: not convex-checked
        hull = np.inf
    kind = "slot" if (length >= 1.5 * width and area >= 0.99 * hull) else "pocket"
    return kind, centre, axis, length, width, X, perr


def _concave_cylinder(face, point, axis) -> bool:
    """True for a cylindrical face whose outward normal points to its axis (material outside
    the surface: a hole's wall, not a boss)."""
    X, N = _face_grid(face)
    rel = X - point
    rad = rel - np.outer(rel @ axis, axis)
    rn = np.linalg.norm(rad, axis=1)
    ok = rn > 0
    if not np.any(ok):
        return False
    return bool(np.median(np.einsum("ij,ij->i", N[ok], rad[ok] / rn[ok, None])) < -0.9)


def _coverage(angles: np.ndarray) -> float:
    """The angle (rad) a set of directions about an axis covers: 2 pi minus the widest gap."""
    a = np.sort(np.asarray(angles))
    if a.size < 2:
        return 0.0
    gaps = np.diff(np.r_[a, a[0] + 2 * np.pi])
    return float(2 * np.pi - gaps.max())


def _same_axis(p1, a1, p2, a2, tol: float) -> bool:
    """Two axis lines coincide: parallel to 1e-6 rad and ``p2`` within ``tol`` of line 1."""
    if np.linalg.norm(np.cross(a1, a2)) > 1e-6:
        return False
    d = np.asarray(p2) - np.asarray(p1)
    return bool(np.linalg.norm(d - (d @ a1) * a1) <= tol)


def _cylinder_holes(model, cyls: list, loop_holes: list, size: float):
    """Holes bounded by concave cylindrical faces (several faces of one axis and diameter -- two
    half-cylinders -- are one hole) that no circular inner loop already gives; also the wall
    faces of every loop hole.  ``cyls``: (face index, axis point, unit axis, radius); ``loop_holes``:
    [centre, axis, diameter, ...] lists, whose walls are appended in place.  Returns
    ``[(face, centre, axis, diameter, walls)]`` and the notes on faces left out."""
    groups: list[list] = []
    for item in cyls:
        i, p1, a1, r1 = item
        tol = 1e-5 * r1 + 1e-7 * size
        for g in groups:
            _, p2, a2, r2 = g[0]
            if abs(r2 - r1) <= tol and _same_axis(p2, a2, p1, a1, tol):
                g.append(item)
                break
        else:
            groups.append([item])
    out, notes = [], []
    centre_of_model = model.bounds.mean(axis=0)
    for g in groups:
        i0, p, a, r = g[0]
        faces = tuple(sorted(it[0] for it in g))
        tol = 1e-5 * r + 1e-7 * size
        # every face's angles and axial range in the first face's frame
        e1 = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(a, e1)
        angs, ts = [], []
        for i, _, _, _ in g:
            X = np.concatenate([_face_grid(model.faces[i])[0]] + [
                model.faces[i].evaluate(_in_domain(model.faces[i], _dense_loop(lp, 4)))
                for lp in model.faces[i].loops]) - p
            angs.append(np.arctan2(X @ e2, X @ e1))
            ts.append(X @ a)
        ang, t = np.concatenate(angs), np.concatenate(ts)
        dia = 2.0 * float(r)
        # a loop's points come from its (u, v) polyline and pcurves, which a STEP file may give
        # only approximately (1e-4 relative on NIST FTC 06): match within the loop test's
        # tolerance, then take the wall's exact axis and diameter
        ltol = 1e-4 * r + 1e-7 * size
        owner = [h for h in loop_holes if abs(h[2] - dia) <= 2 * ltol
                 and np.linalg.norm(np.cross(a, h[1])) <= 1e-3 and _same_axis(p, a, h[0], a, ltol)]
        for h in owner:
            h[4] = tuple(sorted(set(h[4]) | set(faces)))
            ax = a if a @ h[1] >= 0 else -a
            c = p + ((h[0] - p) @ a) * a
            face = model.faces[h[3][0]]
            h[0], h[1], h[2] = hole_center_on_face(face, c, ax), ax, dia
        if owner:
            continue
        cov = _coverage(ang)
        if cov < np.deg2rad(200.0):
            notes.append(f"face{'s' if len(faces) > 1 else ''} "
                         f"{', '.join(f'face:{i}' for i in faces)}: a concave cylinder of "
                         f"diameter {dia:.4g} mm covering {np.rad2deg(cov):.0f} degrees about its "
                         "axis (a fillet or a slot's end, not a hole: a hole covers more than 200)")
            continue
        t0, t1 = float(t.min()), float(t.max())
        ends = [p + t0 * a, p + t1 * a]
        far = int(np.argmax([np.linalg.norm(e - centre_of_model) for e in ends]))
        centre = ends[far]
        axis = a if far == 1 else -a
        out.append((i0, centre, axis, dia, faces))
    return out, notes


def _classify(face, size: float):
    X, N = _face_grid(face)
    pl = fit_plane(X)
    perr = float(np.max(np.abs(pl.residuals)))
    if perr <= 1e-6 * size + 1e-9:
        n = pl.normal if pl.normal @ N.mean(axis=0) >= 0 else -pl.normal
        return "plane", pl.point, n, None, perr
    try:
        cyl = fit_cylinder(X)
        cerr = float(np.max(np.abs(cyl.residuals)))
        if cerr <= 1e-5 * cyl.radius + 1e-9 and cyl.radius < 10 * size:
            return "cylinder", cyl.point, cyl.axis, 2.0 * cyl.radius, cerr
    except ValueError:
        pass
    return "freeform", X.mean(axis=0), None, None, perr


def model_features(model) -> list:
    """All features of a CAD model: one per face (``face:i``), then the holes (``hole:k``).

    Parameters
    ----------
    model : Model or Prepared
        A CAD model (``kind == 'cad'``); a Prepared model's ``.model`` is used.

    Returns
    -------
    list of Feature
        Faces in index order, then holes in (face, loop) order.  Cached on the model object.

    Raises
    ------
    ValueError
        For a mesh or point-cloud model (no CAD topology).
    """
    model = getattr(model, "model", model)
    if getattr(model, "kind", None) != "cad":
        raise ValueError(f"features need a CAD model with faces (got a {getattr(model, 'kind', '?')!r} "
                         "model); load the STEP/IGES file, not a mesh")
    cached = getattr(model, "_sv_features", None)
    if cached is not None:
        return list(cached)
    size = model.size
    names = getattr(model, "face_names", None)
    out, holes, openings, cyls, notes = [], [], [], [], []
    for i, f in enumerate(model.faces):
        name = None if names is None else names[i]
        kind, c, ax, dia, err = _classify(f, size)
        out.append(Feature(f"face:{i}", kind, i, np.asarray(c), None if ax is None else
                           np.asarray(ax), dia, None, name, err))
        if kind == "cylinder":
            p, a = np.asarray(c, float), np.asarray(ax, float) / np.linalg.norm(ax)
            if _concave_cylinder(f, p, a):
                cyls.append((i, p, a, 0.5 * float(dia)))
        for j, lp in enumerate(f.loops[1:], start=1):
            try:
                h = _hole(f, lp, size)
            except ValueError as exc:
                notes.append(f"face:{i} loop {j}: left out ({exc})")
                continue
            if h is not None:
                holes.append([h[0], h[1], h[2], (i, j, name, h[3]), ()])
                continue
            try:
                openings.append((i, j, name, _opening(f, lp, size)))
            except ValueError as exc:
                notes.append(f"face:{i} loop {j}: not a circle, and its outline could not be "
                             f"read ({exc}); left out")
    extra, cnotes = _cylinder_holes(model, cyls, holes, size)
    notes.extend(cnotes)
    k = 0
    for c, ax, dia, (i, j, name, err), walls in holes:
        out.append(Feature(f"hole:{k}", "hole", i, c, ax, dia, j, name, err, walls))
        k += 1
    for i, c, ax, dia, walls in extra:
        name = None if names is None else names[i]
        out.append(Feature(f"hole:{k}", "hole", i, c, ax, dia, None, name, 0.0, walls))
        k += 1
    for n, (i, j, name, (kind, c, ax, length, width, X, err)) in enumerate(openings):
        out.append(Feature(f"{kind}:{n}", kind, i, np.asarray(c), np.asarray(ax), None, j, name,
                           err, (), X, length, width))
    try:
        object.__setattr__(model, "_sv_features", tuple(out))
        object.__setattr__(model, "_sv_feature_notes", tuple(notes))
    except (AttributeError, TypeError):  # pragma: no cover - a model without a __dict__
        pass
    logger.debug("model features: %d faces, %d holes (%d from cylindrical faces only), "
                 "%d other openings, %d notes", len(model.faces), k, len(extra), len(openings),
                 len(notes))
    return out


def feature_notes(model) -> list:
    """Why some loops or faces of ``model`` are not features (one str each): an inner loop whose
    outline could not be read, a concave cylindrical face that covers too little of its axis to
    be a hole.  Computed with :func:`model_features`."""
    model = getattr(model, "model", model)
    model_features(model)
    return list(getattr(model, "_sv_feature_notes", ()))


_KINDS_FOR = {"hole": ("hole",), "cylinder": ("cylinder",), "flatness": ("plane",),
              "plane": ("plane",), "face": ("plane", "cylinder", "freeform")}


def find_feature(features, ref=None, near=None, kind: str = "face", *, strict: bool = True):
    """Pick a feature by id (``'hole:3'``, ``'face:2'``), by the CAD name of its face (a STEP
    face name; it must name one face) or the one of ``kind`` closest to ``near`` (3,).

    For ``near``, the distance to a hole or cylinder is ``hypot(across, along / 4)`` from its
    centre (``across``/``along`` its axis: a point at the wrong height still finds its hole);
    to a face from its centre. With ``strict`` (the default) a hole or cylinder farther than
    ``max(2 x its diameter, 5 mm)`` from ``near`` is an error, not a silent match.

    Raises
    ------
    ValueError
        Unknown id or name, or no feature of that kind (the message lists what exists).
    """
    feats = list(features)
    if ref is not None:
        ref = str(ref)
        for f in feats:
            if f.id == ref:
                if kind in _KINDS_FOR and f.kind not in _KINDS_FOR[kind] and f.kind != "hole":
                    raise ValueError(f"{ref} is a {f.kind} feature, but a {kind} is needed")
                return f
        named = faces_named(feats, ref)
        if len(named) > 1:
            raise ValueError(f"the name {ref!r} belongs to {len(named)} faces "
                             f"({', '.join(f.id for f in named[:10])}); name one by its id")
        if named:
            f = named[0]
            if kind in _KINDS_FOR and f.kind not in _KINDS_FOR[kind]:
                raise ValueError(f"{ref!r} names {f.id}, a {f.kind} face, but a {kind} is "
                                 "needed" + (" (name a hole by its id, hole:N)"
                                             if kind == "hole" else ""))
            return f
        if ref.startswith(("plane:", "cylinder:")):  # alias: plane:12 = face:12
            return find_feature(feats, "face:" + ref.split(":")[1], None, kind)
        have = [f.id for f in feats if f.kind in _KINDS_FOR.get(kind, (kind,))]
        raise ValueError(f"no feature {ref!r} in the model; {kind} features: "
                         f"{', '.join(have[:30]) or 'none'} (see `shapeverify info --features`)")
    kinds = _KINDS_FOR.get(kind, (kind,))
    cand = [f for f in feats if f.kind in kinds]
    if not cand:
        raise ValueError(f"the model has no {'/'.join(kinds)} feature to match near={near}")
    p = np.asarray(near, np.float64)
    d = []
    for f in cand:
        q = p - f.center
        if f.kind in ("hole", "cylinder") and f.axis is not None:
            # mostly across the axis: a point given at the wrong height still finds its hole
            along = float(q @ f.axis)
            d.append(float(np.hypot(np.linalg.norm(q - along * f.axis), 0.25 * along)))
        else:
            d.append(float(np.linalg.norm(q)))
    best = cand[int(np.argmin(d))]
    if strict and best.kind in ("hole", "cylinder") and best.diameter:
        far = max(2.0 * float(best.diameter), 5.0)
        if min(d) > far:
            nearest = ", ".join(f"{cand[i].id} at ({', '.join(f'{c:.1f}' for c in cand[i].center)})"
                                for i in np.argsort(d)[:3])
            raise ValueError(f"no {kind} near {list(map(float, p))}: the nearest is {min(d):.1f} mm "
                             f"away (more than max(2 x its diameter, 5 mm) = {far:.1f} mm); "
                             f"nearest: {nearest} (see `shapeverify info --features`)")
    return best


def faces_named(features, name: str) -> list:
    """The face features (not holes) whose CAD name is ``name`` (a name may denote several
    faces, e.g. a face group a drawing calls ``sealing``)."""
    return [f for f in features if f.kind != "hole" and f.name is not None and f.name == name]


def features_table(model) -> list:
    """The rows of ``shapeverify info --features``: one dict per feature (see
    :meth:`Feature.to_dict`), faces first, then holes."""
    return [f.to_dict() for f in model_features(model)]
