"""How an inspection plan (:mod:`shapeverify.characteristics`) joins an inspection.

:class:`PlanPose` shows the plan's alignment to the inspection as a registration would be shown;
:func:`with_characteristics` combines the inspection's verdict with the characteristics'.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .result import InspectionResult

__all__ = ["PlanPose", "with_characteristics"]


@dataclass(frozen=True, eq=False)
class PlanPose:
    """The pose of a plan's alignment, in the shape the inspection reads a registration."""

    alignment: object
    free: object = None          # the free registration it started from, if any

    @property
    def T_model_scan(self):
        return self.alignment.T_model_scan

    @property
    def rms(self):
        return self.alignment.rms

    @property
    def covariance(self):
        return self.alignment.covariance

    @property
    def iterations(self):
        return int(self.alignment.details.get("iterations", getattr(self.free, "iterations", 0)))

    @property
    def converged(self):
        return bool(self.alignment.details.get("converged", True))

    @property
    def inlier_fraction(self):
        return float(self.alignment.details.get(
            "inlier_fraction", getattr(self.free, "inlier_fraction", 1.0)))

    @property
    def weights(self):
        return None

    @property
    def message(self):
        a = self.alignment
        return (f"{a.kind} alignment of the plan: fitted {', '.join(a.dof_fitted) or 'none'}; "
                f"locked {', '.join(a.dof_locked) or 'none'}; rms {a.rms:.4g} mm")


def with_characteristics(result: InspectionResult, plan_result) -> InspectionResult:
    """The inspection's verdict combined with the plan's characteristics: a failing one fails a
    passing part (rule ``characteristics``), an undecided one (ISO 14253-1) makes it
    ``incomplete`` (rule ``undecided``); error and incomplete verdicts stand."""
    chars = tuple(plan_result.characteristics)
    failed = [c.name for c in chars if c.verdict == "fail"]
    undecided = [c.name for c in chars if c.verdict == "undecided"]
    verdict, rule, reasons = result.verdict, result.rule, list(result.reasons)
    lines = []
    if failed:
        lines.append(f"characteristic{'s' if len(failed) > 1 else ''} out of tolerance: "
                     f"{', '.join(failed)}")
    if undecided:
        lines.append(f"characteristic{'s' if len(undecided) > 1 else ''} that cannot be decided "
                     f"within the measurement uncertainty (ISO 14253-1): {', '.join(undecided)}")
    if verdict in ("pass", "fail") and failed:
        if verdict == "pass":
            verdict, rule = "fail", "characteristics"
            reasons = [f"fail: {lines[0]}"] + lines[1:] + reasons[1:]
        else:
            reasons = reasons[:1] + lines + reasons[1:]
    elif verdict == "pass" and undecided:
        verdict, rule = "incomplete", "undecided"
        reasons = [f"incomplete: {lines[0]}"] + reasons[1:]
    else:
        reasons = reasons[:1] + lines + reasons[1:]
    return dataclasses.replace(result, verdict=verdict, rule=rule, reasons=tuple(reasons),
                               characteristics=chars, plan=plan_result)
