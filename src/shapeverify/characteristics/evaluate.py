"""Evaluate an inspection plan: alignment, then every characteristic with its uncertainty.

Definitions (ISO 1101; lengths in mm, model frame after the plan's alignment)
------------------------------------------------------------------------------
The *evaluated points* of a face group are the scan points whose exact closest CAD point
(``prep.closest(x, exact=True)``) lies on a face of the group, not on the model's free boundary,
with ``|d| <=`` the evaluation distance (``d`` the signed distance along the outward CAD normal;
the evaluation distance from the caller, else the plan's ``evaluation_distance``, else the one
default :func:`shapeverify.inspection.default_evaluation_distance` of the plan's largest
tolerance, five times it at least: never a cut-off at or inside a limit).  The *kept points*
are the evaluated points less the measurement outliers of the inspection's own rule,
neighbourhood support (:mod:`.support`: a deviation its neighbours do not support, departing
from their median by more than the noise could make it), and less any points the caller
excludes.  Every characteristic reports in ``details['excluded']`` how many points of its faces
it left out and why (``beyond_evaluation_distance``, ``past_model_edge``,
``unsupported_outliers``, ``excluded_by_caller``, ``on_supplemental_geometry``: points on the
file's construction faces, :mod:`.supplemental_points`); the values below are taken on the kept
points only, so one stray point does not decide a profile and no value is a cut-off.

* **surface_profile** (ISO 1101 §18.6, profile of a surface): the zone is bounded by two surfaces
  offset ±t/2 from the true profile.  With a datum reference (``datum: true``, default) the
  profile is located by the plan's alignment; measured value ``2 max_i |d_i|`` over the
  kept points (the width of the narrowest zone centred on the CAD that holds them all),
  nominal 0, limits ``[0, t]``.  Without a datum (``datum: false``) the zone may float: the
  group is first best-fitted on its own (robust 6-DOF, :func:`.alignment.best_fit`), then the
  same value is taken.
* **flatness** (ISO 1101 §18.2): minimum-zone value of the kept points of the planar face
  (:func:`.zones.minimum_zone_flatness`, exact), limits ``[0, t]``.
* **hole** diameter and position (ISO 1101 §18.12 position of an axis): the hole is measured by
  :func:`.holes.measure_hole` (edge-point circle for the centre, count-based bias correction for
  the diameter); position value ``2 |Δ⊥|`` with Δ⊥ the measured centre's offset from the nominal
  perpendicular to the nominal axis (the diameter of the smallest cylindrical zone about the true
  position that holds the measured axis), limits ``[0, t]``; diameter deviation = measured -
  nominal, limits ±tol.
* **cylinder** diameter: robust least-squares cylinder (Tukey) of the evaluated points of the
  cylindrical face (or of all the faces of one cylinder split by the CAD, ``faces``);
  deviation = measured - nominal.
* **check_point**: deviation at a point = mean ``d`` of the evaluated points within ``radius``
  of the CAD point closest to ``at`` (same face), nominal 0.  Its noise part ``s / sqrt(n)``
  comes from the local sample standard deviation s, so the coverage factor is Student's t for
  the Welch-Satterthwaite degrees of freedom (GUM G.4) at the level of ``k`` (95.45 % for 2).

Uncertainty and decision (ISO 14253-1)
--------------------------------------
``uncertainty`` is the expanded uncertainty ``U = k u`` (``k = coverage_factor``, default 2,
about 95 %) from two sources combined in quadrature: the pose (the alignment's 6x6 covariance,
propagated through the characteristic's dependence on the pose: ``g^T C g`` with
``g = [q x n, n]`` for a displacement of point q along n) and the scan noise (the scatter of the
points that make the value: ``s / sqrt(n)`` for means; the hole's edge scatter; a single point's
noise for extreme values: a zone width taken from the largest of ``n`` deviations carries the
``k``-level quantile of the largest of ``n`` normal deviates, ``z_n sigma`` per side,
:func:`.support.extreme_quantile`, about 5 sigma at 10^5 points; flatness takes the noise's
expected part off its width and keeps only its spread in U, :mod:`.zone_noise`).  Verdict: ``pass`` inside
``[lower + U, upper - U]``, ``fail``
outside ``[lower - U, upper + U]``, else ``undecided`` (:func:`.zones.decide`).  Zone widths
(profile, flatness, position) have only the upper limit.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..registration.losses import MAD_TO_SIGMA
from ..registration.rigid import apply_transform
from .alignment import AlignmentResult, align, best_fit, face_indices
from .features import find_feature, model_features
from .holes import measure_hole, plane_basis, position_coverage
from . import registry
from .plan import Plan, load_plan
from .supplemental_points import on_supplemental
from .zone_noise import corrected_width
from .support import extreme_quantile
from .zones import decide, minimum_zone_flatness, worst_verdict, zone_decide

__all__ = ["CharacteristicResult", "PlanResult", "evaluate_plan", "evaluate_characteristics"]

logger = logging.getLogger(__name__)


def _f(x):
    return _jsonable(x)


def format_value(v, signed: bool = False, sep: str = "\n", escape=str) -> str:
    """A characteristic's value (as in its JSON) for a table: numbers to 4 decimals, points as
    (x, y, z) to 3, dicts as 'key value' entries joined by ``sep``; ``escape`` quotes text (e.g.
    ``html.escape``).  The CLI and the HTML report both use it.

    >>> format_value({"center": [1.0, 2.0, 3.0], "diameter": 36.14251}, signed=True, sep="; ")
    'center (1.000, 2.000, 3.000); diameter +36.1425'
    """
    if v is None:
        return "–"
    if isinstance(v, bool):
        return escape(str(v))
    if isinstance(v, (int, float, np.integer, np.floating)):
        return f"{v:+.4f}" if signed else f"{v:.4f}"
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(f"{x:.3f}" if isinstance(x, (int, float)) else escape(str(x))
                               for x in v) + ")"
    if isinstance(v, dict):
        return sep.join(f"{escape(str(k))} {format_value(x, signed, sep, escape)}"
                        for k, x in v.items())
    return escape(str(v))


@dataclass(frozen=True, eq=False, repr=False)
class CharacteristicResult:
    """One evaluated characteristic (see the module docstring for the definitions).

    ``nominal``, ``measured``, ``deviation``, ``lower``, ``upper``, ``uncertainty`` are floats
    (mm), or dicts for a hole (``nominal``/``measured``: ``{"center": [x, y, z], "diameter":
    d}``; the others keyed ``diameter`` and ``position``).  ``uncertainty`` is expanded (k).
    ``verdict``: 'pass' | 'fail' | 'undecided'.  ``details``: definition-specific facts
    (points used, min/max, the measured normal, the reason when not measured...).
    """

    name: str
    type: str
    nominal: object
    measured: object
    deviation: object
    lower: object
    upper: object
    uncertainty: object
    verdict: str
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """``{name, type, nominal, measured, deviation, lower, upper, uncertainty, verdict,
        details}`` with plain floats/lists (NaN -> None)."""
        return {"name": self.name, "type": self.type, "nominal": _f(self.nominal),
                "measured": _f(self.measured), "deviation": _f(self.deviation),
                "lower": _f(self.lower), "upper": _f(self.upper),
                "uncertainty": _f(self.uncertainty), "verdict": self.verdict,
                "details": _jsonable(self.details)}

    def __repr__(self) -> str:
        m = self.measured
        ms = (f"{m:.4g}" if isinstance(m, float) else
              "{…}" if isinstance(m, dict) else repr(m))
        return f"CharacteristicResult({self.name!r}, {self.type}, measured={ms}, verdict={self.verdict!r})"


def _jsonable(d):
    if isinstance(d, dict):
        return {str(k): _jsonable(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_jsonable(v) for v in d]
    if isinstance(d, np.ndarray):
        return _jsonable(d.tolist())
    if isinstance(d, (np.integer,)):
        return int(d)
    if isinstance(d, (float, np.floating)):
        return float(d) if np.isfinite(d) else None
    return d


@dataclass(frozen=True, eq=False, repr=False)
class PlanResult:
    """Result of :func:`evaluate_plan`.

    Attributes
    ----------
    plan : Plan
    alignment : AlignmentResult
    characteristics : tuple of CharacteristicResult
    verdict : str
        Worst of the characteristics' verdicts: 'fail' if any fails, else 'undecided' if any is
        undecided (or the plan has none), else 'pass'.
    points : (N, 3) float64
        Scan points in the model frame (after the alignment).
    deviations : (N,) float64
        Signed deviation along the CAD normal (NaN where not evaluated).
    face : (N,) int32
        Face of each point's closest CAD point.
    evaluated : (N,) bool
        Within the evaluation distance, not past the model's free boundary.
    noise : float
        Robust scale of the deviations (mm), ``1.4826 median |d|``.
    section : dict or None
        The plan's cross-section: ``s`` (position along the section line, mm), ``deviation``,
        ``points`` (model frame), ``direction``, ``plane`` (point, normal).
    timings : dict
    """

    plan: Plan
    alignment: AlignmentResult
    characteristics: tuple
    verdict: str
    points: np.ndarray = field(repr=False)
    deviations: np.ndarray = field(repr=False)
    face: np.ndarray = field(repr=False)
    evaluated: np.ndarray = field(repr=False)
    noise: float = float("nan")
    section: dict | None = None
    timings: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> CharacteristicResult:
        for c in self.characteristics:
            if c.name == name:
                return c
        raise KeyError(f"no characteristic {name!r}; have {[c.name for c in self.characteristics]}")

    def to_dict(self) -> dict:
        """JSON-ready: ``verdict``, ``alignment`` (type, T_model_scan, rms, dofs...),
        ``characteristics`` (list of :meth:`CharacteristicResult.to_dict`), ``noise``,
        ``coverage_factor``, ``units``."""
        return {"verdict": self.verdict, "units": "mm",
                "coverage_factor": float(self.plan.coverage_factor),
                "alignment": _jsonable(self.alignment.to_dict()),
                "characteristics": [c.to_dict() for c in self.characteristics],
                "noise": _f(self.noise), "timings": _jsonable(self.timings)}

    def __repr__(self) -> str:
        return (f"PlanResult(verdict={self.verdict!r}, alignment={self.alignment.kind!r}, "
                f"characteristics={len(self.characteristics)}, "
                f"{', '.join(f'{c.name}={c.verdict}' for c in self.characteristics[:8])})")


# ------------------------------------------------------------------------------ helpers
def _pose_var(cov, q, n) -> float:
    """Variance of the displacement of model point q along n caused by the pose."""
    g = np.r_[np.cross(q, n), n]
    C = np.where(np.isfinite(cov), cov, 0.0)
    return float(max(g @ C @ g, 0.0))


class _Scan:
    """The aligned scan with its closest CAD points (computed once), the evaluated points and
    the points the characteristics keep (:mod:`.support`).

    ``deviations``: the inspection's :class:`~shapeverify.inspection.Deviations` at this very
    pose and evaluation distance (its closest points are not computed again).
    """

    def __init__(self, prep, scan, T, evaluation_distance, exclude=None, deviations=None):
        from .support import neighbourhood_support

        self.prep = prep
        self.exclude = exclude
        dev = deviations
        if dev is not None and _same_evaluation(dev, scan, T, evaluation_distance):
            from ..measures.codes import ON_BOUNDARY, TOO_FAR

            self.X = np.asarray(dev.points_model, np.float64)
            self.d = np.asarray(dev.values, np.float64)
            # the signed distance where the inspection did not evaluate (NaN there): from the
            # foot point, signed by the normal (the same definition as prep.closest's)
            gap = self.X - np.asarray(dev.foot_points, np.float64)
            raw = np.sign(np.einsum("ij,ij->i", gap, np.asarray(dev.normals, np.float64))) * \
                np.linalg.norm(gap, axis=1)
            self.d = np.where(np.isfinite(self.d), self.d, raw)
            self.face = np.asarray(dev.face)
            self.normals = np.asarray(dev.normals, np.float64)
            self.feet = np.asarray(dev.foot_points, np.float64)
            self.on_boundary = np.asarray(dev.reason) == ON_BOUNDARY
            self.too_far = np.asarray(dev.reason) == TOO_FAR
        else:
            self.X = apply_transform(T, scan)
            cl = prep.closest(self.X, exact=True)
            self.d = np.asarray(cl.distances, np.float64)
            self.face = np.asarray(cl.face)
            self.normals = np.asarray(cl.normals, np.float64)
            self.feet = np.asarray(cl.points, np.float64)
            found = np.isfinite(self.d)
            self.too_far = ~found | (np.abs(np.where(found, self.d, 0.0)) > evaluation_distance)
            self.on_boundary = np.asarray(cl.on_boundary, bool) & ~self.too_far
        self.evaluated = ~self.too_far & ~self.on_boundary
        # points on the file's supplemental geometry (a scan of the whole file): not the part
        self.on_supplemental = np.zeros(self.d.shape[0], bool)
        if getattr(prep.model, "supplemental", ()):
            self.on_supplemental = on_supplemental(prep.model, self.X, self.d, self.evaluated,
                                                   float(prep.model_spacing),
                                                   _mad_sigma(self.d[self.evaluated]))
            self.evaluated &= ~self.on_supplemental
        self.by_caller = np.zeros(self.d.shape[0], bool) if exclude is None else \
            np.asarray(exclude, bool) & self.evaluated
        sup = neighbourhood_support(self.feet, self.d, self.evaluated & ~self.by_caller,
                                    faces=self.face)
        self.support = sup
        self.unsupported = sup.unsupported
        self.ok = self.evaluated & ~self.by_caller & ~self.unsupported
        dv = self.d[self.ok]
        mad = _mad_sigma(dv)
        # the scan's noise from neighbour differences (the part's form cancels); the spread
        # of the deviations where that cannot be had
        self.noise = sup.noise if np.isfinite(sup.noise) else mad

    def on(self, faces) -> np.ndarray:
        return self.ok if faces is None else self.ok & np.isin(self.face, faces)

    def excluded(self, faces, where=None) -> dict:
        """How many points whose closest CAD point lies on ``faces`` (None: all; and within
        the mask ``where``) the characteristics leave out, by reason (module docstring)."""
        on = np.ones(self.d.shape[0], bool) if faces is None else np.isin(self.face, faces)
        if where is not None:
            on &= where
        return {"beyond_evaluation_distance": int(np.count_nonzero(on & self.too_far)),
                "past_model_edge": int(np.count_nonzero(on & self.on_boundary)),
                "excluded_by_caller": int(np.count_nonzero(on & self.by_caller)),
                "unsupported_outliers": int(np.count_nonzero(on & self.unsupported)),
                "on_supplemental_geometry": int(np.count_nonzero(on & self.on_supplemental))}


def _mad_sigma(x) -> float:
    """Gaussian sigma of ``x`` from its median absolute deviation (NaN for none)."""
    return float(MAD_TO_SIGMA * np.median(np.abs(x - np.median(x)))) if x.size else float("nan")


def _same_evaluation(dev, scan, T, evaluation_distance) -> bool:
    """``dev`` holds this scan's deviations at the pose T, evaluation distance and all faces."""
    if dev.n != scan.shape[0] or dev.n_outside_faces or not np.isclose(
            float(dev.evaluation_distance), float(evaluation_distance), rtol=1e-12, atol=0.0):
        return False
    k = np.linspace(0, scan.shape[0] - 1, min(scan.shape[0], 16)).astype(np.int64)
    return bool(np.allclose(apply_transform(T, scan[k]), dev.points_model[k], rtol=0.0,
                            atol=1e-9 * max(1.0, float(np.abs(dev.points_model[k]).max()))))


def _k_eff(k: float, u_fixed2: float, u_sample2: float, dof: int) -> float:
    """Coverage factor for ``k``'s normal coverage level when part of the variance comes from a
    sample standard deviation with ``dof`` degrees of freedom (GUM G.4: Welch-Satterthwaite
    effective degrees of freedom, Student t)."""
    from scipy.stats import norm, t

    if dof < 1 or u_sample2 <= 0:
        return float(k)
    nu = (u_fixed2 + u_sample2) ** 2 / (u_sample2 ** 2 / dof)
    return float(t.ppf(norm.cdf(k), nu))


def _not_measured(c, reason: str) -> CharacteristicResult:
    logger.warning("characteristic %s not measured: %s", c.name, reason)
    return CharacteristicResult(c.name, c.type, None, None, None, None, None, None, "undecided",
                                {"reason": reason})


def _profile(c, S: _Scan, al: AlignmentResult, k: float, prep, scan, evaluation_distance):
    fidx = face_indices(prep.model, c.faces)
    m = S.on(fidx)
    d, X, nrm = S.d, S.X, S.normals
    cov = al.covariance
    details = {"datum": bool(c.datum)}
    noise = S.noise
    Sx = S
    if not c.datum:
        bf = best_fit(scan, prep, faces=c.faces, init=al.T_model_scan, reach=evaluation_distance,
                      degenerate_ok=True)
        S2 = _Scan(prep, scan, bf.T_model_scan, evaluation_distance, S.exclude)
        m, d, X, nrm, cov = S2.on(fidx), S2.d, S2.X, S2.normals, bf.covariance
        noise, Sx = S2.noise, S2
        details["T_model_scan"] = bf.T_model_scan.tolist()
    if np.count_nonzero(m) == 0:
        return _not_measured(c, "no scan points on the profile's faces")
    dm = d[m]
    i = int(np.argmax(np.abs(dm)))
    value = 2.0 * float(abs(dm[i]))
    j = np.flatnonzero(m)[i]
    # the value is twice the extreme deviation: its noise part is the k-level quantile of the
    # largest of n noisy deviations (.support.extreme_quantile), its pose part k u_pose there
    zq = extreme_quantile(dm.size, k)
    U = 2.0 * float(np.sqrt((zq * noise) ** 2 + k * k * _pose_var(cov, X[j], nrm[j])))
    lo, hi = _zone_limits(c)
    details.update({"n": int(m.sum()), "min": float(dm.min()), "max": float(dm.max()),
                    "max_abs": float(abs(dm[i])), "at": X[j].tolist(), "noise": noise,
                    "extreme_quantile": zq, "excluded": Sx.excluded(fidx),
                    "faces": "all" if fidx is None else fidx.tolist()})
    details.update(_lower_bound(Sx, fidx))
    return CharacteristicResult(c.name, c.type, 0.0, value, value, lo, hi, U,
                                zone_decide(c.type, value, lo, hi, U), details)


def _untrusted(r: CharacteristicResult, al: AlignmentResult) -> CharacteristicResult:
    """A characteristic measured in a frame the alignment does not vouch for (not converged, a
    datum not seen or fitting badly) decides nothing: 'undecided' with the alignment's reason."""
    if al.details.get("converged", True) or r.verdict == "undecided" and "reason" in r.details:
        return r
    import dataclasses

    why = al.details.get("reason") or "the alignment did not converge"
    return dataclasses.replace(r, verdict="undecided",
                               details={**r.details, "measured_verdict": r.verdict,
                                        "reason": f"the plan's alignment is not trusted: {why}"})


def _lower_bound(S: _Scan, faces) -> dict:
    """A zone width is only a lower bound when a surface of points lies beyond the evaluation
    distance over its faces (points with at least 3 such neighbours within 3 spacings; scattered
    gross outliers are no surface): said in the details."""
    from scipy.spatial import cKDTree

    far = S.too_far & np.isfinite(S.feet[:, 0])
    if faces is not None:
        far &= np.isin(S.face, faces)
    sp = S.support.spacing
    if np.count_nonzero(far) < 4 or not sp > 0:
        return {}
    F = S.feet[far]
    cnt = cKDTree(F).query_ball_point(F, 3.0 * sp, return_length=True)
    n = int(np.count_nonzero(cnt >= 4))
    if n == 0:
        return {}
    return {"lower_bound": True,
            "note": f"{n} points of these faces lie beyond the evaluation distance and are not "
                    "evaluated: the value is a lower bound (raise the evaluation distance to "
                    "measure them)"}


def _zone_limits(c):
    if c.tol is not None:
        return 0.0, float(c.tol)
    return 0.0, float(c.upper - c.lower)


def _face_feature(c, feats, S: _Scan, kind):
    if c.feature is not None:
        return find_feature(feats, c.feature, kind=kind)
    if kind in ("flatness", "plane"):
        fi = int(S.prep.closest(np.asarray([c.near], float), exact=True).face[0])
        f = feats[fi]
        if f.kind != "plane":
            raise ValueError(f"{c.name}: the face nearest to {c.near} is face:{fi}, a {f.kind} "
                             "face; flatness needs a planar face (give feature: face:N)")
        return f
    return find_feature(feats, near=c.near, kind=kind)


def _flatness(c, S: _Scan, feats, k, on=None, margin=None):
    """Minimum-zone flatness of the kept points of the feature's faces; ``on(faces)``: the mask
    of the points to use (:func:`.gdt._on`: not within the edge band, where a point of a
    neighbouring surface beyond the edge -- a tilted wall's foot -- is closest to this face)."""
    if getattr(c, "faces", None) is not None:    # coplanar faces, one zone
        fidx = face_indices(S.prep.model, c.faces)
        f = feats[int(fidx[0])]
        if any(feats[int(i)].kind != "plane" for i in fidx):
            raise ValueError(f"{c.name}: flatness of faces {c.faces}: not all are planar faces")
    else:
        f = _face_feature(c, feats, S, "flatness")
        fidx = np.array([f.face])
    fl = fidx.tolist()
    m = S.on(fl) if on is None else on(fl)
    if np.count_nonzero(m) < 3:
        return _not_measured(c, f"fewer than 3 scan points on {f.id}")
    P = S.X[m]
    width, n = minimum_zone_flatness(P, f.axis)
    # the zone is set by the extreme points on both sides: their expected noise is taken off
    # and its spread is U (.zone_noise)
    width, U, noise = corrected_width(width, P, n, S.noise, k)
    details = {"feature": f.id, "n": int(m.sum()), "normal": n.tolist(),
               "definition": "minimum zone, less the noise's expected part", "noise": S.noise,
               **noise,
               "excluded": {**S.excluded(fl),
                            "near_edge": int(np.count_nonzero(S.on(fl) & ~m))}}
    if margin is not None:
        details["edge_margin"] = float(margin)
    if len(fl) > 1:
        details["faces"] = fl
    details.update(_lower_bound(S, fl))
    return CharacteristicResult(c.name, c.type, 0.0, width, width, 0.0, float(c.tol), U,
                                zone_decide(c.type, width, 0.0, float(c.tol), U), details)


def _hole(c, S: _Scan, feats, al, k):
    f = _face_feature(c, feats, S, "hole")
    try:
        hm = measure_hole(S.X, f.center, f.axis, f.diameter, face=S.prep.model.faces[f.face],
                          deviations=S.d, normals=S.normals)
    except ValueError as exc:
        return _not_measured(c, str(exc))
    e1, e2 = plane_basis(f.axis)
    delta = hm.center - f.center
    dperp = delta - (delta @ f.axis) * f.axis
    pos = 2.0 * float(np.linalg.norm(dperp))
    var = np.array([hm.u_center ** 2 + _pose_var(al.covariance, hm.center, e) for e in (e1, e2)])
    if np.linalg.norm(dperp) > 1e-12:
        w = np.array([dperp @ e1, dperp @ e2]) / np.linalg.norm(dperp)
        u_rad = float(np.sqrt(w ** 2 @ var))
    else:
        u_rad = float(np.sqrt(var.mean()))
    U_pos = 2.0 * position_coverage(k) * u_rad      # (a 2-D offset: .holes)
    U_d = k * hm.u_diameter
    verdicts, lower, upper = {}, {}, {}
    dd = hm.diameter - f.diameter
    if c.diameter is not None:
        lo, hi = c.diameter.limits()
        verdicts["diameter"] = decide(dd, lo, hi, U_d)
        lower["diameter"], upper["diameter"] = lo, hi
    if c.position is not None:
        verdicts["position"] = decide(pos, None, float(c.position.tol), U_pos)
        lower["position"], upper["position"] = 0.0, float(c.position.tol)
    notes = _rim_notes(hm, verdicts, lower, upper, {"diameter": U_d, "position": U_pos})
    return CharacteristicResult(
        c.name, c.type, {"center": f.center.tolist(), "diameter": float(f.diameter)},
        {"center": hm.center.tolist(), "diameter": float(hm.diameter)},
        {"center": delta.tolist(), "position": pos, "diameter": float(dd)}, lower, upper,
        {"center": float(k * np.sqrt(var.max())), "position": U_pos, "diameter": U_d},
        worst_verdict(verdicts.values()),
        {"feature": f.id, "verdicts": verdicts, "axis": f.axis.tolist(),
         "edge_diameter": hm.edge_diameter, "bias": hm.bias, "spacing": hm.spacing,
         "area_diameter": hm.area_diameter, "anisotropy": hm.anisotropy,
         "n_edge": hm.n_edge, "edge_points": hm.edge_points.tolist(), "method": hm.method,
         **({"notes": notes} if notes else {})})


def _rim_notes(hm, verdicts, lower, upper, U) -> list:
    """Why a hole seen only at its rim is undecided: its U there, and the spacing at which U
    would be a quarter of the zone (:func:`.holes.rim_spacing_needed`)."""
    from .holes import rim_spacing_needed

    out = []
    for key, v in verdicts.items():
        width = upper[key] - (lower[key] if lower[key] is not None else 0.0)
        need = rim_spacing_needed(hm, U[key], 0.25 * width)
        if v == "undecided" and need is not None and need < hm.spacing:
            out.append(f"{key}: the hole is seen only at its rim (no wall points), where U is "
                       f"{U[key]:.3f} mm at {hm.spacing:.2f} mm point spacing; U of a quarter "
                       f"of the zone needs a spacing <= {need:.2f} mm, or a view of its wall")
    return out


def _cylinder(c, S: _Scan, feats, k):
    from ..fitting import fit_cylinder
    from .size_features import radius_uncertainty

    if getattr(c, "faces", None) is not None:      # one cylinder split into several faces
        from .face_groups import cylinder_groups

        fl = face_indices(S.prep.model, c.faces).tolist()
        if any(feats[i].kind != "cylinder" for i in fl) or \
                len(cylinder_groups(feats, fl, float(S.prep.model.size))) != 1:
            raise ValueError(f"{c.name}: the faces {c.faces} are not the faces of one "
                             "cylinder (one axis, one radius)")
        f = feats[fl[0]]
    else:
        f = _face_feature(c, feats, S, "cylinder")
        fl = [f.face]
    m = S.on(fl)
    if np.count_nonzero(m) < 20:
        return _not_measured(c, f"only {int(m.sum())} scan points on "
                                f"{f.id if len(fl) == 1 else fl}")
    P = S.X[m]
    cy = fit_cylinder(P, loss="tukey", axis=f.axis)
    a = cy.axis
    # linearised covariance of the radius (axis point in the plane, tilt, radius)
    u_R = radius_uncertainty(P, cy.point, a, cy.residuals, cy.weights)
    meas = 2.0 * cy.radius
    dev = meas - f.diameter
    lo, hi = c.diameter.limits()
    U = k * 2.0 * u_R
    return CharacteristicResult(c.name, c.type, float(f.diameter), meas, dev, lo, hi, U,
                                decide(dev, lo, hi, U),
                                {"feature": f.id, "n": int(m.sum()), "axis": a.tolist(),
                                 "rms": cy.rms, "excluded": S.excluded(fl),
                                 **({"faces": fl} if len(fl) > 1 else {})})


def _check_point(c, S: _Scan, al, k):
    at = np.asarray(c.at, np.float64)
    foot = S.prep.closest(at[None], exact=True)
    q, n, fc = foot.points[0], foot.normals[0], int(foot.face[0])
    near = np.linalg.norm(S.feet - q, axis=1) <= c.radius
    m = S.ok & (S.face == fc) & near
    nm = int(np.count_nonzero(m))
    if nm == 0:
        return _not_measured(c, f"no scan points within {c.radius:g} mm of the check point "
                                f"{np.round(q, 3).tolist()}")
    dm = S.d[m]
    value = float(dm.mean())
    s = float(dm.std(ddof=1)) if nm > 1 else S.noise
    s = max(s, S.noise) if nm < 5 else s
    u_pose2, u_noise2 = _pose_var(al.covariance, q, n), s * s / nm
    u = np.sqrt(u_pose2 + u_noise2)
    lo, hi = c.limits()
    U = _k_eff(k, u_pose2, u_noise2, nm - 1) * float(u)
    return CharacteristicResult(c.name, c.type, 0.0, value, value, lo, hi, U,
                                decide(value, lo, hi, U),
                                {"point": q.tolist(), "normal": n.tolist(), "face": fc, "n": nm,
                                 "std": s, "excluded": S.excluded([fc], near)})


def _section(sec, S: _Scan):
    p0 = np.asarray(sec.point, np.float64)
    n = np.asarray(sec.normal, np.float64)
    n = n / np.linalg.norm(n)
    m = S.ok & (np.abs((S.X - p0) @ n) <= 0.5 * sec.width)
    if not m.any():
        return {"name": sec.name, "s": [], "deviation": [], "points": np.zeros((0, 3)),
                "plane": [p0.tolist(), n.tolist()], "direction": None}
    Q = S.X[m] - p0
    Q = Q - np.outer(Q @ n, n)
    _, _, vt = np.linalg.svd(Q - Q.mean(axis=0), full_matrices=False)
    dirn = vt[0] if vt[0][np.argmax(np.abs(vt[0]))] > 0 else -vt[0]
    s = Q @ dirn
    o = np.argsort(s)
    return {"name": sec.name, "s": s[o], "deviation": S.d[m][o], "points": S.X[m][o],
            "normals": S.normals[m][o], "plane": [p0.tolist(), n.tolist()],
            "direction": dirn.tolist()}


def _largest_tolerance(plan) -> float:
    """The largest ``tol`` anywhere in the plan's characteristics (mm; 0.2 if none is above
    0: a position of zone 0 at MMC, all of it bonus, was the only tolerance of a plan and the
    evaluation distance of 5 x 0 mm raised)."""
    found = []

    def walk(x):
        if isinstance(x, dict):
            for k, v in x.items():
                if k == "tol" and isinstance(v, (int, float)):
                    if abs(float(v)) > 0:
                        found.append(abs(float(v)))
                else:
                    walk(v)
        elif isinstance(x, (list, tuple)):
            for v in x:
                walk(v)

    walk([c.model_dump() if hasattr(c, "model_dump") else c for c in plan.characteristics])
    return max(found) if found else 0.2


@dataclass(frozen=True, eq=False)
class EvalContext:
    """What every evaluator ``f(c, ctx)`` of :mod:`.registry` gets: the aligned scan ``S``
    (``_Scan``), the model's features ``feats``, the plan's alignment ``al``, the coverage
    factor ``k``, ``prep``, the raw ``scan``, the evaluation distance ``md`` and the ``plan``.
    ``cache``: per-evaluation memo (e.g. fitted datum reference frames, :mod:`.drf`)."""

    S: object
    feats: list
    al: AlignmentResult
    k: float
    prep: object
    scan: np.ndarray
    md: float
    plan: Plan
    cache: dict = field(default_factory=dict)


def eval_profile(c, ctx: EvalContext):
    """surface_profile located by the plan's alignment (its own DRF: :func:`.gdt.eval_surface_profile`)."""
    return _profile(c, ctx.S, ctx.al, ctx.k, ctx.prep, ctx.scan, ctx.md)


def eval_flatness(c, ctx: EvalContext):
    from .gdt import _on, edge_margin

    return _flatness(c, ctx.S, ctx.feats, ctx.k, on=lambda faces: _on(ctx, faces),
                     margin=edge_margin(ctx.S))


def eval_hole(c, ctx: EvalContext):
    return _hole(c, ctx.S, ctx.feats, ctx.al, ctx.k)


def eval_cylinder(c, ctx: EvalContext):
    return _cylinder(c, ctx.S, ctx.feats, ctx.k)


def eval_check_point(c, ctx: EvalContext):
    return _check_point(c, ctx.S, ctx.al, ctx.k)


def evaluate_characteristics(prep, scan, plan, alignment: AlignmentResult, exclude=None,
                             evaluation_distance: float | None = None, deviations=None):
    """Evaluate a plan's characteristics at a given alignment (see :func:`evaluate_plan`).

    Returns
    -------
    (tuple of CharacteristicResult, _Scan, section dict or None)
    """
    plan = load_plan(plan)
    from ..measures.checks import default_evaluation_distance

    md = float(evaluation_distance or plan.evaluation_distance
               or default_evaluation_distance(_largest_tolerance(plan), prep.model.size))
    S = _Scan(prep, scan, alignment.T_model_scan, md, exclude, deviations)
    feats = model_features(prep.model) if prep.model.kind == "cad" else []
    k = float(plan.coverage_factor)
    ctx = EvalContext(S, feats, alignment, k, prep, scan, md, plan)
    out = []
    for c in plan.characteristics:
        try:
            r = registry.evaluator(c.type)(c, ctx)   # the one dispatch (.registry)
        except ValueError as exc:
            if "feature" in str(exc) or "face" in str(exc):
                raise ValueError(f"characteristic {c.name!r}: {exc}") from None
            r = _not_measured(c, str(exc))
        except Exception as exc:    # noqa: BLE001 -- the characteristic says so, the rest stand
            logger.debug("characteristic %s", c.name, exc_info=True)
            r = _not_measured(c, f"its evaluation failed ({type(exc).__name__}: {exc}): an "
                                 "error of shapeverify on this part and scan, please report it "
                                 "with them; the characteristic is not measured")
        note = getattr(c.pmi, "statistical_note", None)    # an (ST) tolerance: say so
        if note:
            r.details["statistical"] = note
        out.append(_untrusted(r, alignment))
    sec = None if plan.section is None else _section(plan.section, S)
    return tuple(out), S, sec


def evaluate_plan(prep, scan, plan=None, registration=None, init=None, rng=None, *,
                  alignment: AlignmentResult | None = None, exclude=None,
                  evaluation_distance: float | None = None, deviations=None) -> PlanResult:
    """Align a scan the plan's way and evaluate every characteristic of the plan.

    Parameters
    ----------
    prep : Prepared
        The prepared CAD model (:func:`shapeverify.prepare`).
    scan : (N, 3) float64
        Scan points (scan frame, mm).
    plan : Plan, dict, path of a YAML file, YAML text or None
        None: the free best fit only (no characteristics; verdict 'undecided').
    registration : Registration, optional
        An existing free registration of this scan: the start pose of the plan's alignment
        (which then skips its own free registration).  The pose covariance is always the
        alignment's own (M-estimator covariance, see :mod:`.alignment`).  Without a plan the
        registration *is* the alignment (the free best fit; the scan is not aligned again).
    init : (4, 4), optional
        Start pose; for a constrained alignment the fixture's pose, whose locked DOFs are kept
        (default identity: the scan is in the model frame already).
    rng : None, int or Generator
        Seeds the free registration's random subsets.
    alignment : AlignmentResult, optional
        The plan's alignment, when already computed (:func:`align`).
    exclude : (N,) bool, optional
        More scan points to leave out of the characteristics (counted as
        ``excluded_by_caller``).  Measurement outliers need not be given: the characteristics
        leave out the points their neighbourhood does not support (:mod:`.support`).
    evaluation_distance : float, optional
        Points farther than this from the CAD are not used (mm; default: the plan's
        ``evaluation_distance``, else the default of :func:`shapeverify.inspect`).
    deviations : Deviations, optional
        The scan's deviations at the alignment's pose and this evaluation distance (from
        :func:`shapeverify.deviations`, all faces): its closest points are used, not computed
        again (ignored when they do not belong to this pose).

    Returns
    -------
    PlanResult

    Raises
    ------
    PlanError
        An invalid plan (line and key named).
    ValueError
        A feature the plan names does not exist, or the alignment cannot be solved.

    Examples
    --------
    The 12 mm hole of the small test bracket, on a simulated scan (0.02 mm noise):

    >>> import shapeverify as sv
    >>> from shapeverify.characteristics.parts import bracket
    >>> from shapeverify.simulate import virtual_scan
    >>> prep = sv.prepare(bracket(), spacing=1.0)
    >>> scan = virtual_scan(prep, view=[1, 1, 1.6], pixel=1.0, noise=0.02, motion=(2, 3), rng=13).scan
    >>> with open("plan.yaml", "w") as f:
    ...     _ = f.write("alignment: {type: best_fit}\\n"
    ...                 "characteristics:\\n"
    ...                 "  - {name: H1, type: hole, near: [30, 40, 0], diameter: {tol: 0.5}}\\n")
    >>> res = evaluate_plan(prep, scan, "plan.yaml")
    >>> h1 = res["H1"]          # a 12 mm hole seen at its rim only, 1 mm pixels
    >>> abs(h1.measured["diameter"] - 12.0) <= h1.uncertainty["diameter"], h1.verdict
    (True, 'pass')
    """
    from ..measures.checks import check_scan

    t0 = time.perf_counter()
    no_plan = plan is None
    plan = Plan.default() if no_plan else load_plan(plan)
    P = check_scan(scan, getattr(prep.model, "size", None))
    a = plan.alignment
    start = init
    if start is None and registration is not None and a.type != "constrained":
        start = registration.T_model_scan   # (a constrained fit keeps the fixture's pose)
    if alignment is not None:
        al = alignment
    elif no_plan and registration is not None and init is None:
        from .from_registration import registration_alignment

        al = registration_alignment(registration)     # the free best fit already made
    else:
        al = align(P, prep, a, init=start, rng=rng)
    t1 = time.perf_counter()
    chars, S, sec = evaluate_characteristics(prep, P, plan, al, exclude, evaluation_distance,
                                             deviations)
    t2 = time.perf_counter()
    dev = np.where(S.ok, S.d, np.nan)
    verdict = worst_verdict([c.verdict for c in chars])   # no characteristics: 'undecided'
    return PlanResult(plan=plan, alignment=al, characteristics=chars, verdict=verdict,
                      points=S.X, deviations=dev, face=S.face, evaluated=S.ok, noise=S.noise,
                      section=sec, timings={"alignment": t1 - t0, "characteristics": t2 - t1})
