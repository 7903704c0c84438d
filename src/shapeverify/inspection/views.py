"""Several views of one part (a robot or a turntable moves the part or the sensor): one verdict.

:func:`inspect_views` places every view on the CAD (from its given pose, or from no start with
the global search), inspects it alone to see whether it fits, leaves out a view that fits
nowhere (named, with the reason: never merged), checks that the placed views agree where they
see the same surface, and inspects the union: the coverage is the union's, the verdict the
whole part's. ``result.views`` holds each view's pose, fit, coverage and agreement.

How the views agree: for the points of view *a* that lie within two scan spacings of a point of
view *b*, the difference of their signed CAD deviations is the disagreement of the two poses
there (the part's own form cancels out); its median |.| is reported for every overlapping pair,
and a pair that disagrees by more than half the tightest limit is named in the reasons (one of
the two poses is off, or the part moved between the views).

After each view is placed alone, all placed views are refined together (:func:`joint_refine`):
in :data:`JOINT_ROUNDS` rounds, each view in turn takes Huber point-to-plane steps against the
CAD (its closest points) and against the other views where they overlap (its points within two
scan spacings of another view's point, the residual along the CAD normal: the views must agree
where they see the same surface).  Each view's pose change is reported (``joint_change``), and
the agreement is measured at the refined poses.  With no CAD (``joint_refine(..., prep=None)``)
the views are refined against each other only, the first one held (scan to scan: on the Stanford
bunny's views within 0.13 deg of ``bun.conf``, ``tests/test_views_several.py``).

Example
-------
>>> import numpy as np, shapeverify as sv
>>> from shapeverify.cad.examples import wavy_panel
>>> prep = sv.prepare(wavy_panel(), spacing=2.0)
>>> pts = prep.points.points
>>> even, odd = pts[::2], pts[1::2]                  # two views that overlap in the middle
>>> left, right = even[even[:, 0] < 0.1 * pts[:, 0].max()], odd[odd[:, 0] >= 0]
>>> res = inspect_views(prep, [left, right], tolerance=0.2)
>>> str(res.verdict), [v.used for v in res.views]
('pass', [True, True])
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
from shapeverify._lazy import cKDTree

from ..errors import RegistrationError, ScanError

__all__ = ["ViewSummary", "inspect_views", "is_view_list"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ViewSummary:
    """One view of a multi-view inspection (lengths in mm).

    Attributes
    ----------
    name : str
    n_points : int
    used : bool
        False: the view fits nowhere on the CAD and is not in the union (``reason`` says why).
    reason : str
    T_model_scan : (4, 4) float64 or None
        The view's pose (None when it could not be registered).
    rms, inlier_fraction : float
        The view's registration fit.
    coverage : float
        Share of the inspected CAD area this view sees alone (0..1).
    verdict : str
        The view's verdict alone (a partial view is usually ``incomplete``).
    warnings : tuple of str
        The view's registration warnings.
    disagreement : dict {view name: mm}
        Median |difference of the deviations| where this view overlaps another.
    joint_change : (deg, mm) or None
        How far the joint refinement moved the view from its pose alone (rotation, and the
        displacement of its centroid); None when it was not refined jointly (one view).
    """

    name: str
    n_points: int
    used: bool
    reason: str = ""
    T_model_scan: np.ndarray | None = field(default=None, repr=False)
    rms: float = float("nan")
    inlier_fraction: float = float("nan")
    coverage: float = 0.0
    verdict: str = ""
    warnings: tuple = ()
    disagreement: dict = field(default_factory=dict)
    joint_change: tuple | None = None

    def to_dict(self) -> dict:
        from .result import _num

        return {"name": self.name, "n_points": self.n_points, "used": self.used,
                "reason": self.reason, "verdict": self.verdict,
                "T_model_scan": None if self.T_model_scan is None
                else [[float(v) for v in row] for row in self.T_model_scan],
                "rms": _num(self.rms), "inlier_fraction": _num(self.inlier_fraction),
                "coverage": _num(self.coverage), "warnings": list(self.warnings),
                "disagreement_mm": {k: _num(v) for k, v in self.disagreement.items()},
                "joint_change": None if self.joint_change is None
                else {"rotation_deg": _num(self.joint_change[0]),
                      "translation_mm": _num(self.joint_change[1])}}


def is_view_list(scan) -> bool:
    """True for a list/tuple of views (2-D arrays or objects with ``points``), not for one scan
    given as a nested list of coordinates."""
    return (isinstance(scan, (list, tuple)) and len(scan) > 0
            and all((isinstance(v, np.ndarray) and v.ndim == 2) or hasattr(v, "points")
                    for v in scan))


def _views(views, names):
    pts, labels = [], []
    for i, v in enumerate(views):
        p = np.asarray(getattr(v, "points", v), dtype=np.float64)
        pts.append(p)
        labels.append(str(names[i]) if names is not None else
                      str(getattr(v, "name", "") or f"view {i + 1}"))
    if len(set(labels)) != len(labels):
        labels = [f"{lab} ({i + 1})" for i, lab in enumerate(labels)]
    return pts, labels


def _union_registration(regs, used):
    """One Registration for the union of the placed views (already in model coordinates)."""
    ok = [regs[i] for i in used]
    n = np.array([r.weights.shape[0] for r in ok], dtype=np.float64)
    rms = float(np.sqrt(np.sum(n * np.array([r.rms for r in ok]) ** 2) / n.sum()))
    inl = float(np.sum(n * np.array([r.inlier_fraction for r in ok])) / n.sum())
    scale = float(np.sqrt(np.sum(n * np.array([r.scale for r in ok]) ** 2) / n.sum()))
    return dataclasses.replace(
        ok[int(np.argmax(n))], T_model_scan=np.eye(4), rms=rms, inlier_fraction=inl, scale=scale,
        converged=all(bool(r.converged) for r in ok), iterations=sum(r.iterations for r in ok),
        weights=np.concatenate([r.weights for r in ok]), warnings=(), alternatives=(),
        undetermined=(), undetermined_directions=np.zeros((0, 6)), init="views",
        covariance=np.full((6, 6), np.nan), history=(),
        message="; ".join(r.message for r in ok if r.message))


#: rounds of the joint refinement (each view in turn against the CAD and the other views)
JOINT_ROUNDS = 4
#: scan points of each view that take part in the joint refinement (an evenly spaced subset)
JOINT_POINTS = 4000


def _view_normals(p: np.ndarray, k: int = 12) -> np.ndarray:
    """(N, 3) unit normals of a view's points (own frame): the least principal axis of each
    point's ``k`` nearest neighbours (their sign is arbitrary; only the line is used)."""
    k = min(k, p.shape[0])
    _, idx = cKDTree(p).query(p, k)
    Q = p[idx] - p[idx].mean(axis=1, keepdims=True)
    _, vec = np.linalg.eigh(np.einsum("nki,nkj->nij", Q, Q))
    return vec[:, :, 0]


def joint_refine(pts, poses, prep, spacing: float, rounds: int = JOINT_ROUNDS, *,
                 reach: float | None = None, fixed=None) -> list:
    """The poses (4, 4) of the views ``pts`` (each (N_i, 3), own frame), refined together
    (module docstring): ``rounds`` sweeps over the views, one Huber point-to-plane step each
    against the CAD's closest points and the overlapping points of the other views (within
    ``reach``, default ``2 x spacing``; residual along the CAD normal at the view's point).
    Directions the data leave undetermined get no step
    (:func:`~shapeverify.registration.rigid.solve_step`).

    ``prep`` None: the views against each other only (scan to scan, no CAD): the residual is
    along the other view's normal there (a local plane fit of its points), and the views in
    ``fixed`` (default the first) keep their pose, which fixes the common frame.
    """
    from ..registration.losses import get_loss
    from ..registration.rigid import compose_step, make_transform, point_to_plane_system, \
        solve_step

    huber = get_loss("huber")
    reach = 2.0 * spacing if reach is None else float(reach)
    fixed = set((0,) if prep is None and fixed is None else (fixed or ()))
    T = [np.asarray(P, np.float64).copy() for P in poses]
    sub = [p[np.linspace(0, len(p) - 1, min(JOINT_POINTS, len(p))).astype(np.int64)]
           for p in pts]
    own_normals = [_view_normals(p) for p in pts] if prep is None else None
    for _ in range(rounds):
        for i in range(len(pts)):
            if i in fixed:
                continue
            X = sub[i] @ T[i][:3, :3].T + T[i][:3, 3]
            src, dst, nrm = [], [], []
            if prep is not None:
                cl = prep.closest(X)
                ok = np.isfinite(cl.distances) & ~np.asarray(cl.on_boundary, bool)
                src, dst, nrm = [X[ok]], [cl.points[ok]], [cl.normals[ok]]
            else:
                ok = np.ones(len(X), bool)
            others = [j for j in range(len(pts)) if j != i]
            if others:
                Z = np.concatenate([pts[j] @ T[j][:3, :3].T + T[j][:3, 3] for j in others])
                dist, k = cKDTree(Z).query(X, distance_upper_bound=reach)
                near = ok & np.isfinite(dist)
                kk = np.minimum(k[near], len(Z) - 1)
                src.append(X[near])
                dst.append(Z[kk])
                if prep is not None:
                    nrm.append(cl.normals[near])
                else:
                    NZ = np.concatenate([own_normals[j] @ T[j][:3, :3].T for j in others])
                    nrm.append(NZ[kk])
            if not src:
                continue
            Xa, Ya, Na = (np.concatenate(a) for a in (src, dst, nrm))
            if Xa.shape[0] < 6:
                continue
            r = np.einsum("ij,ij->i", Xa - Ya, Na)
            sigma = max(1.4826 * float(np.median(np.abs(r))), 1e-9 * spacing)
            c = Xa.mean(axis=0)
            radius = max(float(np.sqrt(np.mean(np.sum((Xa - c) ** 2, axis=1)))), 1e-12)
            H, g, _ = point_to_plane_system(Xa, Ya, Na, huber.weight(r, sigma), c)
            theta, _ = solve_step(H, g, radius)
            T[i] = make_transform(*compose_step(T[i][:3, :3], T[i][:3, 3], theta, c))
    return T


def _pose_change(T0, T1, p) -> tuple[float, float]:
    """(rotation deg, displacement mm of the centroid of p) between the poses T0 and T1."""
    from ..registration.rigid import rotation_vector

    c = p.mean(axis=0)
    ang = float(np.degrees(np.linalg.norm(rotation_vector(T1[:3, :3] @ T0[:3, :3].T))))
    return ang, float(np.linalg.norm(T1[:3, :3] @ c + T1[:3, 3] - T0[:3, :3] @ c - T0[:3, 3]))


def _disagreement(alone, placed, labels, used, spacing):
    """{(a, b): median |d_a - d_b|} over the evaluated points of view a within 2 spacings of
    an evaluated point of view b (``alone[i].deviations.values``: each view's deviations, one
    per point of ``placed[i]``)."""
    out = {}
    dev = {i: alone[i].deviations.values for i in used}
    trees = {i: cKDTree(placed[i]) for i in used}
    r = 2.0 * spacing
    for a in used:
        for b in used:
            if b <= a:
                continue
            dist, j = trees[b].query(placed[a], distance_upper_bound=r)
            near = np.isfinite(dist)
            near[near] &= np.isfinite(dev[a][near]) & np.isfinite(dev[b][j[near]])
            if np.count_nonzero(near) < 20:
                continue
            out[(labels[a], labels[b])] = float(np.median(np.abs(dev[a][near] - dev[b][j[near]])))
    return out


def inspect_views(prep, views, tolerance=0.2, *, poses=None, names=None, rng=0,
                  shared_frame: bool = False, register_kwargs: dict | None = None, **options):
    """Inspect a part measured in several views (see the module docstring).

    Parameters
    ----------
    prep : shapeverify.nearest.Prepared
    views : sequence of (N_i, 3) array_like or :class:`shapeverify.io.e57.ScanView`
        Each view's points (mm) in its own frame.
    tolerance : float or Tolerance
    poses : sequence of (4, 4) array_like or None, optional
        Each view's start ``T_model_scan`` (an entry None: found by the global search).
    names : sequence of str, optional
        The views' names in the result and the reasons (default: the views' ``name`` or
        "view i").
    rng : int
        Seed of the registrations' random choices.
    shared_frame : bool
        The views are already placed in one frame (an E57 file's scans with their poses): the
        union is placed first and each view refined from that pose (unless ``poses`` given).
    register_kwargs : dict, optional
        More arguments for :func:`shapeverify.register`.
    **options
        The other options of :func:`shapeverify.inspect` (``evaluation_distance``, ``lower``,
        ``upper``, ``faces``, ``per_face``, ``min_coverage``, ...).

    Returns
    -------
    InspectionResult
        Of the union of the views that fit, with ``views`` (one :class:`ViewSummary` each).

    Raises
    ------
    ScanError
        No view fits the CAD anywhere (each view's reason is in the message), or a view is
        not an (N, 3) array.
    ValueError
        ``poses`` of another length than ``views``.
    """
    from ..registration import register
    from .inspect import check_scan, inspect_registered, _model_size

    pts, labels = _views(views, names)
    if poses is not None and len(poses) != len(pts):
        raise ValueError(f"{len(poses)} poses for {len(pts)} views: give one per view (None "
                         "for a view to be placed by the global search)")
    size = _model_size(prep)
    pts = [check_scan(p, size) for p in pts]
    opts = dict(options)
    if shared_frame and poses is None and len(pts) > 1:
        T0 = register(np.concatenate(pts), prep, **dict(register_kwargs or {}, rng=rng))
        poses = [T0.T_model_scan] * len(pts)
    regs, alone, summaries = [], [], []
    for i, p in enumerate(pts):
        kw = dict(register_kwargs or {}, rng=rng)
        if poses is not None and poses[i] is not None:
            kw["init"] = np.asarray(poses[i], dtype=np.float64)
        try:
            reg = register(p, prep, **kw)
        except RegistrationError as exc:
            regs.append(None)
            alone.append(None)
            summaries.append(ViewSummary(labels[i], len(p), False,
                                         f"could not be registered: {exc}"))
            continue
        res = inspect_registered(prep, p, reg, tolerance, **opts)
        regs.append(reg)
        alone.append(res)
        fits = not (str(res.verdict) == "error")
        summaries.append(ViewSummary(
            labels[i], len(p), fits, "" if fits else f"fits nowhere on the CAD: {res.reasons[0]}",
            np.asarray(reg.T_model_scan), float(reg.rms), float(reg.inlier_fraction),
            float(res.coverage.fraction) if res.coverage is not None else 0.0,
            str(res.verdict), tuple(str(w) for w in getattr(reg, "warnings", ()))))
    used = [i for i, s in enumerate(summaries) if s.used]
    if not used:
        raise ScanError("no view fits the CAD: " + "; ".join(f"{s.name}: {s.reason}"
                                                              for s in summaries))
    spacing = float(np.nanmedian([alone[i].scan_spacing for i in used]))
    if len(used) > 1:          # all placed views refined together (module docstring)
        joint = joint_refine([pts[i] for i in used], [regs[i].T_model_scan for i in used],
                             prep, spacing)
        for i, T in zip(used, joint):
            summaries[i] = dataclasses.replace(
                summaries[i], T_model_scan=T,
                joint_change=_pose_change(regs[i].T_model_scan, T, pts[i]))
            regs[i] = dataclasses.replace(regs[i], T_model_scan=T)
    placed = {i: pts[i] @ regs[i].T_model_scan[:3, :3].T + regs[i].T_model_scan[:3, 3]
              for i in used}
    union = np.concatenate([placed[i] for i in used])
    result = inspect_registered(prep, union, _union_registration(regs, used), tolerance, **opts)
    # the agreement at the refined poses: the union's deviations, view by view
    vals = np.asarray(result.deviations.values, np.float64)
    ends = np.cumsum([len(placed[i]) for i in used])
    split = ({i: SimpleNamespace(deviations=SimpleNamespace(values=v))
              for i, v in zip(used, np.split(vals, ends[:-1]))}
             if vals.shape[0] == ends[-1] else alone)
    pairs = _disagreement(split, placed, labels, used, spacing) if len(used) > 1 else {}

    limit = min(abs(result.tolerance.lower), abs(result.tolerance.upper))
    notes = []
    for s in summaries:
        if not s.used:
            notes.append(f"view {s.name} left out: {s.reason}")
        for w in s.warnings:
            notes.append(f"view {s.name}: registration: {w}")
    for (a, b), d in pairs.items():
        if d > 0.5 * limit:
            notes.append(f"views {a} and {b} disagree by {d:.3g} mm (median) where they see the "
                         f"same surface, more than half the tolerance ({limit:g} mm): one of the "
                         "two poses is off, or the part moved between the views")
    summaries = [dataclasses.replace(s, disagreement={
        (b if a == s.name else a): d for (a, b), d in pairs.items() if s.name in (a, b)})
        for s in summaries]
    cov = f"{100 * result.coverage.fraction:.0f} %" if result.coverage is not None else "?"
    notes.append(f"{len(used)} of {len(pts)} views merged ({len(union):,} points); together "
                 f"they cover {cov} of the inspected CAD area, each alone: "
                 + ", ".join(f"{s.name} {100 * s.coverage:.0f} %" for s in summaries if s.used))
    logger.info("views: %d of %d used, verdict %s", len(used), len(pts), result.verdict)
    return dataclasses.replace(result, reasons=tuple(result.reasons) + tuple(notes),
                               views=tuple(summaries))
