"""Evaluators of the GD&T characteristics (issue 28 item 3), each in its own datum reference
frame (:mod:`.drf`) where it names ``datums``.

Definitions (ISO 1101 / ASME Y14.5; zones by :mod:`.gdt_zones`; lengths in mm)
-------------------------------------------------------------------------------
Cylinder features lose their gross outliers first (:func:`_cylinder_points`: 5 robust sigmas
from the robust least-squares cylinder).  The points of a characteristic are the kept points of its faces (:mod:`.evaluate`) whose
closest CAD point is at least 2 scan spacings (0.5 mm) inside the face's edges (:func:`_on`),
moved into the
characteristic's DRF (:meth:`.drf.DRF.apply`) when it names datums.

* **straightness** ``zone: lines``: the faces' points cut into 10 bands across ``direction``
  (default: the face's longest extent); each band's line element is enclosed by two parallel
  lines (minimum zone, the normal turning only along the band); the value is the largest.
  ``zone: diameter``: the axis of a cylinder: centres of the minimum-zone circles of 10
  cross-sections; value = diameter of the smallest cylinder holding them.
* **circularity**: minimum-zone concentric circles of each of 10 cross-sections of the cylinder
  (perpendicular to the CAD axis); the value is the largest radial separation.
* **cylindricity**: minimum-zone coaxial cylinders of all points.
* **parallelism, perpendicularity, angularity** of a plane (``zone: planes``): two parallel
  planes at the CAD orientation relative to the DRF; the zone may turn only about the
  rotations the DRF leaves free (about a single datum plane's normal for a perpendicular or
  inclined face); value = their minimum distance.  Of an axis (``zone: diameter``, a hole or
  boss): the axis of the mating cylinder (largest inscribed for a hole, smallest
  circumscribed for a boss) between the ends of the feature; value = the
  diameter of the smallest cylinder in the CAD axis's direction holding those ends (the
  distance of the ends across that direction).  ``projected: L`` (Ⓟ): the ends are those of
  the fitted axis at the mouth and ``L`` beyond (as for position, below).
* **position** (``zone: diameter``): each feature's axis is the axis of its mating cylinder
  (ASME Y14.5: the unrelated actual mating envelope); value = twice the largest distance of its
  ends from the true position (the CAD axis in the DRF); ``zone: planes`` (ASME Y14.5-2009
  §7.7.3): twice the largest offset of the ends along ``direction`` (across the axis).
  ``material: M``: bonus = the mating
  size's departure from the maximum material size (a hole: mating diameter - (nominal +
  lower); a boss: (nominal + upper) - mating diameter); ``L``: from the least material size
  (a hole's smallest circumscribed, a boss's largest inscribed diameter).  The limit is
  ``tol + bonus`` (a negative bonus, a feature out of its size limits, counts as 0 and is
  reported), at most ``max_tol`` when the frame caps it (ASME Y14.5-2009 §7.3.4).
  ``projected: L`` (Ⓟ, §7.4.1): the zone holds the axis extended out of the hole's mouth:
  value = twice the largest distance from the true position of the fitted axis where it
  crosses the planes normal to the CAD axis at the mouth and ``L`` beyond (the side:
  ``projected_direction``, else the ``hole:k`` feature's axis, :func:`_projection_direction`);
  a short feature's axis is its least-squares cylinder's (a mating fit keeps the CAD
  direction, blind to the tilt the projection magnifies).  A pattern is one tolerance: every feature in the same DRF; the result is the
  feature with the smallest margin, every feature's numbers in ``details['features']``.
* **composite: lower** (position, surface_profile; :mod:`.composite`): the zone framework
  translates, and turns about the axes the DRF leaves free, to the place minimising the worst
  feature's deviation (``details['composite']``: the motion and the located value).
* **circular / total runout** about the DRF's axis (the primary datum's, at its nominal
  place in the DRF): :func:`.gdt_zones.runout`.
* **width** (size): distance between two parallel faces: each face's points' mean distance
  from the other face's least-squares plane, averaged; deviation = measured - CAD distance.
* **surface_profile** with ``datums``: as the plan's profile but the points are moved into the
  DRF and their deviations taken again from the CAD (exact closest points).

Uncertainty (k, ISO 14253-1) of a zone width taken from extreme points: ``2 z_n sigma`` per
zone (:func:`.support.extreme_quantile`, sigma the scan noise) where the zone is one-sided or
about a nominal (profile, position); a two-sided zone read from extreme points -- a planar
orientation zone, circularity and cylindricity (radii from the zone's centre or axis over
``(R theta, h)``, :func:`.zone_noise.cylinder_coords`), straightness of line elements, circular
and total runout on cylinders or on faces square to the axis -- instead takes the noise's
expected part off its width and keeps its spread (:mod:`.zone_noise`; ``zone_of_points``: the
width of the points as read), combined in quadrature with
the datum part (``details['u_datums']``): the datum features' fits re-made on simulated noisy
datums move the frame, which moves the points the value is read from (:mod:`.datum_noise`;
the translation enters location -- position, profile in a DRF, symmetry -- the turn every
zone).  For position ``2 z_n sigma`` per axis end of a mating cylinder (it rests on extreme
points too); a short feature's mating circle (CAD direction) moves only with the difference of
its extremes (:func:`mating_centre_u`).  Free directions of the DRF stay at the plan's
alignment.  Runout keeps its own datum-axis part (:func:`runout_datum_u`).
"""
from __future__ import annotations

import numpy as np

from .alignment import face_indices
from .datum_noise import datum_u
from .drf import DatumFeature, fit_drf
from .zone_noise import corrected_spread, corrected_width, cylinder_coords
from .evaluate import CharacteristicResult, EvalContext, _not_measured, _profile
from .gdt_zones import (MIN_COVERAGE, angular_coverage, circles_zone, cylinders_zone,
                        planes_zone, tangent_basis)
from .support import extreme_quantile
from .zones import decide, zone_decide

__all__ = ["eval_surface_profile", "eval_orientation", "eval_position", "eval_runout",
           "eval_straightness", "eval_circularity", "eval_cylindricity", "eval_width", "drf_of",
           "mating_centre_u", "runout_datum_u"]


# ------------------------------------------------------------------------------ points
def _on(ctx: EvalContext, faces) -> np.ndarray:
    """The kept points of ``faces`` whose closest CAD point lies inside the face, at least
    ``EDGE`` spacings (and 0.5 mm) from its edges (:func:`edge_margin`): a point of a
    neighbouring surface beyond an edge (the plate at the foot of a moved boss, a tilted
    wall's foot) is not the face's.  On a face narrower than twice that band (the wall of a
    hole through a 1.9 mm sheet: NIST CTC 03's datums B and C; FTC 06's 1.9 mm annular step)
    the band is half the face's inradius, so its inner half is kept."""
    S = ctx.S
    m = S.on(faces)
    e = edge_margin(S)
    out = m.copy()
    for f in (np.unique(S.face[m]) if faces is None else faces):
        sel = m & (S.face == f)
        if sel.any():
            tree, inradius = _edge_tree(ctx, int(f))
            d, _ = tree.query(S.feet[sel])
            out[np.flatnonzero(sel)[d < min(e, 0.5 * inradius)]] = False
    return out


def _edge_tree(ctx: EvalContext, f: int):
    """(kd-tree of face ``f``'s trim loops in 3D (:func:`_rim`, a sixteenth of the edge band
    apart), the face's inradius: the largest distance of a point of the face from its loops,
    on a 48 x 48 grid of its domain; inf when no grid point falls inside), cached."""
    key = ("edge", f)
    if key not in ctx.cache:
        from scipy.spatial import cKDTree

        face = ctx.prep.model.faces[f]
        tree = cKDTree(_rim(face, edge_margin(ctx.S) / 16.0))
        (a0, a1), (b0, b1) = face.uv_bounds
        g = np.linspace(0.0, 1.0, 50)[1:-1]
        uv = np.column_stack([np.repeat(a0 + g * (a1 - a0), g.size),
                              np.tile(b0 + g * (b1 - b0), g.size)])
        uv = uv[face.contains(uv)]
        inradius = float(tree.query(face.evaluate(uv))[0].max()) if len(uv) else np.inf
        ctx.cache[key] = (tree, inradius)
    return ctx.cache[key]


#: points whose closest CAD point is nearer than this many scan spacings to the face's edge
#: are left out of the GD&T characteristics (:func:`_on`)
EDGE = 2.0


def _rim(face, step: float) -> np.ndarray:
    """Points along the face's trim loops at most about ``step`` apart in 3-D (a loop's
    straight segment can be 100 mm long between two vertices: a fixed count per segment left
    most of a long edge without the band of :func:`_on`)."""
    from .features import _dense_loop

    # a trim loop's vertices may lie a rounding error outside the surface's domain
    # (FTC 06: v = -5e-6 on [1.8e-8, 38.6]): clipped onto it
    (u0, u1), (v0, v1) = face.surface.domain

    def clip(q):
        return np.column_stack([np.clip(q[:, 0], u0, u1), np.clip(q[:, 1], v0, v1)])

    out = []
    for lp in face.loops:
        q = clip(_dense_loop(lp, 8))
        P = face.evaluate(q)
        seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
        n = np.clip(np.ceil(seg / step), 1, 10_000).astype(np.int64)
        idx = np.repeat(np.arange(len(q)), n)
        t = (np.arange(idx.size) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
        nq = np.roll(q, -1, axis=0)
        out.append(face.evaluate(clip(q[idx] * (1 - t[:, None]) + nq[idx] * t[:, None])))
    return np.concatenate(out)


def edge_margin(S) -> float:
    """The edge band of :func:`_on` (mm): ``EDGE`` scan spacings, at least 0.5 mm."""
    sp = float(getattr(S.support, "spacing", 0.0) or 0.0)
    return max(EDGE * sp, 0.5)


# ------------------------------------------------------------------------------ DRF
def _datum_feature(name, spec, ctx: EvalContext) -> DatumFeature:
    S, feats = ctx.S, ctx.feats
    if spec.targets is not None or spec.kind == "pattern":
        from .datum_targets import pattern_feature, targets_feature

        return (targets_feature if spec.targets is not None else pattern_feature)(
            name, spec, ctx)
    if spec.at is not None:
        at = np.asarray(spec.at, float)
        foot = ctx.prep.closest(at[None], exact=True)
        q, n, fc = foot.points[0], foot.normals[0], int(foot.face[0])
        m = _on(ctx, [fc]) & (np.linalg.norm(S.feet - q, axis=1) <= 2.0)
        return DatumFeature(name, "point", q, n, S.X[m], deviations=S.d[m])
    fidx = face_indices(ctx.prep.model, spec.faces).tolist()
    kinds = {feats[i].kind for i in fidx}
    kind = spec.kind or ("plane" if kinds == {"plane"} else
                         "axis" if kinds == {"cylinder"} else None)
    if kind is None:
        raise ValueError(f"datum {name}: faces {spec.faces} are {sorted(kinds)}; a datum "
                         "feature is planar faces (plane) or cylinder faces (axis); give kind")
    m = _on(ctx, fidx)
    f = feats[fidx[0]]
    if kind == "plane":
        from .datum_filter import filter_plane_points

        return DatumFeature(name, "plane", f.center, f.axis, filter_plane_points(S.X[m]))
    if kind == "midplane":
        one = [i for i in fidx if feats[i].axis @ f.axis > 0]
        two = [i for i in fidx if feats[i].axis @ f.axis < 0]
        if not one or not two or kinds != {"plane"}:
            raise ValueError(f"datum {name}: a midplane needs planar faces on both sides of a "
                             f"width; faces {spec.faces} are not")
        g2 = feats[two[0]]
        mid = 0.5 * (f.center + g2.center)
        mid = f.center + ((mid - f.center) @ f.axis) * f.axis
        return DatumFeature(name, "midplane", mid, f.axis, S.X[_on(ctx, one)],
                            points2=S.X[_on(ctx, two)])
    X = S.X[m]
    q = X - f.center
    radial = q - np.outer(q @ f.axis, f.axis)
    hole = float(np.sum(S.normals[m] * radial)) < 0 if len(X) else True
    X, _ = _cylinder_points(X, f)
    return DatumFeature(name, "axis", f.center, f.axis, X, hole=hole,
                        arc=_faces_arc(ctx.prep.model, fidx, f), radius=0.5 * f.diameter)


def _faces_arc(model, fidx, f) -> float:
    """Degrees about the cylinder feature ``f``'s axis that its CAD faces ``fidx`` cover."""
    from .features import _face_grid

    G = np.concatenate([_face_grid(model.faces[i])[0] for i in fidx])
    return angular_coverage(G, f.center, f.axis)


def datum_features(names, ctx: EvalContext) -> list:
    """The datum features (:class:`.drf.DatumFeature`) of the datum letters ``names``, with
    their scan points (cached per evaluation)."""
    key = ("drf_features", tuple(names))
    if key not in ctx.cache:
        ctx.cache[key] = [_datum_feature(n, ctx.plan.datums[n], ctx) for n in names]
    return ctx.cache[key]


def drf_of(names, ctx: EvalContext):
    """The fitted DRF of the datum letters ``names`` (cached per evaluation)."""
    key = ("drf", tuple(names))
    if key not in ctx.cache:
        ctx.cache[key] = fit_drf(datum_features(names, ctx), size=float(ctx.prep.model.size))
    return ctx.cache[key]


def _frame_points(c, ctx, fidx):
    """(points of the faces in the characteristic's frame, mask, drf or None)."""
    m = _on(ctx, fidx)
    X = ctx.S.X[m]
    names = getattr(c, "datums", None)
    if not names:
        return X, m, None
    drf = drf_of(names, ctx)
    return drf.apply(X), m, drf


def _result(c, ctx, value, U, details, drf=None, lower=0.0, upper=None, nominal=0.0):
    upper = float(c.tol) if upper is None else upper
    if drf is not None:
        details["drf"] = drf.to_dict()
    return CharacteristicResult(c.name, c.type, nominal, value, value - nominal, lower, upper,
                                U, zone_decide(c.type, value, lower, upper, U), details)


def _faces(c, ctx):
    return face_indices(ctx.prep.model, c.faces).tolist()


# ------------------------------------------------------------------------------ profile
def eval_surface_profile(c, ctx: EvalContext):
    """surface_profile: in the plan's alignment, or in its own DRF when it names ``datums``."""
    from .evaluate import eval_profile

    if not getattr(c, "datums", None):
        return eval_profile(c, ctx)
    fidx = face_indices(ctx.prep.model, c.faces)
    fl = None if fidx is None else fidx.tolist()
    X, m, drf = _frame_points(c, ctx, fl)
    if X.shape[0] == 0:
        return _not_measured(c, "no scan points on the profile's faces")
    cl = ctx.prep.closest(X, exact=True)
    d = np.asarray(cl.distances, float)
    shift = comp = None
    if getattr(c, "composite", None) == "lower":   # the zone framework at its best place
        from .composite import best_profile_fit, lower_rotations

        def devs(Y):
            g = ctx.prep.closest(Y, exact=True)
            return np.asarray(g.distances, float), np.asarray(g.normals, float)

        fit = best_profile_fit(X, devs, lower_rotations(drf))
        d = np.asarray(fit.pop("d"), float)
        comp = {"segment": "lower", **fit, "located_value": 2.0 * fit["located"]}
    elif getattr(c, "datum_modifiers", None):     # MMB/LMB: the best pose within the shift
        from .datum_shift import profile_with_shift

        d, shift = profile_with_shift(c, ctx, X, drf, d, np.asarray(cl.normals, float))
    ok = np.isfinite(d)
    # the datums' noise moves the points along their CAD normals; a composite's lower
    # segment floats (only the frame's turn counts)
    Ud = datum_u(drf, ctx, X[ok], np.asarray(cl.normals, float)[ok][:, None],
                 floating=comp is not None)
    d = d[ok]
    i = int(np.argmax(np.abs(d)))
    value = 2.0 * float(abs(d[i]))
    zq = extreme_quantile(d.size, ctx.k)
    U = float(np.hypot(2.0 * zq * ctx.S.noise, Ud))
    lo, hi = (0.0, float(c.tol)) if c.tol is not None else (0.0, float(c.upper - c.lower))
    return _result(c, ctx, value, U, {"n": int(d.size), "min": float(d.min()),
                                      "max": float(d.max()), "noise": ctx.S.noise,
                                      "extreme_quantile": zq, "faces": fl or "all",
                                      "u_datums": Ud, "excluded": ctx.S.excluded(fl),
                                      **({"datum_shift": shift} if shift else {}),
                                      **({"composite": comp} if comp else {})},
                   drf, 0.0, hi)


# ------------------------------------------------------------------------------ orientation
def _axis_ends(X, feat, hole: bool):
    """(end points (2, 3) of the mating cylinder's axis over the points' extent, mating
    diameter, largest radial extent about that axis x 2, axis, how the axis was fitted).

    A feature shorter than its diameter, or with fewer than 60 points, does not fix the tilt
    of an extreme fit (a few points at each end decide it): its axis keeps the CAD direction
    and the mating circle of the points projected along it is taken (the datum axis fit of
    :mod:`.drf` with a fixed direction)."""
    _coverage_check(X, feat)
    kind = "inscribed" if hole else "circumscribed"
    h0 = (X - feat.center) @ feat.axis
    if np.ptp(h0) < float(feat.diameter or 0.0) or X.shape[0] < 60:
        B = tangent_basis(feat.axis)
        _, c2, (lo, hi) = circles_zone((X - feat.center) @ B.T, np.zeros(2), kind)
        p, a = feat.center + c2 @ B, np.asarray(feat.axis, float)
        how = f"{kind} circle, CAD direction (short feature or few points)"
    else:
        _, p, a, (lo, hi) = cylinders_zone(X, feat.center, feat.axis, kind)
        a = a if a @ feat.axis > 0 else -a
        how = f"{kind} cylinder"
    h = (X - p) @ a
    ends = np.stack([p + h.min() * a, p + h.max() * a])
    mating, least = (2 * lo, 2 * hi) if hole else (2 * hi, 2 * lo)
    return ends, mating, least, a, how


def _lsq_axis_ends(X, feat, rim):
    """(end points (2, 3), axis, how) of the least-squares (Tukey) cylinder's axis between
    the planes normal to the CAD axis that bound the feature's faces (their edges ``rim``):
    the axis of a feature too short for a mating fit's tilt, to which the zone applies end to
    end."""
    from ..fitting import fit_cylinder

    cy = fit_cylinder(X, loss="tukey", axis=feat.axis)
    n = np.asarray(feat.axis, float)
    a = np.asarray(cy.axis, float)
    a = a if a @ n > 0 else -a
    p = np.asarray(cy.point, float)
    h = (np.asarray(rim, float) - p) @ n          # the feature's extent along the CAD axis
    ends = np.stack([p + (hk / (a @ n)) * a for hk in (h.min(), h.max())])
    return (ends, a, "least-squares cylinder over the feature's length (a short feature: a "
                     "mating fit does not fix its tilt)")


def _tilted_axis_ends(ctx, fidx, X, feat, ends, a, how):
    """``(ends, a, how)`` of :func:`_axis_ends` where its axis may tilt; where a short
    feature's mating fit kept the CAD direction (which does not see a tilt), the least-squares
    cylinder's axis over the faces' length (:func:`_lsq_axis_ends`), defined by all the
    points: what a zone that reads the axis' tilt (an orientation, a projected zone, a
    composite's lower segment) needs."""
    if "CAD direction" in how:
        return _lsq_axis_ends(X, feat, _faces_rim(ctx, fidx))
    return ends, a, how


def _cylinder_points(X, feat):
    """The points of a cylinder feature less the gross outliers of a robust fit: a residual
    from the Tukey least-squares cylinder (:func:`shapeverify.fitting.fit_cylinder`) more than
    5 robust sigmas (1.4826 MAD) from the median.  The extreme fits (mating cylinders, minimum
    zones) rest on single points; one stray point must not set them.  Returns (X, keep mask)."""
    from ..fitting import fit_cylinder

    if X.shape[0] < 8:
        return X, np.ones(X.shape[0], bool)
    cy = fit_cylinder(X, loss="tukey", axis=feat.axis)
    r = np.asarray(cy.residuals, float)
    med = float(np.median(r))
    s = 1.4826 * float(np.median(np.abs(r - med)))
    keep = np.abs(r - med) <= 5.0 * max(s, 1e-9)
    return X[keep], keep


def _coverage_check(X, feat):
    """A mating cylinder is defined by points all around: refuse (ValueError; the
    characteristic is then not measured) below :data:`.gdt_zones.MIN_COVERAGE` degrees."""
    cover = angular_coverage(X, feat.center, feat.axis)
    if cover < MIN_COVERAGE:
        # rounded down: 239.6 read "covers 240 degrees ... needs 240"
        raise ValueError(f"the scan covers {np.floor(10 * cover) / 10:.1f} degrees of the "
                         f"circumference of the cylinder (a mating cylinder needs "
                         f"{MIN_COVERAGE:.0f}: scan it from more sides)")


def _least_material(X, feat, hole: bool) -> float:
    """The least material size: a hole's smallest circumscribed, a boss's largest inscribed
    cylinder diameter."""
    kind = "circumscribed" if hole else "inscribed"
    return 2.0 * cylinders_zone(X, feat.center, feat.axis, kind)[0]


def _bonus(c, hole: bool, mating: float, least: float, cad_diameter: float, size=None):
    """(bonus, note) of a material modifier (module docstring); (0, None) without one.
    ``size``: the feature's own size limits (default ``c.size``)."""
    if getattr(c, "material", None) is None:
        return 0.0, None
    size = c.size if size is None else size
    nom = float(size.nominal) if size.nominal is not None else float(cad_diameter)
    mmc = nom + (size.lower if hole else size.upper)
    lmc = nom + (size.upper if hole else size.lower)
    if c.material == "M":
        bonus = (mating - mmc) if hole else (mmc - mating)
    else:
        bonus = (lmc - least) if hole else (least - lmc)
    if bonus < 0:
        size = mating if c.material == "M" else least
        return 0.0, (f"the {'mating' if c.material == 'M' else 'least material'} size "
                     f"{size:.4f} is outside the size limits: no bonus")
    return float(bonus), None


def _is_hole(X, N, feat) -> bool:
    q = X - feat.center
    radial = q - np.outer(q @ feat.axis, feat.axis)
    return float(np.sum(N * radial)) < 0


def eval_orientation(c, ctx: EvalContext):
    """parallelism, perpendicularity, angularity (module docstring)."""
    fidx = _faces(c, ctx)
    feats = ctx.feats
    kinds = {feats[i].kind for i in fidx}
    X, m, drf = _frame_points(c, ctx, fidx)
    f = feats[fidx[0]]
    zq = extreme_quantile(max(X.shape[0], 2), ctx.k)
    if kinds == {"plane"} and c.zone == "planes":
        if X.shape[0] < 3:
            return _not_measured(c, f"fewer than 3 scan points on faces {fidx}")
        n0 = f.axis
        turns = [np.cross(w, n0) for w in drf.free_rotations()]
        turns = [t for t in turns if np.linalg.norm(t) > 1e-9]
        Xz = X
        if c.tangent_plane:   # the contacting plane over the face, not the points
            _, nt, (_, hi) = planes_zone(X, n0, list(tangent_basis(n0)))
            Xz = X + np.outer(hi - X @ nt, nt)
        width, n, _ = planes_zone(Xz, n0, turns[:2])
        Ud = datum_u(drf, ctx, X, n0[None], floating=True)
        noise = {}
        if c.tangent_plane:
            U = float(np.hypot(2.0 * zq * ctx.S.noise, Ud))
        else:       # the extremes' expected noise taken off, its spread in U (.zone_noise)
            width, u_noise, noise = corrected_width(width, Xz, n, ctx.S.noise, ctx.k)
            U = float(np.hypot(u_noise, Ud))
        ang = float(np.degrees(np.arccos(np.clip(abs(n0 @ drf.datums[0].direction), 0, 1))))
        return _result(c, ctx, width, U, {"faces": fidx, "n": int(X.shape[0]),
                                          "normal": n.tolist(), "turns": len(turns),
                                          "angle_to_primary_deg": ang,
                                          "definition": "minimum zone, orientation fixed by "
                                                        "the DRF" + ("" if c.tangent_plane else
                                                                     ", less the noise's "
                                                                     "expected part"),
                                          "noise": ctx.S.noise, **noise,
                                          "tangent_plane": bool(c.tangent_plane),
                                          "u_datums": Ud,
                                          "excluded": ctx.S.excluded(fidx)}, drf)
    if kinds == {"plane"} and c.zone == "median_plane":
        return _median_plane_orientation(c, ctx, fidx, drf)
    if kinds == {"cylinder"} and c.zone == "diameter":
        if X.shape[0] < 5:
            return _not_measured(c, f"fewer than 5 scan points on faces {fidx}")
        hole = _is_hole(X, ctx.S.normals[m], f)
        X, _ = _cylinder_points(X, f)
        ends, mating, _, a, how = _axis_ends(X, f, hole)
        # (a short hole's orientation would read 0 by construction: NIST CTC 03's GT11 on a
        # hole through a 1.9 mm sheet)
        ends, a, how = _tilted_axis_ends(ctx, fidx, X, f, ends, a, how)
        ext = float(np.linalg.norm(ends[1] - ends[0]))
        u_axis, proj = 2.0 * zq * ctx.S.noise, None
        if getattr(c, "projected", None) is not None:
            # Ⓟ: the fitted axis between the mouth and projected mm beyond; its tilt (what the
            # ends across the axis measure) is known to u_axis / ext, read over the length
            try:
                ends, how, mouth = _projected_ends(c, ctx, fidx, f, X, ends, a, how)
            except ValueError as exc:
                return _not_measured(c, f"faces {fidx}: {exc}")
            u_axis *= float(c.projected) / max(ext, 1e-9)
            proj = {"length": float(c.projected), "mouth": mouth}
        B = tangent_basis(f.axis)
        e2 = (ends[1] - ends[0]) @ B.T
        value = float(np.linalg.norm(e2))
        Ud = datum_u(drf, ctx, ends, B, floating=True)
        U = float(np.hypot(u_axis, Ud))
        least = _least_material(X, f, hole) if c.material == "L" else float("nan")
        bonus, note = _bonus(c, hole, mating, least, f.diameter)
        return _result(c, ctx, value, U, {"faces": fidx, "n": int(X.shape[0]),
                                          "axis": a.tolist(), "ends": ends.tolist(),
                                          "hole": hole, "mating_diameter": mating,
                                          "axis_fit": how, "bonus": bonus, "note": note,
                                          "noise": ctx.S.noise, "projected": proj,
                                          "u_datums": Ud, "excluded": ctx.S.excluded(fidx)}, drf,
                       0.0, float(c.tol) + bonus)
    raise ValueError(f"{c.name}: {c.type} of faces {fidx} ({sorted(kinds)}) with a {c.zone} "
                     "zone: planes need zone: planes, cylinders zone: diameter")


def _median_plane_orientation(c, ctx: EvalContext, fidx, drf):
    """An orientation zone (two parallel planes, the DRF fixing their orientation as for a
    plane) of a width's derived median plane (:mod:`.median_plane`): the sides are the faces
    whose outward CAD normal points along the first face's and against it."""
    from .median_plane import median_points

    feats = ctx.feats
    f = feats[fidx[0]]
    n0 = np.asarray(f.axis, float)
    one = [i for i in fidx if feats[i].axis @ n0 > 0]
    two = [i for i in fidx if feats[i].axis @ n0 < 0]
    if not one or not two:
        raise ValueError(f"{c.name}: a median plane needs planar faces on both sides of a "
                         f"width; faces {fidx} all face one way")
    X1 = drf.apply(ctx.S.X[_on(ctx, one)])
    X2 = drf.apply(ctx.S.X[_on(ctx, two)])
    if X1.shape[0] < 3 or X2.shape[0] < 3:
        return _not_measured(c, f"fewer than 3 scan points on a side of the width {fidx}")
    M = median_points(X1, X2, n0)
    turns = [np.cross(w, n0) for w in drf.free_rotations()]
    turns = [t for t in turns if np.linalg.norm(t) > 1e-9]
    width, n, _ = planes_zone(M, n0, turns[:2])
    Ud = datum_u(drf, ctx, M, n0[None], floating=True)
    # a median point's height is the mean of a scan point's and the other side's interpolated
    # one: its noise is at most the scan's (sigma sqrt(1/4 + 1/4) when the interpolation
    # carries a point's full noise); the zone's own noise (from the local fits' residuals,
    # .zone_noise) sets the expected part taken off the width, the scan's sigma when too few
    width, u_noise, noise = corrected_width(width, M, n, ctx.S.noise, ctx.k)
    U = float(np.hypot(u_noise, Ud))
    ang = float(np.degrees(np.arccos(np.clip(abs(n0 @ drf.datums[0].direction), 0, 1))))
    return _result(c, ctx, width, U, {"faces": fidx, "sides": [one, two], "u_datums": Ud,
                                      "n": int(M.shape[0]), "n_sides": [len(X1), len(X2)],
                                      "normal": n.tolist(), "turns": len(turns),
                                      "angle_to_primary_deg": ang,
                                      "definition": "minimum zone of the derived median "
                                                    "plane's points, orientation fixed by the "
                                                    "DRF, less the noise's expected part",
                                      "noise": ctx.S.noise, **noise,
                                      "excluded": ctx.S.excluded(fidx)}, drf)


# ------------------------------------------------------------------------------ position
def _feature_faces(ref, ctx) -> list:
    if isinstance(ref, (list, tuple)):
        return face_indices(ctx.prep.model, list(ref)).tolist()
    if str(ref).startswith("hole:"):
        from .features import find_feature

        h = find_feature(ctx.feats, ref, kind="hole")
        if not h.walls:
            raise ValueError(f"{ref}: the hole has no cylindrical wall faces in the model; "
                             "position needs the wall (use type: hole for a hole without one)")
        return list(h.walls)
    return face_indices(ctx.prep.model, [ref]).tolist()


def eval_position(c, ctx: EvalContext):
    """position of one or a pattern of axes, with MMC/LMC bonus (module docstring)."""
    rows = []
    drf = drf_of(c.datums, ctx) if c.datums else None
    zq = None
    sizes = getattr(c, "feature_sizes", None) or [None] * len(c.features)
    for ref, own_size in zip(c.features, sizes):
        fidx = _feature_faces(ref, ctx)
        f = ctx.feats[fidx[0]]
        if f.kind != "cylinder":
            raise ValueError(f"{c.name}: feature {ref} is a {f.kind} face; position takes "
                             "cylinder faces (holes, bosses)")
        m = _on(ctx, fidx)
        X = ctx.S.X[m] if drf is None else drf.apply(ctx.S.X[m])
        if X.shape[0] < 8:
            return _not_measured(c, f"only {X.shape[0]} scan points on {ref}")
        hole = _is_hole(X, ctx.S.normals[m], f)
        n_all = X.shape[0]
        X, _ = _cylinder_points(X, f)
        ends, mating, _, a, how = _axis_ends(X, f, hole)
        if getattr(c, "composite", None) == "lower":
            # a lower segment's framework floats: what it reads of one feature is the axis'
            # tilt, which a short feature's CAD direction would make 0 by construction (NIST
            # FTC 08 GT19/21/24/26: 2e-8)
            ends, a, how = _tilted_axis_ends(ctx, fidx, X, f, ends, a, how)
        least = _least_material(X, f, hole) if c.material == "L" else float("nan")
        zq = extreme_quantile(X.shape[0], ctx.k)
        ext = float(np.linalg.norm(ends[1] - ends[0]))
        # the axis: a mating circle's centre (CAD direction) moves with the difference of its
        # extreme points, not by their common shift (:func:`mating_centre_u`); a free mating
        # cylinder's ends also take its tilt: 2 z_n sigma
        u_axis = (mating_centre_u(X.shape[0], ctx.S.noise, ctx.k) if "circle" in how
                  else 2.0 * zq * ctx.S.noise)
        proj = getattr(c, "projected", None)
        if proj is not None:
            try:
                ends, how, mouth = _projected_ends(c, ctx, fidx, f, X, ends, a, how)
            except ValueError as exc:
                return _not_measured(c, f"{ref}: {exc}")
            # the ends extrapolated up to L past the fitted segment: an end's error grows as
            # (1 + 2 L / extent) times (the far one); the datums' at the projected ends
            u_axis *= 1.0 + 2.0 * float(proj) / max(ext, 1e-9)
        q = ends - f.center
        off = q - np.outer(q @ f.axis, f.axis)
        zone = {}
        if c.zone == "planes":     # two parallel planes normal to u (across the axis)
            u = _across(c.direction, f.axis)
            value = 2.0 * float(np.abs(off @ u).max())
            zone = {"zone_normal": u.tolist()}
            dirs = u[None]
        else:
            value = 2.0 * float(np.linalg.norm(off, axis=1).max())
            dirs = tangent_basis(f.axis)
        bonus, note = _bonus(c, hole, mating, least, f.diameter, own_size)
        # the datums' noise (:mod:`.datum_noise`): the frame moves the ends across the axis;
        # a composite's lower segment floats (only the frame's turn counts)
        u_dat = datum_u(drf, ctx, ends, dirs)
        u_turn = (datum_u(drf, ctx, ends, dirs, floating=True)
                  if getattr(c, "composite", None) == "lower" else u_dat)
        U = float(np.hypot(u_axis, u_dat))
        tol = float(c.tol) + bonus
        cap = getattr(c, "max_tol", None)
        if cap is not None and tol > float(cap):   # ASME Y14.5-2009 §7.3.4: "MAX"
            tol = float(cap)
        rows.append({"centre": f.center.tolist(), "axis": f.axis.tolist(),
                     "u_axis": float(u_axis), "u_turn": float(u_turn), "u_datums": u_dat,
                     "feature": ref if isinstance(ref, str) else list(ref), "faces": fidx,
                     "hole": hole, "value": value, "bonus": bonus, "tolerance": tol,
                     "n": int(X.shape[0]), "outliers": int(n_all - X.shape[0]),
                     "axis_fit": how,
                     "mating_diameter": mating, "least_material_diameter": least,
                     "nominal_diameter": float(f.diameter), "U": U,
                     "verdict": decide(value, None, tol, U), "ends": ends.tolist(),
                     **zone,
                     "note": note, "_axis": (f.center, f.axis)})
        if proj is not None:
            rows[-1]["projected"] = {"length": float(proj), "mouth": mouth}
    shift = comp = None
    if getattr(c, "datum_modifiers", None):       # MMB/LMB: the best pose within the shift
        shift = _position_shift(c, ctx, drf, rows)
    if getattr(c, "composite", None) == "lower":  # the zone framework at its best place
        comp = _lower_position(c, ctx, rows, drf)
    for r in rows:
        for key in ("_axis", "u_axis", "u_turn"):
            r.pop(key, None)
    worst = min(rows, key=lambda r: (r["tolerance"] - r["value"]) - r["U"])
    details = {"features": rows, "material": c.material, "n_features": len(rows),
               **({"datum_shift": shift} if shift else {}),
               **({"composite": comp} if comp else {})}
    res = _result(c, ctx, worst["value"], worst["U"], details, drf, 0.0, worst["tolerance"])
    verdicts = [r["verdict"] for r in rows]
    from .zones import worst_verdict

    if worst_verdict(verdicts) != res.verdict:
        import dataclasses

        res = dataclasses.replace(res, verdict=worst_verdict(verdicts))
    return res


def _across(direction, axis) -> np.ndarray:
    """The unit normal of a planes zone about an axis: ``direction`` less its part along the
    axis; ValueError when it is (nearly) along the axis."""
    u = np.asarray(direction, float) / np.linalg.norm(direction)
    a = np.asarray(axis, float)
    if abs(float(u @ a)) > 1e-6:
        raise ValueError(f"the planes' normal {u.tolist()} is not across the axis "
                         f"{a.tolist()} (zone: planes bounds the axis across itself)")
    return u - (u @ a) * a


def _faces_rim(ctx, fidx) -> np.ndarray:
    """The CAD trim loops of faces ``fidx`` (3-D points about 0.2 mm apart), cached."""
    key = ("rim", tuple(int(f) for f in fidx))
    if key not in ctx.cache:
        ctx.cache[key] = np.concatenate([_rim(ctx.prep.model.faces[int(f)], 0.2)
                                         for f in fidx])
    return ctx.cache[key]


def _projection_direction(c, ctx, fidx, feat) -> np.ndarray:
    """The unit direction out of the hole's mouth, the side the projected zone goes:
    ``c.projected_direction``, else the axis of the ``hole:k`` whose walls are these faces
    (:mod:`.features`: a loop hole's axis points like its entry face's outward normal; a hole
    of wall faces only points out of the wall's end farther from the model's centre)."""
    d = getattr(c, "projected_direction", None)
    if d is None:
        holes = [h for h in (ctx.feats.values() if isinstance(ctx.feats, dict) else ctx.feats)
                 if h.kind == "hole" and set(fidx) & set(h.walls)]
        if not holes:
            raise ValueError("no hole of `info --features` has these walls: the side of the "
                             "projected zone is not known (give projected_direction)")
        if len({float(np.sign(np.asarray(h.axis, float) @ feat.axis)) for h in holes}) > 1:
            raise ValueError("a hole open at both ends: the side of the projected zone is not "
                             "known (give projected_direction)")
        d = holes[0].axis
    d = np.asarray(d, float)
    return d / np.linalg.norm(d)


def _projected_ends(c, ctx, fidx, feat, X, ends, a, how):
    """(the two points of the fitted axis extended out of the hole's mouth that bound the
    projected zone, how the axis was fitted, the mouth (3,) on the CAD axis): the fitted axis
    (a short feature's mating fit keeps the CAD direction, which does not see a tilt: its
    least-squares cylinder's axis is taken) crossing the planes normal to the CAD axis at the
    mouth (the faces' CAD end on the projection's side) and ``c.projected`` mm beyond."""
    d = _projection_direction(c, ctx, fidx, feat)
    n = np.asarray(feat.axis, float)
    n = n if n @ d > 0 else -n
    if abs(float(n @ d)) < 1.0 - 1e-6:
        raise ValueError(f"projected_direction {d.tolist()} is not along the hole's axis "
                         f"{n.tolist()}")
    rim = _faces_rim(ctx, fidx)
    ends, a, how = _tilted_axis_ends(ctx, fidx, X, feat, ends, a, how)
    a = np.asarray(a, float)
    a = a if a @ n > 0 else -a
    h0 = float(((rim - feat.center) @ n).max())
    p = np.asarray(ends[0], float)
    hp = float((p - feat.center) @ n)
    pts = np.stack([p + ((h - hp) / float(a @ n)) * a for h in (h0, h0 + float(c.projected))])
    mouth = (feat.center + h0 * n).tolist()
    return pts, how + f", extended {float(c.projected):g} mm out of the mouth", mouth


def _position_shift(c, ctx, drf, rows) -> dict:
    """Move the axes of ``rows`` (in place: ``value``, ``verdict``, ``ends``) to the best pose
    within the datum feature shift of ``c.datum_modifiers`` (:func:`.datum_shift.
    best_position_shift`, the moved axes then measured exactly: the motion applied to their
    ends); the pose found must lower the largest excess over the zones, else the rows stay.
    Returns the details."""
    from .datum_shift import Infeasible, best_position_shift, shift_limits
    from .drf import rigid_exp

    S, datums, det = shift_limits(c, ctx, drf)
    axes = [(np.asarray(r["ends"]), r["_axis"][0], r["_axis"][1], r["tolerance"]) for r in rows]
    before = max(r["value"] - r["tolerance"] for r in rows)
    try:
        lin, xi, _ = best_position_shift(axes, S, datums)
    except Infeasible as e:
        return {"datums": det, "applied": False, "reason": str(e), "max_excess_before": before}
    T = rigid_exp(xi)
    moved = []
    for (ends, c0, a, _), r in zip(axes, rows):
        e2 = ends @ T[:3, :3].T + T[:3, 3]
        q = e2 - c0
        off = q - np.outer(q @ a, a)
        moved.append((2.0 * float(np.linalg.norm(off, axis=1).max()), e2))
    after = max(v - r["tolerance"] for (v, _), r in zip(moved, rows))
    # excesses as diameters (value - tolerance), the LP's are radii
    out = {"datums": det, "motion": xi.tolist(), "linearised_max_excess": 2.0 * lin,
           "max_excess_before": before, "max_excess_after": after, "applied": bool(after < before)}
    if after < before:
        for (v, e2), r in zip(moved, rows):
            r["value_at_datum_pose"] = r["value"]
            r["value"], r["ends"] = v, e2.tolist()
            r["verdict"] = decide(v, None, r["tolerance"], r["U"])
    return out


def _lower_position(c, ctx, rows, drf) -> dict:
    """The lower segment of a composite position (:mod:`.composite`): the true positions at
    their best place; each row's value becomes twice its largest end distance from there (the
    located value is kept as ``located``); its uncertainty keeps the axis' and the datums'
    turn, not the datum planes' shift (the framework's location is free)."""
    from .composite import best_pattern_fit, lower_rotations

    tols = [r["tolerance"] for r in rows]
    # features of different zones (their own bonus at MMC/LMC): the framework's best place
    # is the one with the smallest largest excess over each feature's own zone
    fit = best_pattern_fit([np.asarray(r["ends"]) for r in rows],
                           [r["centre"] for r in rows], [r["axis"] for r in rows],
                           lower_rotations(drf),
                           radii=None if len(set(tols)) == 1 else [t / 2.0 for t in tols])
    for r, v in zip(rows, fit["per_feature"]):
        r["located"] = r["value"]
        r["value"] = float(v)
        r["U"] = float(np.hypot(r.pop("u_axis"), r.pop("u_turn")))
        r["verdict"] = decide(r["value"], None, r["tolerance"], r["U"])
    return {"segment": "lower", "value": fit["value"], "located": fit["located"],
            "rotation": fit["rotation"], "translation": fit["translation"],
            "pivot": fit["pivot"]}


def mating_centre_u(n: int, noise: float, k: float) -> float:
    """Expanded (k) uncertainty of a position value (twice the axis offset) whose axis is the
    centre of a mating circle of ``n`` points with noise ``noise``: the circle rests on the
    extreme points of each side, and its centre moves by the difference of two extremes, of
    standard deviation ``sqrt(2) (pi / sqrt(6)) sigma / sqrt(2 ln n)`` (the Gumbel spread of
    the largest of n normal deviates; a Monte Carlo of the inscribed circle gives 0.68, 0.51,
    0.41 sigma per component at n = 20, 56, 200 against 0.74, 0.64, 0.56 here); the value
    doubles it.  (The extremes' common shift, ``z_n sigma``, changes the mating size only.)"""
    return float(2.0 * k * _extremes_sd(noise, n))


def _extremes_sd(noise: float, n: int) -> float:
    """``sqrt(2) (pi / sqrt(6)) sigma / sqrt(2 ln n)``: the standard deviation of the
    difference of the largest of ``n`` normal deviates of ``noise`` on two sides (Gumbel)."""
    return np.sqrt(2.0) * (np.pi / np.sqrt(6.0)) * noise / np.sqrt(2.0 * np.log(max(int(n), 3)))


# ------------------------------------------------------------------------------ runout
def runout_datum_u(n: int, noise: float, k: float, feet, normals, mid, axis,
                   length: float) -> float:
    """Expanded (k) change of a runout (a range of normal deviations) from the noise of its
    datum axis, a mating cylinder of ``n`` points over ``length`` mm (0: a plane before it
    sets its direction, only its offset counts).  The axis moves by an offset ``e`` (its
    reading twice, ``mating_centre_u(n)``) and turns by ``w`` about its mid-point ``mid``: the
    line through the mating centres of its two halves (``n / 2`` points each, a quarter of
    the length from the middle) moves at its ends by their difference, ``sqrt 2`` times a
    half's offset (read twice: ``sqrt(2) mating_centre_u(n / 2)``; a Monte Carlo of
    ``cylinders_zone``, 500-8000 points, length / radius 0.7-6, gave 0.8-0.9 x that).  A
    surface point ``x`` with normal ``n`` reads ``n.e + w.((x - mid) x n)``: on a cylinder
    coaxial with the datum the offset and the turn times the axial distance, on a face square
    to it the turn times the radius."""
    u0 = mating_centre_u(n, noise, k)
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    N = np.asarray(normals, float)
    off = np.linalg.norm(N - np.outer(N @ a, a), axis=1)       # |n across the axis|
    if length <= 0:
        return float(u0 * off.max(initial=0.0))
    m = np.cross(np.asarray(feet, float) - np.asarray(mid, float), N)
    lever = np.linalg.norm(m - np.outer(m @ a, a), axis=1)     # the turn's arm (w across a)
    u_turn = np.sqrt(2.0) * mating_centre_u(max(n // 2, 3), noise, k)   # at the ends
    return float(np.sqrt((u0 * off) ** 2 + (u_turn * 2.0 * lever / length) ** 2).max(
        initial=0.0))


def eval_runout(c, ctx: EvalContext):
    """circular_runout / total_runout about the DRF's datum axis (a hole's or boss's, or the
    common axis of coaxial ones, ``A-B``), as a dial indicator reads it normal to the surface:
    the range of the points' signed distances from the CAD surface (in the DRF frame), over
    each circle (points whose CAD feet share a cell of the meridian plane, a tenth of the
    face's extent) -- its maximum -- and over all points.  On a cylinder that is the radial
    range, on a face square to the axis the axial range; every face must be a surface of
    revolution about the datum axis.  Each range is taken less its noise's expected part
    (:mod:`.zone_noise` over ``(R theta, h)`` on cylinders and cones, the plane's coordinates on
    faces square to the axis; both kinds at once: the old ``2 z_n sigma`` in U, no correction);
    ``zone_of_points``: the range of the points."""
    fidx = _faces(c, ctx)
    X, m, drf = _frame_points(c, ctx, fidx)
    nom = None                          # the datum axis's nominal (the DRF puts it there)
    for i, d in enumerate(drf.datums):
        if d.kind in ("axis", "pattern"):
            f = _datum_feature(d.name, ctx.plan.datums[d.name], ctx)
            if d.kind == "axis" or _coaxial(f):
                nom = f
                # a plane before it (A|B: a face, then a hole) sets the axis's direction
                tilt_fixed = any(e.kind in ("plane", "midplane") for e in drf.datums[:i])
                break
    if nom is None:
        raise ValueError(f"{c.name}: runout needs an axis datum (a hole or boss, or coaxial "
                         f"ones); {'|'.join(c.datums)} has none")
    p0 = np.asarray(nom.point, float)
    a0 = np.asarray(nom.direction, float) / np.linalg.norm(nom.direction)
    for i in fidx:
        _check_revolution(c, ctx.feats[i], p0, a0, float(ctx.prep.model.size))
    if X.shape[0] < 5:
        return _not_measured(c, f"only {X.shape[0]} scan points on faces {fidx}")
    if ctx.feats[fidx[0]].kind == "cylinder":
        X, _ = _cylinder_points(X, ctx.feats[fidx[0]])
    foot = ctx.prep.closest(X, exact=True)
    d = np.asarray(foot.distances, float)
    q = np.asarray(foot.points, float) - p0
    h = q @ a0
    r = np.linalg.norm(q - np.outer(h, a0), axis=1)
    total = float(d.max() - d.min())
    w = max(float(np.ptp(h)), float(np.ptp(r))) / 10.0 + 1e-9
    cell = np.floor(h / w).astype(np.int64) * 1_000_003 + np.floor(r / w).astype(np.int64)
    # the noise's expected part of each range taken off (.zone_noise) over the surface's
    # coordinates: (R theta, h) on cylinders and cones, the plane's own on faces square to
    # the axis; faces of both kinds together keep the old rule (2 z_n sigma, no correction)
    kinds = {ctx.feats[i].kind for i in fidx}
    T = per = None
    if kinds <= {"cylinder", "cone"}:
        T, _, per = cylinder_coords(np.asarray(foot.points, float), p0, a0)
    elif kinds == {"plane"}:
        T = (np.asarray(foot.points, float) - p0) @ tangent_basis(a0).T

    def zone(sel):
        dk = d[sel]
        if T is None:
            raw = float(dk.max() - dk.min())
            return raw, 2.0 * extreme_quantile(d.size, ctx.k) * ctx.S.noise, {}
        return corrected_spread(float(dk.max() - dk.min()), T[sel], dk, ctx.S.noise, ctx.k,
                                per)

    if c.type == "circular_runout":
        rows, circ = [], 0.0
        for key in np.unique(cell):
            sel = cell == key
            if np.count_nonzero(sel) >= 2:
                rows.append(zone(sel))
                circ = max(circ, float(np.ptp(d[sel])))
        if not rows:        # every circle a single point: no range (as before)
            rows.append((0.0, 2.0 * extreme_quantile(d.size, ctx.k) * ctx.S.noise, {}))
        j = int(np.argmax([z[0] for z in rows]))
        value, u_noise, noise = rows[j]
        noise = {**noise, "zone_of_points": circ,
                 "circles_corrected": [z[0] for z in rows]}
    else:
        circ = 0.0
        for key in np.unique(cell):
            dk = d[cell == key]
            if dk.size >= 2:
                circ = max(circ, float(dk.max() - dk.min()))
        value, u_noise, noise = zone(np.ones(d.size, bool))
        noise = {**noise, "zone_of_points": total}
    # the datum axis's own noise: a mating cylinder rests on extreme points (the Gumbel
    # spread of :func:`_extremes_sd`); it shifts and -- when no plane before it sets its direction --
    # tilts the axis, which the indicator reads at each point along the surface normal
    hd = (np.asarray(nom.points, float) - p0) @ a0
    Ud = 0.0
    if hd.size > 2:
        mid = p0 + 0.5 * (float(hd.max()) + float(hd.min())) * a0
        Ud = runout_datum_u(hd.size, ctx.S.noise, ctx.k, np.asarray(foot.points, float),
                            np.asarray(foot.normals, float), mid, a0,
                            0.0 if tilt_fixed else float(np.ptp(hd)))
    return _result(c, ctx, value, float(np.hypot(u_noise, Ud)),
                   {"faces": fidx, "n": int(X.shape[0]), "circular": circ, "total": total,
                    "axis_point": p0.tolist(), "axis": a0.tolist(),
                    "definition": "range of the normal deviations from the CAD surface of "
                                  "revolution, per circle and overall" +
                                  (", less the noise's expected part" if noise.get("rule")
                                   else ""),
                    "u_datum_axis": Ud, **noise,
                    "noise": ctx.S.noise, "excluded": ctx.S.excluded(fidx)}, drf)


def _coaxial(d) -> bool:
    """A pattern datum whose cylinders share one axis (a common datum axis A-B)."""
    groups = getattr(d, "groups", None) or ()
    if not groups:
        return False
    c0, a0 = np.asarray(groups[0][0], float), np.asarray(groups[0][1], float)
    for c, a, *_ in groups[1:]:
        q = np.asarray(c, float) - c0
        if np.linalg.norm(np.cross(a, a0)) > 1e-6 or np.linalg.norm(q - (q @ a0) * a0) > 1e-4:
            return False
    return True


def _check_revolution(c, f, p0, a0, size: float) -> None:
    """A runout's face is a surface of revolution about the datum axis (p0, a0)."""
    tol = 1e-6 * max(size, 1.0) + 1e-6
    if f.kind == "plane":
        ok = abs(abs(f.axis @ a0) - 1.0) < 1e-6
    elif f.kind in ("cylinder", "cone"):
        q = f.center - p0
        ok = (np.linalg.norm(np.cross(f.axis, a0)) < 1e-6
              and np.linalg.norm(q - (q @ a0) * a0) < tol)
    else:
        ok = True          # a torus, sphere or free-form face: taken as the drawing says
    if not ok:
        raise ValueError(f"{c.name}: face {f.id} ({f.kind}) is not a surface of revolution "
                         "about the datum axis; runout measures such surfaces")


# ------------------------------------------------------------------------------ form
def _sections(h, n: int = 10):
    edges = np.linspace(h.min(), h.max() + 1e-12, n + 1)
    return [np.flatnonzero((h >= edges[i]) & (h < edges[i + 1])) for i in range(n)]


def circularity_zone(X, center, axis, noise: float, k: float = 2.0):
    """Circularity of cylinder points ``X`` (CAD axis through ``center`` along ``axis``): the
    largest over the :func:`_sections` (6 points or more) of the concentric circles' zone,
    each less its noise's expected part (:mod:`.zone_noise`: the radial distances from the
    section's zone centre over ``(R theta, h)``, theta wrapping).  ``(value, u_noise,
    details)``, ``None`` with no section; ``details['sections']``: the zones of the points,
    ``zone_of_points`` their largest."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    B = tangent_basis(axis)
    h = (X - center) @ axis
    raw, rows = [], []
    for idx in _sections(h):
        if idx.size >= 6:
            w, c2, _ = circles_zone((X[idx] - center) @ B.T, np.zeros(2))
            T, rho, per = cylinder_coords(X[idx], center + c2 @ B, axis)
            raw.append(float(w))
            rows.append(corrected_spread(w, T, rho, noise, k, per))
    if not rows:
        return None
    j = int(np.argmax([r[0] for r in rows]))
    value, u, det = rows[j]
    return value, u, {**det, "zone_of_points": float(max(raw)), "sections": raw,
                      "sections_corrected": [r[0] for r in rows], "section": j}


def eval_circularity(c, ctx: EvalContext):
    fidx = _faces(c, ctx)
    X, _, _ = _frame_points(c, ctx, fidx)
    f = ctx.feats[fidx[0]]
    if f.kind != "cylinder":
        raise ValueError(f"{c.name}: circularity of a {f.kind} face (give cylinder faces)")
    X, _ = _cylinder_points(X, f)
    z = circularity_zone(X, f.center, f.axis, ctx.S.noise, ctx.k)
    if z is None:
        return _not_measured(c, "no cross-section with 6 scan points")
    value, U, det = z
    return _result(c, ctx, value, U,
                   {"faces": fidx, "n": int(X.shape[0]), "noise": ctx.S.noise,
                    "definition": "largest cross-section's concentric circles zone, less the "
                                  "noise's expected part", **det})


def cylindricity_zone(X, center, axis, noise: float, k: float = 2.0):
    """Cylindricity of points ``X`` (start: the CAD axis): the coaxial cylinders' zone less
    its noise's expected part (:mod:`.zone_noise`, the radial distances from the zone's axis
    over ``(R theta, h)``).  ``(value, u_noise, details)``."""
    w, p, a, _ = cylinders_zone(X, center, axis, "zone")
    T, rho, per = cylinder_coords(X, p, a)
    value, u, det = corrected_spread(w, T, rho, noise, k, per)
    return value, u, {**det, "axis": a.tolist(), "point": p.tolist()}


def eval_cylindricity(c, ctx: EvalContext):
    fidx = _faces(c, ctx)
    X, _, _ = _frame_points(c, ctx, fidx)
    f = ctx.feats[fidx[0]]
    if f.kind != "cylinder" or X.shape[0] < 8:
        return _not_measured(c, f"cylindricity needs cylinder faces with 8 points "
                                f"({f.kind}, {X.shape[0]} points)")
    X, _ = _cylinder_points(X, f)
    value, U, det = cylindricity_zone(X, f.center, f.axis, ctx.S.noise, ctx.k)
    return _result(c, ctx, value, U,
                   {"faces": fidx, "n": int(X.shape[0]), "noise": ctx.S.noise,
                    "definition": "coaxial cylinders zone, less the noise's expected part",
                    **det})


def eval_straightness(c, ctx: EvalContext):
    fidx = _faces(c, ctx)
    X, _, _ = _frame_points(c, ctx, fidx)
    f = ctx.feats[fidx[0]]
    zq = extreme_quantile(max(X.shape[0], 2), ctx.k)
    if c.zone == "diameter":
        if f.kind != "cylinder":
            raise ValueError(f"{c.name}: straightness of an axis needs cylinder faces")
        B = tangent_basis(f.axis)
        h = (X - f.center) @ f.axis
        cen = []
        for idx in _sections(h):
            if idx.size >= 6:
                _, c2, _ = circles_zone((X[idx] - f.center) @ B.T, np.zeros(2))
                cen.append(f.center + c2 @ B + h[idx].mean() * f.axis)
        if len(cen) < 5:
            return _not_measured(c, "fewer than 5 cross-sections with 6 scan points")
        r = cylinders_zone(np.array(cen), f.center, f.axis, "circumscribed")[0]
        return _result(c, ctx, 2.0 * r, 2.0 * zq * ctx.S.noise,
                       {"faces": fidx, "centres": np.array(cen).tolist()})
    if getattr(c, "through", None) is not None:
        return _straightness_of_line(c, ctx, fidx)
    if f.kind != "plane":
        raise ValueError(f"{c.name}: straightness of line elements needs a planar face")
    n0 = f.axis
    B = tangent_basis(n0)
    if c.direction is not None:
        u = np.asarray(c.direction, float)
        u = u - (u @ n0) * n0
        u /= np.linalg.norm(u)
    else:
        _, _, vt = np.linalg.svd((X - X.mean(0)) @ B.T, full_matrices=False)
        u = vt[0] @ B
    v = np.cross(n0, u)
    vals, rows = [], []
    for idx in _sections(X @ v):
        if idx.size >= 3:
            w, nz, _ = planes_zone(X[idx], n0, [u])
            vals.append(float(w))
            # the line element's band of points, its noise's expected part taken off
            # (.zone_noise: over the face's coordinates, the band a tenth of it across)
            rows.append(corrected_width(w, X[idx], nz, ctx.S.noise, ctx.k))
    if not vals:
        return _not_measured(c, "no line element with 3 scan points")
    j = int(np.argmax([r[0] for r in rows]))
    value, U, noise = rows[j]
    return _result(c, ctx, value, U,
                   {"faces": fidx, "direction": u.tolist(), "lines": vals,
                    **noise, "zone_of_points": float(max(vals)),
                    "lines_corrected": [r[0] for r in rows], "line": j,
                    "noise": ctx.S.noise})


def line_element_zone(t, d) -> float:
    """Minimum zone (two parallel lines, their distance) of the 2D points ``(t_i, d_i)``: a
    line element's points along it (``t``) and across it (``d``)."""
    P = np.column_stack([np.asarray(t, float), np.zeros(len(t)), np.asarray(d, float)])
    return _two_lines_zone(P)[0]


def _two_lines_zone(P):
    """``(width, normal)`` of points ``(along, across, deviation)``: the planes zone turned
    about the across direction only, which is the zone of two lines in ``(along,
    deviation)`` (the across coordinate does not change it)."""
    width, n, _ = planes_zone(P, [0.0, 0.0, 1.0], [[1.0, 0.0, 0.0]])
    return float(width), n


def _straightness_of_line(c, ctx: EvalContext, fidx):
    """Straightness of the one line element of the faces through ``c.through`` along
    ``c.direction`` (``c.length`` long): the points whose CAD foot lies within a band of
    the section plane (holding the line and the face's normal at ``through``; half-width one
    scan spacing, at least 0.5 mm) and within the line's length; each point's signed
    deviation from the CAD (along the CAD normal, which is the section's across-line
    direction on a straight line element) against its place along the line; the minimum zone
    of two parallel lines of these (the pose's own tilt is a slope, which the zone takes out).
    The CAD line must be straight: points along it lie on the faces (1e-4 mm)."""
    S = ctx.S
    at = np.asarray(c.through, float)
    u = np.asarray(c.direction, float)
    u /= np.linalg.norm(u)
    L = float(c.length)
    line = at + np.outer(np.linspace(-0.5, 0.5, 9) * L, u)
    cl = ctx.prep.closest(line, exact=True)
    off = np.abs(np.asarray(cl.distances, float))
    if not np.all(off <= 1e-4) or not np.all(np.isin(cl.face, fidx)):
        raise ValueError(f"{c.name}: the line through {np.round(at, 4).tolist()} along "
                         f"{np.round(u, 6).tolist()} is not a straight line element of faces "
                         f"{fidx} (up to {float(off.max()):.3g} mm off)")
    n0 = np.asarray(cl.normals[4], float)
    u = u - (u @ n0) * n0
    u /= np.linalg.norm(u)
    s = np.cross(u, n0)
    sp = float(getattr(S.support, "spacing", 0.0) or 0.0)
    band = max(0.5, sp)
    m = S.on(fidx)
    q = S.feet - at
    sel = m & (np.abs(q @ s) <= band) & (np.abs(q @ u) <= 0.5 * L)
    t, d = q[sel] @ u, S.d[sel]
    if t.size < 3 or np.ptp(t) < 0.5 * L:
        return _not_measured(c, f"{t.size} scan points on the line element (at least 3 over "
                                "half its length)")
    # the band's points along the line (t) and across it in the face (q.s), their deviations
    # (d): the zone of two lines in (t, d) is the planes zone of these turned about the
    # across direction only; its noise's expected part is taken off (.zone_noise)
    P = np.column_stack([t, q[sel] @ s, d])
    width, nz = _two_lines_zone(P)
    value, U, noise = corrected_width(width, P, nz, ctx.S.noise, ctx.k)
    return _result(c, ctx, value, U,
                   {"faces": fidx, "n": int(t.size), "through": at.tolist(), **noise,
                    "direction": u.tolist(), "section_normal": s.tolist(), "band": band,
                    "length": L, "span": float(np.ptp(t)), "noise": ctx.S.noise,
                    "definition": "minimum zone of two parallel lines in the section plane "
                                  "(deviations from the straight CAD line element)"})


# ------------------------------------------------------------------------------ size
def eval_width(c, ctx: EvalContext):
    fidx = _faces(c, ctx)
    f1, f2 = ctx.feats[fidx[0]], ctx.feats[fidx[-1]]
    if len(fidx) != 2 or f1.kind != "plane" or f2.kind != "plane" or \
            abs(abs(f1.axis @ f2.axis) - 1) > 1e-6:
        raise ValueError(f"{c.name}: width needs two parallel planar faces, got {c.faces}")
    S = ctx.S
    P1, P2 = S.X[_on(ctx, [fidx[0]])], S.X[_on(ctx, [fidx[1]])]
    if len(P1) < 3 or len(P2) < 3:
        return _not_measured(c, "fewer than 3 scan points on a face of the width")
    nominal = float(abs((f2.center - f1.center) @ f1.axis))

    def lsq(P):
        cen = P.mean(0)
        n = np.linalg.svd(P - cen, full_matrices=False)[2][2]
        return cen, n

    c1, n1 = lsq(P1)
    c2, n2 = lsq(P2)
    value = 0.5 * (abs(float(np.mean((P2 - c1) @ n1))) + abs(float(np.mean((P1 - c2) @ n2))))
    u = ctx.S.noise * np.sqrt(1.0 / len(P1) + 1.0 / len(P2))
    U = ctx.k * float(u)
    dev = value - nominal
    return CharacteristicResult(c.name, c.type, nominal, value, dev, float(c.lower),
                                float(c.upper), U, decide(dev, c.lower, c.upper, U),
                                {"faces": fidx, "n": [len(P1), len(P2)],
                                 "definition": "mean distance between the least-squares "
                                               "planes"})
