"""Datums set up from datum targets (ASME Y14.5-2018 section 7.24, ISO 5459 section 7) and
from several features at once (a pattern of holes as one datum, a common axis).

A datum target is a place on the datum feature where the simulator touches the part: a point
(a spherical-ended pin), a line (the edge of a knife or the side of a pin) or a small area (a
circular or rectangular pad).  The datum is the geometry the simulators, held at their basic
(CAD) locations, establish from those contacts.  On a scan each contact is measured from the
scan points around it:

* **point target** at ``p0`` on a face with CAD normal ``n``: the least-squares plane of the
  scan points of that face within :data:`POINT_RADIUS` of ``p0`` (2.5 scan spacings when
  that is more: a small neighbourhood of the surface; at least the :data:`POINT_MIN` nearest
  within three times that: :func:`point_neighbours`; less those more than
  :data:`SURFACE_BAND` or 5 robust sigmas from the median height: not on that surface),
  cut by the simulator's line ``p0 + s n``: the contact is ``p0 + s n``
  (:func:`point_contact`).  It fixes one degree of freedom: the part's position along ``n``
  at ``p0``.
* **line target** through ``p0`` along ``u``, ``L`` long: the scan points within
  :data:`LINE_RADIUS` (1.5 scan spacings when more) of the segment; their deviations along ``n`` fitted by a straight line
  in the parameter along ``u`` (least squares); the contacts are its values at the two ends
  (:func:`line_contact`).  It fixes two degrees of freedom: the position along ``n`` and the
  rotation about ``u x n``.
* **area target** (circle of diameter ``L``, rectangle ``L x W``) on a plane: the datum plane
  is the tangent plane (:mod:`.drf`, as for a whole planar datum feature) of the scan points
  inside the area.

A datum of several point and line targets gives one equation per contact; :func:`.drf.fit_drf`
solves them in the degrees of freedom the datums before it left free (least squares when there
are more contacts than those: e.g. four points of a secondary datum in three free directions).

A **pattern datum** (several cylinders as one datum feature, ASME Y14.5 section 7.18) and a
**common datum** (two coaxial cylinders, ``E-F``): each cylinder's axis is fitted as for a
single axis datum (its mating cylinder: largest inscribed for a hole, smallest circumscribed
for a boss); the datum is the pattern of those axes held at their CAD positions relative to
one another, placed by least squares on all of them (4 equations per axis: its direction and
its position).  This is the least-squares fit of the pattern, not the simultaneous mating of
a rigid pattern of simulators the standard describes (which can differ by the features' form
errors, here of the order of the scan noise).

Lengths in mm.
"""
from __future__ import annotations

import numpy as np

__all__ = ["POINT_RADIUS", "POINT_MIN", "LINE_RADIUS", "SURFACE_BAND", "point_neighbours",
           "point_contact", "line_contact",
           "circle_contact", "in_area",
           "targets_feature", "pattern_feature"]

#: scan points within this distance (mm) of a point target make its neighbourhood plane
POINT_RADIUS = 2.0
#: a point target's plane takes at least this many scan points (the nearest, within three
#: times the radius) when its disc holds fewer
POINT_MIN = 8
#: scan points within this distance (mm) of a line target's segment make its contact line
LINE_RADIUS = 1.0
#: of a point target's neighbours, those farther than this (mm; or 5 robust sigmas) from
#: their median height along the target's normal are not on its surface: a point behind a thin
#: wall whose closest CAD point is on the target's face (its own face missing from the model)
SURFACE_BAND = 0.5


def point_neighbours(feet, on, p0, spacing: float) -> np.ndarray:
    """The scan points (boolean mask) whose contact plane a point target at ``p0`` takes: of
    the points ``on`` its face, those with feet within :data:`POINT_RADIUS` of ``p0`` (2.5
    ``spacing`` when more); when that disc holds fewer than :data:`POINT_MIN`, the
    :data:`POINT_MIN` nearest within three times its radius.  A randomly sampled scan leaves
    a small disc nearly empty now and then: its median spacing is about half the mean
    distance between points (NIST CTC 02's datum A, three point targets, sampled at 1.5 mm:
    one target had fewer than 3 points in 23 % of scans, and every tolerance on A|B|C was
    undecided).

    >>> rng = np.random.default_rng(0)       # 2.1 mm apart on average, at random
    >>> feet = np.column_stack([rng.uniform(0, 30, 200), rng.uniform(0, 30, 200), np.zeros(200)])
    >>> d = np.linalg.norm(feet - [15, 15, 0], axis=1)
    >>> sel = point_neighbours(feet, np.ones(200, bool), np.array([15.0, 15, 0]), 0.5)
    >>> int((d <= 2.0).sum()), int(sel.sum()), bool(d[sel].max() < d[~sel].min())
    (4, 8, True)
    """
    d = np.linalg.norm(np.asarray(feet, float) - np.asarray(p0, float), axis=1)
    r = max(POINT_RADIUS, 2.5 * float(spacing))
    sel = on & (d <= r)
    if int(sel.sum()) >= POINT_MIN:
        return sel
    cand = np.flatnonzero(on & (d <= 3.0 * r))
    out = np.zeros(len(d), bool)
    out[cand[np.argsort(d[cand], kind="stable")[:POINT_MIN]]] = True
    return out


def point_contact(X, p0, n) -> float:
    """Where the simulator of a point target at ``p0`` (direction ``n``) meets the scanned
    surface (see :func:`point_contact_plane`)."""
    return point_contact_plane(X, p0, n)[0]


def point_contact_plane(X, p0, n) -> tuple[float, np.ndarray]:
    """``(s, m)``: where the simulator of a point target at ``p0`` (direction ``n``) meets the
    scanned surface, ``p0 + s n`` on the least-squares plane of the points ``X``, and that
    plane's unit normal ``m`` (turned towards ``n``).

    Parameters
    ----------
    X : (m, 3) array
        Scan points of the target's neighbourhood (m >= 3, not on one line).
    p0, n : (3,) arrays
        The target's point and the CAD surface's unit normal there.

    Raises
    ------
    ValueError
        Fewer than 3 points, points on a line, or a plane parallel to ``n``.
    """
    X = np.asarray(X, np.float64)
    p0, n = np.asarray(p0, float), np.asarray(n, float)
    if X.shape[0] < 3:
        raise ValueError(f"{X.shape[0]} scan points near the datum target at "
                         f"{np.round(p0, 4).tolist()} (a plane needs 3; is it scanned?)")
    h = (X - p0) @ n
    med = float(np.median(h))
    mad = 1.4826 * float(np.median(np.abs(h - med)))
    X = X[np.abs(h - med) <= max(SURFACE_BAND, 5.0 * mad)]
    if X.shape[0] < 3:
        raise ValueError(f"{X.shape[0]} scan points near the datum target at "
                         f"{np.round(p0, 4).tolist()} lie on its surface (a plane needs 3)")
    c = X.mean(axis=0)
    _, s, vt = np.linalg.svd(X - c, full_matrices=False)
    if s[1] <= 1e-9 * max(s[0], 1e-12):
        raise ValueError(f"the scan points near the datum target at {np.round(p0, 4).tolist()} "
                         "lie on a line; no plane through them")
    m = vt[2]
    den = float(m @ n)
    if abs(den) < 0.5:
        raise ValueError(f"the scanned surface at the datum target {np.round(p0, 4).tolist()} "
                         f"is {np.degrees(np.arccos(min(1.0, abs(den)))):.0f} degrees off its "
                         "CAD normal")
    m = m if den > 0 else -m
    return float(m @ (c - p0)) / abs(den), m


def line_contact(X, p0, u, n, length) -> tuple[float, float]:
    """The contacts of a line target at its two ends ``p0 -/+ length/2 u``: the deviations of
    ``X`` along ``n`` fitted by ``a + b t`` (t the parameter along ``u``), at ``t = -/+ L/2``.

    Raises
    ------
    ValueError
        Fewer than 3 points or all of them at one place along the line.
    """
    X = np.asarray(X, np.float64)
    p0, u, n = (np.asarray(v, float) for v in (p0, u, n))
    if X.shape[0] < 3:
        raise ValueError(f"{X.shape[0]} scan points along the line datum target at "
                         f"{np.round(p0, 4).tolist()} (need 3; is it scanned?)")
    t = (X - p0) @ u
    if np.ptp(t) < 0.1 * length:
        raise ValueError(f"the scan points along the line datum target at "
                         f"{np.round(p0, 4).tolist()} cover {np.ptp(t):.3g} of its "
                         f"{length:g} mm")
    A = np.column_stack([np.ones_like(t), t])
    a, b = np.linalg.lstsq(A, (X - p0) @ n, rcond=None)[0]
    h = 0.5 * float(length)
    return float(a - b * h), float(a + b * h)


def circle_contact(X, p0, axis, radius, slope, hole: bool) -> np.ndarray:
    """The centre of a circular line target (a ring of diameter ``2 radius`` about ``p0``,
    normal ``axis``, touching the part along a circle): the centre of the smallest circle
    holding the scan points of a boss (the ring closing on it), of the largest circle inside
    those of a hole (a plug opening in it) -- each point first moved along the surface to the
    ring's plane: its radius about that centre less ``slope`` times its height above the
    plane (found by fixed-point iteration; ``slope``: the
    CAD surface's change of radius with height at the circle, ``-n_axial / n_radial`` of its
    normal; 0 on a cylinder, ``tan`` of the half angle on a drafted boss).  The ring's
    plane is held at its basic place (the datums before it fix the height).

    Returns
    -------
    (3,) array: the centre, in the ring's plane.

    Raises
    ------
    ValueError
        Fewer than 3 points, or they cover less than :data:`.gdt_zones.MIN_COVERAGE` degrees of
        the circle.
    """
    from .gdt_zones import MIN_COVERAGE, angular_coverage, circles_zone, tangent_basis

    X = np.asarray(X, np.float64)
    p0 = np.asarray(p0, float)
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    if X.shape[0] < 3:
        raise ValueError(f"{X.shape[0]} scan points along the circular datum target at "
                         f"{np.round(p0, 4).tolist()} (need 3; is it scanned?)")
    cover = angular_coverage(X, p0, a)
    if cover < MIN_COVERAGE:
        raise ValueError(f"the scan covers {cover:.0f} degrees of the circular datum target at "
                         f"{np.round(p0, 4).tolist()} (need {MIN_COVERAGE:.0f})")
    q = X - p0
    h = q @ a
    B = tangent_basis(a)
    xy = q @ B.T
    c2 = np.zeros(2)
    for _ in range(20):     # the move to the plane is radial about the centre being found
        v = xy - c2
        rho = np.linalg.norm(v, axis=1)
        moved = c2 + v * ((rho - float(slope) * h) / rho)[:, None]
        _, c_new, _ = circles_zone(moved, c2, "inscribed" if hole else "circumscribed")
        step = float(np.linalg.norm(c_new - c2))
        c2 = c_new
        if step < 1e-12:
            break
    return p0 + c2 @ B


def in_area(X, target) -> np.ndarray:
    """Mask of the points ``X`` inside an area target (``type`` circle: within ``length/2``
    of ``at`` across ``direction``; rectangle: ``length`` along ``xdirection``, ``width``
    across), measured in the target's plane."""
    X = np.asarray(X, np.float64)
    c = np.asarray(target.at, float)
    n = np.asarray(target.direction, float)
    n = n / np.linalg.norm(n)
    q = X - c
    q = q - np.outer(q @ n, n)
    if target.type == "circle":
        return np.linalg.norm(q, axis=1) <= 0.5 * target.length
    if target.type == "rectangle":
        x = np.asarray(target.xdirection if target.xdirection is not None else
                       np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))]), float)
        x = x - (x @ n) * n
        x /= np.linalg.norm(x)
        y = np.cross(n, x)
        return (np.abs(q @ x) <= 0.5 * target.length) & (np.abs(q @ y) <= 0.5 * target.width)
    raise ValueError(f"a {target.type} datum target is not an area")


# ------------------------------------------------------------------------------ datum features
def targets_feature(name, spec, ctx):
    """The :class:`.drf.DatumFeature` of a datum set up from datum targets (``spec.targets``)
    on a scan (:class:`.evaluate.EvalContext`): point and line targets make a 'targets'
    feature of contacts; area targets (all on one plane) a 'plane' feature of the points
    inside them.  Raises ValueError (naming the datum) for a mix of areas and points/lines."""
    from .alignment import face_indices
    from .drf import DatumFeature
    from .gdt import _on

    S = ctx.S
    areas = [t for t in spec.targets if t.type in ("circle", "rectangle")]
    if areas and len(areas) != len(spec.targets):
        raise ValueError(f"datum {name}: area targets mixed with point/line targets; a datum "
                         "is set up from areas alone or from points and lines alone")
    if areas:
        fidx = sorted({int(face_indices(ctx.prep.model, [t.face])[0]) for t in areas})
        if {ctx.feats[i].kind for i in fidx} != {"plane"}:
            raise ValueError(f"datum {name}: its area targets lie on faces {fidx} that are not "
                             "all planes")
        m = _on(ctx, fidx)
        keep = np.zeros(len(S.X), bool)
        for t in areas:
            keep |= in_area(S.feet, t)
        f = ctx.feats[fidx[0]]
        return DatumFeature(name, "plane", np.asarray(areas[0].at, float), f.axis,
                            S.X[m & keep])
    pts, contacts = [], []
    for t in spec.targets:
        at = np.asarray(t.at, float)
        if t.type == "circular_line":
            k0 = sum(len(p) for p in pts)
            X, extra = _circle_points(name, t, ctx)
            pts.append(X)
            contacts.append(("circular_line", at, extra.pop("axis"),
                             np.arange(k0, k0 + len(X)), None, float(t.length), extra))
            continue
        fc = int(face_indices(ctx.prep.model, [t.face])[0])
        # the normal of the target's own face (a target at an edge has its closest CAD
        # point on either face)
        if ctx.feats[fc].kind == "plane":
            n = np.asarray(ctx.feats[fc].axis, float)
        else:
            foot = ctx.prep.closest(at[None], exact=True)
            if int(foot.face[0]) != fc:
                raise ValueError(f"datum {name}: the target at {np.round(at, 4).tolist()} is "
                                 f"not on its face face:{fc} (closest: face:{int(foot.face[0])})")
            n = np.asarray(foot.normals[0], float)
        # the target's face only, edges included (a target may sit near an edge; a point of
        # the neighbouring face has its foot there, not on this face)
        on = S.on([fc])
        sp = float(getattr(S.support, "spacing", 0.0) or 0.0)
        if t.type == "point":
            sel = point_neighbours(S.feet, on, at, sp)
            u, length = None, 0.0
        else:
            u = np.asarray(t.direction, float) / np.linalg.norm(t.direction)
            q = S.feet - at
            tt = np.clip(q @ u, -0.5 * t.length, 0.5 * t.length)
            sel = on & (np.linalg.norm(q - tt[:, None] * u, axis=1)
                        <= max(LINE_RADIUS, 1.5 * sp))
            length = float(t.length)
        k0 = sum(len(p) for p in pts)
        pts.append(S.X[sel])
        contacts.append((t.type, at, n, np.arange(k0, k0 + int(sel.sum())), u, length))
    X = np.concatenate(pts) if pts else np.zeros((0, 3))
    nbar = np.mean([c[2] for c in contacts], axis=0)
    if np.linalg.norm(nbar) < 1e-9:
        nbar = contacts[0][2]
    return DatumFeature(name, "targets", np.mean([c[1] for c in contacts], axis=0),
                        nbar / np.linalg.norm(nbar), X, contacts=tuple(contacts))


def _circle_points(name, t, ctx) -> tuple[np.ndarray, dict]:
    """(scan points, {axis, slope, hole}) of a circular line target: the points of its faces
    whose feet lie within :data:`LINE_RADIUS` (1.5 scan spacings when more) of the circle; the
    slope and side from the CAD normals at 16 points of the circle."""
    from .alignment import face_indices
    from .gdt_zones import tangent_basis

    S = ctx.S
    at = np.asarray(t.at, float)
    a = np.asarray(t.direction, float) / np.linalg.norm(t.direction)
    R = 0.5 * float(t.length)
    faces = t.faces if t.faces is not None else [t.face]
    fidx = [int(i) for i in face_indices(ctx.prep.model, faces)]
    B = tangent_basis(a)
    ang = 2 * np.pi * np.arange(16) / 16
    U = np.outer(np.cos(ang), B[0]) + np.outer(np.sin(ang), B[1])
    foot = ctx.prep.closest(at + R * U, exact=True)
    far = np.asarray(foot.distances, float)
    if np.abs(far).max() > max(1e-3, 1e-6 * R):
        raise ValueError(f"datum {name}: its circular target (\u2300{2 * R:g} at "
                         f"{np.round(at, 4).tolist()}) is {np.abs(far).max():.3g} mm off the CAD "
                         "surface")
    Nn = np.asarray(foot.normals, float)
    nr, na = np.sum(Nn * U, axis=1), Nn @ a
    if np.abs(nr).min() < 0.1:
        raise ValueError(f"datum {name}: the surface under its circular target is nearly "
                         "perpendicular to the ring's axis (a ring touches a boss or a hole)")
    q = S.feet - at
    h = q @ a
    rad = np.linalg.norm(q - np.outer(h, a), axis=1)
    sp = float(getattr(S.support, "spacing", 0.0) or 0.0)
    sel = S.on(fidx) & (np.hypot(rad - R, h) <= max(LINE_RADIUS, 1.5 * sp))
    return S.X[sel], {"axis": a, "slope": float(np.mean(-na / nr)),
                      "hole": bool(np.mean(nr) < 0)}


def pattern_feature(name, spec, ctx):
    """The 'pattern' :class:`.drf.DatumFeature` of several cylinders (``spec.faces``: their
    faces; coaxial faces make one cylinder): each cylinder's points and CAD axis."""
    from .alignment import face_indices
    from .drf import DatumFeature
    from .gdt import _cylinder_points, _on

    S, feats = ctx.S, ctx.feats
    fidx = face_indices(ctx.prep.model, spec.faces).tolist()
    if {feats[i].kind for i in fidx} != {"cylinder"}:
        raise ValueError(f"datum {name}: a pattern datum is of cylinder faces; faces "
                         f"{spec.faces} are {sorted({feats[i].kind for i in fidx})}")
    groups: list = []
    for i in fidx:
        f = feats[i]
        for g in groups:
            q = f.center - g[0].center
            if (np.linalg.norm(np.cross(f.axis, g[0].axis)) < 1e-4
                    and np.linalg.norm(q - (q @ g[0].axis) * g[0].axis) < 1e-4 * f.diameter
                    + 1e-6 and abs(f.diameter - g[0].diameter) < 1e-4 * f.diameter + 1e-6):
                g[1].append(i)
                break
        else:
            groups.append((f, [i]))
    pts, out = [], []
    k0 = 0
    for f, faces in groups:
        m = _on(ctx, faces)
        X = S.X[m]
        q = X - f.center
        radial = q - np.outer(q @ f.axis, f.axis)
        hole = float(np.sum(S.normals[m] * radial)) < 0 if len(X) else True
        X, _ = _cylinder_points(X, f)
        pts.append(X)
        out.append((f.center, f.axis, np.arange(k0, k0 + len(X)), hole))
        k0 += len(X)
    axes = np.array([f.axis if f.axis @ groups[0][0].axis > 0 else -f.axis
                     for f, _ in groups])
    return DatumFeature(name, "pattern", np.mean([f.center for f, _ in groups], axis=0),
                        axes.mean(axis=0), np.concatenate(pts), groups=tuple(out))
