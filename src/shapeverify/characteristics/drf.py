"""Datum reference frames (ISO 5459, ASME Y14.5): datum features fitted on the scan in their
order of precedence, each removing the degrees of freedom it constrains.

Datum features and the fit each gets (the *association criteria*)
-----------------------------------------------------------------
* **plane** (one planar face, or coplanar faces): the **tangent plane** -- the constrained
  L-infinity (minimax) plane outside the material: of all planes with every point on the
  material side, the one closest to the farthest point; it is the outer plane of the minimum
  zone (:func:`.gdt_zones.planes_zone` with ``outer``).  Not least squares: it rests on the
  high points as a surface plate does.  A secondary (tertiary) plane may only turn in the
  directions the datums before it left free (perpendicular to the primary, ...).
* **axis** of a hole: the axis of the **largest inscribed cylinder**; of a boss: of the
  **smallest circumscribed cylinder** (:func:`.gdt_zones.cylinders_zone`).  When the datums
  before it fix its direction (a hole perpendicular to a primary plane) it is the centre of the
  largest inscribed / smallest circumscribed circle of the points projected along the nominal
  axis (:func:`.gdt_zones.circles_zone`).
* **midplane** (two opposite parallel planar faces: a tab or a slot): the centre plane of
  the width's mating planes (:func:`.gdt_zones.width_planes`: the closest parallel pair
  enclosing a tab, the farthest pair inside a slot).
* **point** (``at``, a datum target point): the surface point at ``at``: ``at`` moved along the
  CAD normal by the mean deviation of the scan points within 2 mm.
* **targets** (a datum set up from point and line datum targets) and **pattern** (several
  cylinders as one datum: a pattern of holes, a common axis ``E-F``): :mod:`.datum_targets`.

Each datum gives linear equations in the small rigid correction ``xi = (omega, t)`` that moves
its measured geometry onto its nominal one (a plane: its normal, 2 equations, and its offset,
1; an axis: its direction, 2, and its position, 2; a point: 1 along its normal).  The
equations are solved in order of precedence, each datum only in the degrees of freedom the
ones before it left free (a lexicographic least-squares solution): the primary datum is met
exactly, the secondary as far as the primary lets it, and so on.  The correction is applied
and the datums fitted again until it is below 1e-10 (the fits of the lower datums depend on the
higher ones).  What no datum fixes is reported as the DRF's **free directions** (e.g. a primary
plane alone: two translations in the plane and the rotation about its normal); in those the
points stay where the plan's alignment put them (of the corrections that meet the datums, the
one with the least rotation, then the least translation: :func:`_hold_free`).

Lengths in mm, the model frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .gdt_zones import (MIN_COVERAGE, angular_coverage, circles_zone, cylinders_zone,
                        planes_zone, tangent_basis, width_planes)

__all__ = ["DatumFeature", "DatumFit", "DRF", "fit_drf", "rigid_exp"]


@dataclass(frozen=True)
class DatumFeature:
    """A datum feature's nominal geometry and its scan points.

    ``kind``: 'plane' (``point`` on it, ``direction`` the outward normal), 'axis' (``point`` on
    it, ``direction`` its direction, ``hole`` True for a hole, False for a boss) or 'point'
    (``point``, ``direction`` the outward normal).  ``points``: the scan points on the datum
    feature (model frame, the plan's alignment; may be empty for a point datum if
    ``deviations`` are given); ``deviations``: signed deviations of those points (point datums).
    """

    name: str
    kind: str
    point: np.ndarray
    direction: np.ndarray
    points: np.ndarray = field(repr=False)
    hole: bool = True
    deviations: np.ndarray | None = field(default=None, repr=False)
    #: 'midplane': the points of the opposite face (outward normal -direction)
    points2: np.ndarray | None = field(default=None, repr=False)
    #: 'targets': the contacts, each (kind 'point' | 'line' | 'circular_line', p0, n, indices
    #: into ``points``, line direction u or None, line length or circle diameter[, a circle's
    #: {slope, hole}]) (:mod:`.datum_targets`)
    contacts: tuple | None = field(default=None, repr=False)
    #: 'pattern': the features, each (p0, axis, indices into ``points``, hole)
    groups: tuple | None = field(default=None, repr=False)
    #: 'axis' of a partial cylinder (a radius: the CAD faces cover less than
    #: :data:`.gdt_zones.MIN_COVERAGE` degrees about their axis): the degrees they cover and
    #: their basic radius (mm)
    arc: float | None = None
    radius: float | None = None


@dataclass(frozen=True)
class DatumFit:
    """One fitted datum: its measured point and direction (in the corrected frame), the fit
    used, the number of points and the fit's form value (mm)."""

    name: str
    kind: str
    fit: str
    point: np.ndarray
    direction: np.ndarray
    n: int
    form: float


@dataclass(frozen=True)
class DRF:
    """A fitted datum reference frame.

    Attributes
    ----------
    names : tuple of str        datum letters, primary first
    T : (4, 4)                  the correction: model-frame points (the plan's alignment) ->
                                the frame in which the datums sit on their nominal geometry
    datums : tuple of DatumFit  the last fits (in the corrected frame)
    free : list of str          the directions no datum constrains
    free_basis : (6, k)         the same as small motions ``(omega, t)``
    iterations : int
    """

    names: tuple
    T: np.ndarray
    datums: tuple
    free: list
    free_basis: np.ndarray
    iterations: int
    #: per datum, the small motions (6, k) it constrained (the directions the datums before
    #: it left free and it fixed): where a datum feature shift (MMB/LMB) may move the frame
    constrained: tuple = ()

    def apply(self, X) -> np.ndarray:
        """Points (N, 3) of the model frame in the DRF's frame."""
        X = np.asarray(X, np.float64)
        return X @ self.T[:3, :3].T + self.T[:3, 3]

    def free_rotations(self) -> np.ndarray:
        """(k, 3) rotation axes the DRF leaves free (unit; pure rotations only)."""
        out = []
        for v in self.free_basis.T:
            w = v[:3]
            if np.linalg.norm(w) > 1e-9:
                out.append(w / np.linalg.norm(w))
        if not out:
            return np.zeros((0, 3))
        u, s, _ = np.linalg.svd(np.array(out).T, full_matrices=False)
        return u[:, s > 1e-9].T

    def to_dict(self) -> dict:
        return {"datums": "|".join(self.names), "free": list(self.free),
                "T": self.T.tolist(), "iterations": self.iterations,
                "fits": [{"name": d.name, "kind": d.kind, "fit": d.fit, "n": d.n,
                          "form": d.form, "point": d.point.tolist(),
                          "direction": d.direction.tolist()} for d in self.datums]}


def rigid_exp(xi) -> np.ndarray:
    """The rigid motion (4, 4) of the small motion ``xi = (omega, t)``: rotation by the vector
    omega (Rodrigues), then translation t."""
    w, t = np.asarray(xi[:3], float), np.asarray(xi[3:], float)
    th = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if th < 1e-15:
        R = np.eye(3) + K
    else:
        R = np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th ** 2 * K @ K
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _turns(d0, N) -> list:
    """Directions in which the unit vector d0 may turn under the rotations the free motions
    N (6, k) contain."""
    out = []
    for v in N.T:
        w = v[:3]
        if np.linalg.norm(w) > 1e-9:
            t = np.cross(w, d0)
            if np.linalg.norm(t) > 1e-9:
                out.append(t / np.linalg.norm(t))
    if not out:
        return []
    u, s, _ = np.linalg.svd(np.array(out).T, full_matrices=False)
    return [u[:, i] for i in range(len(s)) if s[i] > 1e-6]


def _turn_sine(d0, N) -> float:
    """How far (the sine of the angle) the free rotations N (6, k) turn the unit vector d0, per
    unit rotation: 0 when the datums before fix its direction (a plane's fitted normal leaves
    a rotation about itself, 1e-4 off the nominal axis: that is not a turn)."""
    out = 0.0
    for v in N.T:
        w = v[:3]
        if np.linalg.norm(w) > 1e-12:
            out = max(out, float(np.linalg.norm(np.cross(w, d0)) / np.linalg.norm(w)))
    return out


def _plane_rows(n, pm, d0, p0, B):
    """Rows (G, r) of ``G xi = r`` that bring a fitted plane (normal ``n`` through ``pm``) onto
    its nominal (``d0`` through ``p0``): its two turns across ``d0`` ((omega x n).b =
    (d0 - n).b for each b of ``B``) and its offset along ``d0``."""
    rows = [np.r_[np.cross(n, b), 0, 0, 0] for b in B]
    rhs = [(d0 - n) @ b for b in B]
    rows.append(np.r_[np.cross(pm, d0), d0])
    rhs.append(d0 @ (p0 - pm))
    return np.array(rows), np.array(rhs)


def _axis_rows(a, c, d0, p0, B):
    """Rows (G, r) that bring a fitted axis (direction ``a`` through ``c``) onto its nominal
    (``d0`` through ``p0``): its two turns and its two translations across ``d0``."""
    rows = [np.r_[np.cross(a, b), 0, 0, 0] for b in B]
    rhs = [(d0 - a) @ b for b in B]
    for b in B:
        rows.append(np.r_[np.cross(c, b), b])
        rhs.append(b @ (p0 - c))
    return np.array(rows), np.array(rhs)


def _fit(f: DatumFeature, X, N):
    """(DatumFit, rows G (m, 6), right side r (m,)) of one datum on points X (corrected frame)."""
    d0 = np.asarray(f.direction, float) / np.linalg.norm(f.direction)
    p0 = np.asarray(f.point, float)
    B = tangent_basis(d0)
    if f.kind == "plane":
        if X.shape[0] < 3:
            raise ValueError(f"datum {f.name}: {X.shape[0]} scan points on its plane (need 3)")
        turn = _turns(d0, N)[:2]
        width, n, (lo, hi) = planes_zone(X, d0, turn)
        pm = p0 + (hi - n @ p0) * n     # a point of the tangent (outer) plane
        fit = DatumFit(f.name, "plane", "tangent plane (constrained minimax, outside the "
                       "material)", pm, n, X.shape[0], width)
        return (fit, *_plane_rows(n, pm, d0, p0, B))
    if f.kind == "axis":
        kind = "inscribed" if f.hole else "circumscribed"
        what = ("largest inscribed" if f.hole else "smallest circumscribed")
        turn = _turns(d0, N)
        if X.shape[0] < 5:
            raise ValueError(f"datum {f.name}: {X.shape[0]} scan points on its axis (need 5)")
        cover = angular_coverage(X, p0, d0)
        if cover < MIN_COVERAGE and f.arc is not None and f.arc < MIN_COVERAGE:
            return _fit_arc(f, X, cover, _turn_sine(d0, N), d0, p0, B)
        if cover < MIN_COVERAGE:
            raise ValueError(f"datum {f.name}: the scan covers {np.floor(10 * cover) / 10:.1f} "
                             f"degrees of its circumference (its axis needs "
                             f"{MIN_COVERAGE:.0f})")
        if turn:
            _, c, a, (lo, hi) = cylinders_zone(X, p0, d0, kind)
            form, name = hi - lo, f"axis of the {what} cylinder"
        else:
            xy = (X - p0) @ B.T
            _, c2, (lo, hi) = circles_zone(xy, np.zeros(2), kind)
            c, a = p0 + c2 @ B, d0
            form, name = hi - lo, (f"centre of the {what} circle (direction fixed by the "
                                   "datums before it)")
        a = a if a @ d0 > 0 else -a
        fit = DatumFit(f.name, "axis", name, c, a, X.shape[0], form)
        return (fit, *_axis_rows(a, c, d0, p0, B))
    if f.kind == "point":
        dv = np.asarray(f.deviations if f.deviations is not None else [], float)
        if dv.size == 0:
            raise ValueError(f"datum {f.name}: no scan points at the datum point {p0.tolist()}")
        pm = p0 + float(np.mean(dv)) * d0
        fit = DatumFit(f.name, "point", "surface point (mean deviation within 2 mm)", pm, d0,
                       dv.size, float(np.ptp(dv)))
        return fit, np.array([np.r_[np.cross(pm, d0), d0]]), np.array([d0 @ (p0 - pm)])
    if f.kind == "midplane":
        X2 = f.points2
        if X.shape[0] < 3 or X2 is None or X2.shape[0] < 3:
            raise ValueError(f"datum {f.name}: fewer than 3 scan points on a side of its width")
        turn = _turns(d0, N)[:2]
        size, n, (h1, h2), mid = width_planes(X, X2, d0, turn)
        pm = p0 + (mid - n @ p0) * n
        fit = DatumFit(f.name, "midplane", "centre plane of the width's mating planes (the "
                       "closest pair enclosing a tab, the farthest pair inside a slot)", pm, n,
                       X.shape[0] + X2.shape[0], size)
        return (fit, *_plane_rows(n, pm, d0, p0, B))
    if f.kind == "targets":
        return _fit_targets(f, X)
    if f.kind == "pattern":
        return _fit_pattern(f, X, N)
    raise ValueError(f"datum {f.name}: unknown kind {f.kind!r} (plane, midplane, axis, "
                     "point, targets or pattern)")


#: a partial cylindrical datum feature needs this much arc (degrees) of the face and its scan
MIN_ARC = 90.0


def _fit_arc(f: DatumFeature, X, cover, turn: float, d0, p0, B):
    """A partial cylindrical datum feature (a radius; FTC 10's datum K, a boss of 166 degrees):
    no mating cylinder exists (the largest inscribed / smallest circumscribed circle of an arc
    is unbounded or degenerate), so its simulator is the cylinder of the basic radius (ASME
    Y14.5-2018 7.11.4: a datum feature simulator of basic size), placed by least squares on
    the points (Gauss-Newton on ``sum (|xy - c| - r)^2``), the direction fixed by the datums
    before it.  The scan must cover most of the face's arc."""
    if turn > 0.01:
        raise ValueError(f"datum {f.name}: a partial cylinder ({f.arc:.0f} degrees) sets an "
                         "axis only with its direction fixed by a datum before it")
    if f.arc < MIN_ARC or cover < 0.8 * f.arc:
        raise ValueError(f"datum {f.name}: the scan covers {cover:.0f} degrees of the "
                         f"{f.arc:.0f} its partial cylinder spans (its axis needs "
                         f"{max(MIN_ARC, 0.8 * f.arc):.0f})")
    r0 = float(f.radius)
    xy = (X - p0) @ B.T
    c = np.zeros(2)
    for _ in range(50):
        q = xy - c
        rho = np.linalg.norm(q, axis=1)
        J = -q / rho[:, None]                       # d(rho - r0)/dc
        step = np.linalg.lstsq(J, -(rho - r0), rcond=None)[0]
        c = c + step
        if np.linalg.norm(step) < 1e-12 * max(r0, 1.0):
            break
    res = np.linalg.norm(xy - c, axis=1) - r0
    pc = p0 + c @ B
    fit = DatumFit(f.name, "axis", f"axis of the cylinder of basic radius {r0:g} least-squares "
                   f"placed on the partial cylinder ({f.arc:.0f} degrees; direction fixed by "
                   "the datums before it)", pc, d0, X.shape[0], float(np.ptp(res)))
    return (fit, *_axis_rows(d0, pc, d0, p0, B))


def _fit_targets(f: DatumFeature, X):
    """A datum of point and line targets: one row per contact (:mod:`.datum_targets`)."""
    from .datum_targets import circle_contact, line_contact, point_contact_plane

    rows, rhs, pms, s_all = [], [], [], []
    for contact in f.contacts:
        kind, p0, n, idx, u, length = contact[:6]
        p0, n = np.asarray(p0, float), np.asarray(n, float)
        if kind == "circular_line":
            # a ring about the axis n: its centre fixes the two translations across n
            ex = contact[6]
            try:
                cm = circle_contact(X[idx], p0, n, 0.5 * length, ex["slope"], ex["hole"])
            except ValueError as e:
                raise ValueError(f"datum {f.name}: {e}") from None
            for b in tangent_basis(n):
                rows.append(np.r_[np.cross(cm, b), b])
                rhs.append(b @ (p0 - cm))
            pms.append(cm)
            continue
        try:
            # the rows use the CAD normal n, not the scanned surface's: a noisy measured normal
            # would give a datum's rows small components in directions it does not control
            # (four B points on +/-x faces would also fix y) and the rank decisions would take
            # them; the fixed point is the least squares of the contacts to first order
            if kind == "point":
                ends = [(p0, point_contact_plane(X[idx], p0, n)[0])]
            else:
                h = 0.5 * length * np.asarray(u, float)
                s1, s2 = line_contact(X[idx], p0, u, n, length)
                ends = [(p0 - h, s1), (p0 + h, s2)]
        except ValueError as e:
            raise ValueError(f"datum {f.name}: {e}") from None
        for q0, s in ends:
            pm = q0 + s * n
            rows.append(np.r_[np.cross(pm, n), n])
            rhs.append(-s)
            pms.append(pm)
            s_all.append(s)
    pm = np.mean(pms, axis=0)
    fit = DatumFit(f.name, "targets", f"{len(f.contacts)} datum target contacts (point: the "
                   "neighbourhood plane's point on the target's normal; line: the deviations' "
                   "line at its ends; circular line: the centre of the ring closed on the "
                   "part)", pm, np.asarray(f.direction, float), len(X),
                   float(np.ptp(s_all)) if s_all else 0.0)
    return fit, np.array(rows), np.array(rhs)


def _fit_pattern(f: DatumFeature, X, N):
    """A pattern of axes (or a common axis) as one datum: each axis fitted as an 'axis'
    datum; 2 rows (across its nominal direction) at each of its ends, so that all rows are
    lengths and the least squares is of the axes' ends' distances from their true positions
    (:mod:`.datum_targets`)."""
    rows, rhs, forms, cs = [], [], [], []
    for k, (p0, d0, idx, hole) in enumerate(f.groups):
        p0, d0 = np.asarray(p0, float), np.asarray(d0, float) / np.linalg.norm(d0)
        g = DatumFeature(f"{f.name}[{k + 1}]", "axis", p0, d0, X[idx], hole=hole)
        fit, _, _ = _fit(g, X[idx], N)
        c, a = fit.point, fit.direction
        h = (X[idx] - c) @ a
        for e in (c + h.min() * a, c + h.max() * a):
            nom = p0 + ((e - p0) @ d0) * d0
            for b in tangent_basis(d0):
                rows.append(np.r_[np.cross(e, b), b])
                rhs.append(b @ (nom - e))
        forms.append(fit.form)
        cs.append(c)
    d0 = np.asarray(f.direction, float)
    fit = DatumFit(f.name, "pattern", f"{len(f.groups)} axes (each its mating cylinder's) "
                   "fitted together at their CAD positions (least squares)",
                   np.mean(cs, axis=0), d0 / np.linalg.norm(d0), len(X), float(max(forms)))
    return fit, np.array(rows), np.array(rhs)


def _with_points2(f, X2):
    import dataclasses

    return dataclasses.replace(f, points2=X2)


def _describe(N, scale) -> list:
    out = []
    for v in N.T:
        w, t = v[:3] * scale, v[3:]
        if np.linalg.norm(w) > 1e-6 * max(1.0, np.linalg.norm(t)):
            a = w / np.linalg.norm(w)
            # the point of the rotation axis: t = -omega x p  ->  p = omega x t / |omega|^2
            p = np.round(np.cross(w, t) / (w @ w), 3) + 0.0     # no '-0.000'
            out.append(f"rotation about ({a[0]:+.3f}, {a[1]:+.3f}, {a[2]:+.3f}) through "
                       f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})")
        else:
            a = t / np.linalg.norm(t)
            out.append(f"translation along ({a[0]:+.3f}, {a[1]:+.3f}, {a[2]:+.3f})")
    return out


def _hold_free(xi, N, Sc, L: float):
    """``xi`` (scaled motion) less the free motions ``N`` that take it away from where the plan's
    alignment put the points: of all corrections that meet the datums (``xi + N s``), the one
    with the least rotation, then the least translation.  (The least-norm solution of the
    datum equations is not that: with G|H -- a plane, then an axis 317 mm from the origin --
    the axis' offset was met partly by a turn about the origin, the DRF turned 1.6e-4 rad
    about H's axis, which no datum fixes, and a bore 604 mm from H read 0.69 mm off on a
    perfect CTC 02.)"""
    if N.shape[1] == 0:
        return xi
    W = np.diag([1e3 * L] * 3 + [1.0] * 3) @ Sc
    s = np.linalg.lstsq(W @ N, W @ xi, rcond=None)[0]
    return xi - N @ s


def one_pass(feats, Sc, L: float, fit_one):
    """One pass of the lexicographic solution (module docstring): ``fit_one(i, f, Sc @ N)`` gives
    datum ``i``'s (DatumFit, G, r) in the degrees of freedom ``N`` the datums before it left
    free.  Returns the scaled correction ``xi`` (the motion is ``Sc @ xi``), the free motions
    ``N``, the fits and, per datum, the motions it constrained."""
    xi = np.zeros(6)
    N = np.eye(6)
    fits, cons = [], []
    for i, f in enumerate(feats):
        fit, G, r = fit_one(i, f, Sc @ N)
        fits.append(fit)
        A = G @ Sc @ N
        if A.size == 0 or N.shape[1] == 0:
            cons.append(np.zeros((6, 0)))
            continue
        y = np.linalg.lstsq(A, r - G @ Sc @ xi, rcond=None)[0]
        xi = xi + N @ y
        _, s, vt = np.linalg.svd(A, full_matrices=True)
        rank = int(np.sum(s > 1e-9 * max(1.0, s.max() if s.size else 1.0)))
        cons.append(Sc @ N @ vt[:rank].T)
        N = N @ vt[rank:].T
    return _hold_free(xi, N, Sc, L), N, fits, cons


def fit_drf(features, size: float = 100.0, max_iterations: int = 8) -> DRF:
    """Fit a datum reference frame (see the module docstring).

    Parameters
    ----------
    features : sequence of DatumFeature
        Primary, secondary, tertiary (1 to 3).
    size : float
        The part's size (mm): scales rotations against translations in the rank decisions.

    Returns
    -------
    DRF

    Raises
    ------
    ValueError
        Too few points on a datum feature, or a fit failed (the datum is named).
    """
    feats = list(features)
    if not 1 <= len(feats) <= 3:
        raise ValueError(f"a datum reference frame has 1 to 3 datums, got {len(feats)}")
    L = float(size) or 1.0
    Sc = np.diag([1 / L] * 3 + [1.0] * 3)   # omega = Sc[:3] y: columns in comparable units
    T = np.eye(4)
    fits, N, it = (), np.eye(6), 0
    for it in range(1, max_iterations + 1):

        def fit_moved(i, f, SN, T=T):
            X = f.points @ T[:3, :3].T + T[:3, 3] if len(f.points) else f.points
            if f.points2 is not None:
                f = _with_points2(f, f.points2 @ T[:3, :3].T + T[:3, 3])
            return _fit(f, X, SN)

        xi, N, fits, cons = one_pass(feats, Sc, L, fit_moved)
        step = Sc @ xi
        T = rigid_exp(step) @ T
        if np.linalg.norm(step[:3]) * L + np.linalg.norm(step[3:]) < 1e-10:
            break
    free_basis = Sc @ N
    return DRF(tuple(f.name for f in feats), T, tuple(fits), _describe(N, 1 / L),
               free_basis, it, tuple(cons))
