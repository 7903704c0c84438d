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

The views are registered to the CAD one by one; they are not yet refined jointly against each
other (a pose graph over the overlaps): the agreement check is what tells when that would
matter.

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

    def to_dict(self) -> dict:
        from .result import _num

        return {"name": self.name, "n_points": self.n_points, "used": self.used,
                "reason": self.reason, "verdict": self.verdict,
                "T_model_scan": None if self.T_model_scan is None
                else [[float(v) for v in row] for row in self.T_model_scan],
                "rms": _num(self.rms), "inlier_fraction": _num(self.inlier_fraction),
                "coverage": _num(self.coverage), "warnings": list(self.warnings),
                "disagreement_mm": {k: _num(v) for k, v in self.disagreement.items()}}


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


def _disagreement(alone, placed, labels, used, spacing):
    """{(a, b): median |d_a - d_b|} over the evaluated points of view a within 2 spacings of
    an evaluated point of view b (the deviations each view's own inspection measured)."""
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
    placed = {i: pts[i] @ regs[i].T_model_scan[:3, :3].T + regs[i].T_model_scan[:3, 3]
              for i in used}
    spacing = float(np.nanmedian([alone[i].spacing for i in used]))
    pairs = _disagreement(alone, placed, labels, used, spacing) if len(used) > 1 else {}
    union = np.concatenate([placed[i] for i in used])
    result = inspect_registered(prep, union, _union_registration(regs, used), tolerance, **opts)

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
