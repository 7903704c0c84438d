"""The result of one inspection and its JSON form."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .deviations import Deviations
from .regions import Outliers
from .verdict import Statistics, Tolerance, Verdict

if TYPE_CHECKING:  # annotations only (registration imports nothing from here, but costs an import)
    from ..registration.icp import Registration
    from .coverage import Coverage

__all__ = ["InspectionResult"]


def _num(x):
    """JSON-ready number: NaN/inf -> None, numpy scalars -> Python."""
    if x is None:
        return None
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True, eq=False)
class InspectionResult:
    """Everything one inspection found (lengths in mm, positions in model coordinates).

    Attributes
    ----------
    verdict : Verdict
        'pass', 'fail', 'error' or 'incomplete' (a ``str`` enum: compares equal to those strings).
    reasons : tuple of str
        Why: the first names the rule that decided; notes (outliers, undetermined pose
        directions, registration warnings) follow.
    registration : Registration
        Result of :func:`shapeverify.register` (``T_model_scan``, ``rms``, ``weights``, ...).
    deviations : Deviations
    statistics : Statistics
        Over the evaluated inliers: evaluated points less the measurement outliers (what the
        part is); ``excluded`` counts the rest and why.
    per_face : dict {face: Statistics}
    regions : tuple of DefectRegion
        Deviation and material regions (``kind``), most severe first.
    outliers : Outliers
        Out-of-tolerance points in no region (measurement outliers).
    tolerance : Tolerance
    timings : dict {stage: seconds}
    scan_spacing : float
        The scan's spacing as area per point on the part (mm,
        :func:`shapeverify.inspection.regions.surface_spacing`; NaN if not needed).
        :attr:`spacing` is the same (its older name, kept: the scan's spacing, not the
        model's ``Prepared.model_spacing``).
    units : str
    coverage : Coverage or None
        How much of the inspected CAD area was seen (:mod:`shapeverify.inspection.coverage`).
    rule : str
        The verdict rule that decided (:func:`shapeverify.inspection.decide`).
    excluded : dict
        Scan points not in the statistics, by reason: ``too_far``, ``material``,
        ``on_boundary``, ``outside_faces``, ``outliers``.
    inputs : dict
        What was inspected: ``part``, ``scan`` (file name), ``model`` (file), ``model_sha256``
        when known (set by :mod:`shapeverify.pipeline`).
    characteristics : tuple of CharacteristicResult
        With a plan: each characteristic's nominal, measured, deviation, limits, uncertainty and
        verdict (:mod:`shapeverify.characteristics`).
    plan : PlanResult or None
        With a plan: the whole plan evaluation (alignment, section, ...).
    views : tuple of ViewSummary
        With several views (:mod:`shapeverify.inspection.views`): each view's pose, fit,
        coverage alone and agreement with the others; () for one scan.
    noise : float
        The scan's own noise sigma (mm) about local quadrics of its evaluated points; a noise
        large against the tolerance makes a part that would pass ``incomplete`` (rule
        ``undecided``, ISO 14253-1).  NaN when unknown.
    """

    verdict: Verdict
    reasons: tuple
    registration: Registration
    deviations: Deviations
    statistics: Statistics
    per_face: dict
    regions: tuple
    outliers: Outliers
    tolerance: Tolerance
    timings: dict = field(default_factory=dict)
    scan_spacing: float = float("nan")
    units: str = "mm"
    coverage: Coverage | None = None
    rule: str = ""
    excluded: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    characteristics: tuple = ()
    plan: object = None
    views: tuple = ()
    noise: float = float("nan")

    def __post_init__(self):
        try:  # the one place a verdict string becomes a Verdict
            object.__setattr__(self, "verdict", Verdict(self.verdict))
        except ValueError:
            raise ValueError(f"verdict must be one of {[v.value for v in Verdict]}, got {self.verdict!r}") from None

    @property
    def decision(self) -> dict:
        """``{"verdict", "rule", "reason"}``: why the verdict is what it is."""
        return {"verdict": self.verdict.value, "rule": self.rule,
                "reason": self.reasons[0] if self.reasons else ""}

    @property
    def spacing(self) -> float:
        """The scan's spacing (mm): :attr:`scan_spacing` (this older name is kept)."""
        return self.scan_spacing

    @property
    def evaluation_distance(self) -> float:
        """The evaluation distance used (mm; ``inf``: none): ``deviations.evaluation_distance``."""
        return float(self.deviations.evaluation_distance)

    @property
    def T_model_scan(self) -> np.ndarray:
        return np.asarray(self.registration.T_model_scan, dtype=np.float64)

    @property
    def passed(self) -> bool:
        return self.verdict == "pass"

    @property
    def fit(self) -> dict:
        """The fit of the scan at the inspected pose, by the inspection's own rule (issue 29
        item 6): ``{"inlier_fraction", "rms", "rule"}`` -- the share of the scan points that
        were evaluated and are not isolated outliers, the rms of their deviations (mm), and the
        rule that left the others out.  The registration's own ``inlier_fraction`` and ``rms``
        (:meth:`registration_dict`) use its robust weights over every point it matched (a
        perfect hammer scan with 0.02 mm noise: "inliers 58.9 %, rms 0.060" while the evaluated
        deviations' std is 0.028); a summary a person reads should show these."""
        dev = self.deviations
        n = int(dev.n)
        kept = int(dev.n_evaluated) - self.outliers.n
        return {"inlier_fraction": (kept / n) if n else None,
                "rms": _num(self.statistics.rms),
                "rule": (f"scan points within the evaluation distance "
                         f"({dev.evaluation_distance:g} mm) of the inspected CAD faces, not past "
                         "their edges, less the isolated out-of-tolerance outliers")}

    def registration_dict(self) -> dict:
        r = self.registration
        d = {"rms": _num(r.rms), "iterations": _num(r.iterations), "converged": bool(r.converged),
             "inlier_fraction": _num(r.inlier_fraction)}
        scale = _num(getattr(r, "scale", None))
        if scale is not None:      # the robust residual scale (mm): a stored record redraws it
            d["scale"] = scale
        msg = getattr(r, "message", None)
        if msg:
            d["message"] = str(msg)
        for key in ("undetermined", "warnings"):
            vals = getattr(r, key, None)
            if vals:
                d[key] = [str(v) for v in vals]
        return d

    def to_dict(self, per_face: bool = True) -> dict:
        """JSON-ready summary (no per-point arrays).

        Keys: ``verdict``, ``decision`` (verdict, rule, reason), ``reasons``, ``inputs``
        (part, scan, model, model_sha256), ``units``, ``T_model_scan`` (4x4 nested list),
        ``registration`` (rms, iterations, converged, inlier_fraction[, scale, message, undetermined,
        warnings]), ``fit`` (:attr:`fit`: inlier_fraction, rms, rule), ``deviation`` (statistics of the evaluated inliers: n, mean, std, rms, min,
        max, p05, p95, in_tolerance_fraction, n_above, n_below), ``tolerance`` (lower, upper,
        symmetric[, tolerance][, per_face]), ``coverage`` (fraction, area_mm2, per_face, gaps,
        ...), ``n_points``, ``excluded`` (too_far, material, on_boundary, outside_faces,
        outliers), ``evaluation_distance``, ``regions`` (list, most severe first, each with
        ``kind``), ``outliers`` (n, n_low_weight), ``scan_spacing`` (and ``spacing``, the same under its
        older name), ``timings`` (seconds per stage)
        and, if ``per_face``, ``per_face`` ({face: statistics}).
        """
        dev = self.deviations
        d = {
            "verdict": self.verdict.value,
            "decision": self.decision,
            "reasons": list(self.reasons),
            "inputs": dict(self.inputs),
            "units": self.units,
            "T_model_scan": [[float(v) for v in row] for row in self.T_model_scan],
            "registration": self.registration_dict(),
            "fit": self.fit,
            "deviation": {k: _num(v) for k, v in self.statistics.to_dict().items()},
            "tolerance": self.tolerance.to_dict(),
            "coverage": None if self.coverage is None else self.coverage.to_dict(),
            "n_points": dev.n,
            "excluded": {k: int(v) for k, v in self.excluded.items()},
            "evaluation_distance": _num(dev.evaluation_distance),
            "regions": [{k: (_num(v) if not isinstance(v, (list, str)) else v)
                         for k, v in r.to_dict().items()} for r in self.regions],
            "outliers": self.outliers.to_dict(),
            "scan_spacing": _num(self.scan_spacing),
            "spacing": _num(self.scan_spacing),      # its older name (readers of old records)
            "noise": _num(self.noise),
            "timings": {k: _num(v) for k, v in self.timings.items()},
        }
        if self.plan is not None:
            plan = self.plan.to_dict()
            d["characteristics"] = plan["characteristics"]
            d["alignment"] = plan["alignment"]
        if self.views:
            d["views"] = [v.to_dict() for v in self.views]
        if per_face:
            d["per_face"] = {str(f): {k: _num(v) for k, v in s.to_dict().items()}
                             for f, s in self.per_face.items()}
        return d

    def __repr__(self) -> str:
        s = self.statistics
        return (f"InspectionResult(verdict={self.verdict.value!r}, n={self.deviations.n}, "
                f"evaluated={s.n}, mean={s.mean:+.4f}, std={s.std:.4f}, min={s.min:+.4f}, "
                f"max={s.max:+.4f} {self.units}, regions={len(self.regions)}, "
                f"outliers={self.outliers.n}, coverage="
                f"{float('nan') if self.coverage is None else self.coverage.fraction:.3f}, "
                f"rule={self.rule!r})")
