"""A stored inspection as the report draws it: what was decided, never inspected again.

The service stores, beside each scan (``<uuid>.npz``), the per-point arrays the report draws --
each point's deviation, why it was not evaluated, its face -- and the coverage's model points
with their covered flags; the history row holds the result's JSON (verdict, reasons, rule,
the full registration summary with its warnings and robust scale, statistics, regions, per-face
statistics, tolerance).  :class:`StoredResult` puts the two together with the attributes
:func:`shapeverify.report.html.html_report` reads, so ``GET /report/{id}`` redraws exactly the
stored decision: its verdict and reasons are the stored ones, whatever the code that would
decide them today.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from shapeverify.inspection.verdict import Statistics, Tolerance, Verdict
from shapeverify.registration.rigid import apply_transform

__all__ = ["report_arrays", "StoredResult", "ARRAY_KEYS"]

#: the arrays :func:`report_arrays` adds to a stored scan's archive
ARRAY_KEYS = ("dev_values", "dev_reason", "dev_face", "coverage_points", "coverage_covered")


def report_arrays(result) -> dict:
    """The per-point arrays of an inspection result that its report draws (for ``np.savez``)."""
    dev = result.deviations
    cov = result.coverage
    return {
        "dev_values": np.asarray(dev.values, dtype=np.float64),
        "dev_reason": np.asarray(dev.reason, dtype=np.int8),
        "dev_face": np.asarray(dev.face, dtype=np.int32),
        "coverage_points": (np.zeros((0, 3)) if cov is None
                            else np.asarray(cov.points, dtype=np.float64)),
        "coverage_covered": (np.zeros(0, bool) if cov is None
                             else np.asarray(cov.covered, dtype=bool)),
    }


def _nan(x) -> float:
    return float("nan") if x is None else float(x)


def _statistics(d: dict) -> Statistics:
    return Statistics(n=int(d.get("n") or 0), mean=_nan(d.get("mean")), std=_nan(d.get("std")),
                      rms=_nan(d.get("rms")), min=_nan(d.get("min")), max=_nan(d.get("max")),
                      p05=_nan(d.get("p05")), p95=_nan(d.get("p95")),
                      in_tolerance_fraction=_nan(d.get("in_tolerance_fraction")),
                      n_above=int(d.get("n_above") or 0), n_below=int(d.get("n_below") or 0))


def _region(d: dict) -> SimpleNamespace:
    r = SimpleNamespace(**d)
    for key in ("area", "extreme", "extreme_raw", "severity"):
        setattr(r, key, _nan(d.get(key)))
    r.centroid = np.asarray(d["centroid"], dtype=np.float64)
    r.extreme_point = np.asarray(d.get("extreme_point", d["centroid"]), dtype=np.float64)
    r.faces = tuple(int(f) for f in d.get("faces", ()))
    return r


@dataclass(frozen=True, eq=False)
class StoredDeviations:
    """The stored per-point deviations (NaN where not evaluated) and the points in model
    coordinates (the stored scan moved by the stored ``T_model_scan``)."""

    values: np.ndarray
    reason: np.ndarray
    face: np.ndarray
    points_model: np.ndarray
    evaluation_distance: float

    @property
    def evaluated(self) -> np.ndarray:
        return self.reason == 0

    @property
    def n(self) -> int:
        return int(self.values.shape[0])

    @property
    def n_evaluated(self) -> int:
        return int(np.count_nonzero(self.evaluated))


@dataclass(frozen=True, eq=False)
class StoredResult:
    """An inspection result rebuilt from its stored JSON and arrays (see the module)."""

    summary: dict
    verdict: Verdict
    reasons: tuple
    rule: str
    tolerance: Tolerance
    deviations: StoredDeviations
    regions: tuple
    per_face: dict
    statistics: Statistics
    registration: SimpleNamespace
    coverage: SimpleNamespace | None
    timings: dict = field(default_factory=dict)

    @classmethod
    def from_stored(cls, summary: dict, scan: np.ndarray, arrays) -> "StoredResult":
        """``summary``: the stored result JSON (a history record's ``result``); ``scan``: the
        stored scan points; ``arrays``: the archive with :data:`ARRAY_KEYS`.

        Raises
        ------
        ValueError
            If the arrays do not belong to the scan (another number of points).
        """
        values = np.asarray(arrays["dev_values"], dtype=np.float64)
        if values.shape[0] != scan.shape[0]:
            raise ValueError(f"the stored deviations have {values.shape[0]} points but the stored "
                             f"scan has {scan.shape[0]}")
        T = np.asarray(summary["T_model_scan"], dtype=np.float64)
        dev = StoredDeviations(values, np.asarray(arrays["dev_reason"], dtype=np.int8),
                               np.asarray(arrays["dev_face"], dtype=np.int32),
                               apply_transform(T, scan),
                               # "max_distance": the deprecated key of records before issue 31
                               _nan(summary.get("evaluation_distance",
                                                summary.get("max_distance"))))
        tol = summary.get("tolerance") or {}
        per_face_tol = {int(f): (float(lo), float(hi))
                        for f, (lo, hi) in (tol.get("per_face") or {}).items()}
        cov = None
        if summary.get("coverage") is not None and len(arrays["coverage_points"]):
            cov = SimpleNamespace(points=np.asarray(arrays["coverage_points"]),
                                  covered=np.asarray(arrays["coverage_covered"], dtype=bool),
                                  **{k: v for k, v in summary["coverage"].items()
                                     if k not in ("points", "covered")})
        reg = dict(summary.get("registration") or {})
        reg.setdefault("T_model_scan", T)
        return cls(
            summary=summary, verdict=Verdict(summary["verdict"]),
            reasons=tuple(summary.get("reasons") or ()),
            rule=str((summary.get("decision") or {}).get("rule") or ""),
            tolerance=Tolerance(float(tol["lower"]), float(tol["upper"]), per_face=per_face_tol),
            deviations=dev, regions=tuple(_region(r) for r in summary.get("regions") or ()),
            per_face={int(f): _statistics(s) for f, s in (summary.get("per_face") or {}).items()},
            statistics=_statistics(summary.get("deviation") or {}),
            registration=SimpleNamespace(**reg), coverage=cov,
            timings={k: v for k, v in (summary.get("timings") or {}).items()
                     if isinstance(v, (int, float)) and math.isfinite(v)})

    @property
    def T_model_scan(self) -> np.ndarray:
        return np.asarray(self.summary["T_model_scan"], dtype=np.float64)

    @property
    def decision(self) -> dict:
        return dict(self.summary.get("decision") or {})

    def to_dict(self, per_face: bool = True) -> dict:
        """The stored JSON (a copy)."""
        import copy

        d = copy.deepcopy(self.summary)
        if not per_face:
            d.pop("per_face", None)
        return d
