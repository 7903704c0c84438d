"""The result of one inspection and its JSON form."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .deviations import Deviations
from .regions import Outliers
from .verdict import Statistics, Tolerance

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
    verdict : {'pass', 'fail', 'error'}
    reasons : tuple of str
        Why the verdict is 'fail' or 'error' (empty for a clean 'pass').
    registration : Registration
        Result of :func:`shapeverify.register` (``T_model_scan``, ``rms``, ``weights``, ...).
    deviations : Deviations
    statistics : Statistics
        Over all evaluated points.
    per_face : dict {face: Statistics}
    regions : tuple of DefectRegion
        Largest |extreme| first.
    outliers : Outliers
        Out-of-tolerance points in no region (measurement outliers).
    tolerance : Tolerance
    timings : dict {stage: seconds}
    spacing : float
        Median scan point spacing used for the regions (mm; NaN if not needed).
    units : str
    """

    verdict: str
    reasons: tuple
    registration: object
    deviations: Deviations
    statistics: Statistics
    per_face: dict
    regions: tuple
    outliers: Outliers
    tolerance: Tolerance
    timings: dict = field(default_factory=dict)
    spacing: float = float("nan")
    units: str = "mm"

    @property
    def T_model_scan(self) -> np.ndarray:
        return np.asarray(self.registration.T_model_scan, dtype=np.float64)

    @property
    def passed(self) -> bool:
        return self.verdict == "pass"

    def registration_dict(self) -> dict:
        r = self.registration
        d = {"rms": _num(r.rms), "iterations": _num(r.iterations), "converged": bool(r.converged),
             "inlier_fraction": _num(r.inlier_fraction)}
        msg = getattr(r, "message", None)
        if msg:
            d["message"] = str(msg)
        return d

    def to_dict(self, per_face: bool = True) -> dict:
        """JSON-ready summary (no per-point arrays).

        Keys: ``verdict``, ``reasons``, ``units``, ``T_model_scan`` (4x4 nested list),
        ``registration`` (rms, iterations, converged, inlier_fraction[, message]),
        ``deviation`` (n, mean, std, rms, min, max, p05, p95, in_tolerance_fraction, n_above,
        n_below), ``tolerance`` (lower, upper, symmetric[, tolerance][, per_face]),
        ``not_evaluated`` (too_far, on_boundary, total), ``n_points``, ``max_distance``,
        ``regions`` (list), ``outliers`` (n, n_low_weight), ``spacing``, ``timings``
        (seconds per stage) and, if ``per_face``, ``per_face`` ({face: statistics}).
        """
        dev = self.deviations
        d = {
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "units": self.units,
            "T_model_scan": [[float(v) for v in row] for row in self.T_model_scan],
            "registration": self.registration_dict(),
            "deviation": {k: _num(v) for k, v in self.statistics.to_dict().items()},
            "tolerance": self.tolerance.to_dict(),
            "n_points": dev.n,
            "not_evaluated": {"too_far": dev.n_too_far, "on_boundary": dev.n_on_boundary,
                              "total": dev.n - dev.n_evaluated},
            "max_distance": _num(dev.max_distance),
            "regions": [{k: (_num(v) if not isinstance(v, (list, str)) else v)
                         for k, v in r.to_dict().items()} for r in self.regions],
            "outliers": self.outliers.to_dict(),
            "spacing": _num(self.spacing),
            "timings": {k: _num(v) for k, v in self.timings.items()},
        }
        if per_face:
            d["per_face"] = {str(f): {k: _num(v) for k, v in s.to_dict().items()}
                             for f, s in self.per_face.items()}
        return d

    def __repr__(self) -> str:
        s = self.statistics
        return (f"InspectionResult(verdict={self.verdict!r}, n={self.deviations.n}, "
                f"evaluated={s.n}, mean={s.mean:+.4f}, std={s.std:.4f}, min={s.min:+.4f}, "
                f"max={s.max:+.4f} {self.units}, regions={len(self.regions)}, "
                f"outliers={self.outliers.n}, reasons={len(self.reasons)})")
