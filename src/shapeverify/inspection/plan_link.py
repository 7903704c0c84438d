"""How an inspection plan (:mod:`shapeverify.characteristics`) joins an inspection.

:class:`PlanPose` shows the plan's alignment to the inspection as a registration would be shown;
:func:`with_characteristics` combines the inspection's verdict with the characteristics';
:func:`plan_result_of` goes the other way: an inspection without a plan in the form of a plan's
result (for the PDF report), with the inspection's own pose, deviations and verdict -- the scan
is not aligned again.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .result import InspectionResult
from .verdict import with_characteristics_rule

__all__ = ["PlanPose", "with_characteristics", "registration_alignment", "plan_result_of"]


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
    def warnings(self):
        """The plan alignment's own warnings (e.g. datum features that allow two placements
        that fit alike); the inspection lists them as notes."""
        return tuple(self.alignment.details.get("warnings", ()))

    @property
    def message(self):
        a = self.alignment
        why = a.details.get("reason")
        return ((f"{why}; " if why else "")
                + f"{a.kind} alignment of the plan: fitted {', '.join(a.dof_fitted) or 'none'}; "
                f"locked {', '.join(a.dof_locked) or 'none'}; rms {a.rms:.4g} mm")


def with_characteristics(result: InspectionResult, plan_result) -> InspectionResult:
    """The inspection's verdict combined with the plan's characteristics (the rule is
    :func:`shapeverify.inspection.verdict.with_characteristics_rule`, rule 8: a failing one
    fails a passing part, an undecided one makes it ``incomplete``)."""
    chars = tuple(plan_result.characteristics)
    failed = [c.name for c in chars if c.verdict == "fail"]
    undecided = [c.name for c in chars if c.verdict == "undecided"]
    verdict, rule, reasons = with_characteristics_rule(result.verdict, result.rule,
                                                       result.reasons, failed, undecided)
    return dataclasses.replace(result, verdict=verdict, rule=rule, reasons=tuple(reasons),
                               characteristics=chars, plan=plan_result)


def registration_alignment(registration):
    """The inspection's registration as an :class:`~shapeverify.characteristics.AlignmentResult`
    (:func:`shapeverify.characteristics.from_registration.registration_alignment`; a
    :class:`PlanPose` gives back the plan's own alignment)."""
    from ..characteristics.from_registration import registration_alignment as convert

    return convert(registration)


def plan_result_of(result: InspectionResult):
    """An inspection as a :class:`~shapeverify.characteristics.PlanResult` (what the PDF report
    draws), without aligning the scan again.

    With a plan: the plan's result as evaluated.  Without one (today's behaviour: a free best
    fit and the tolerance on every point): the inspection's own registration
    (:func:`registration_alignment`), its deviations (NaN where not evaluated: too far, past
    the model's boundary, outside the inspected faces), no characteristics, and the
    inspection's verdict ('pass', 'fail', 'incomplete' or 'error').

    Parameters
    ----------
    result : InspectionResult

    Returns
    -------
    PlanResult
    """
    if result.plan is not None:
        return result.plan
    from ..characteristics.evaluate import PlanResult
    from ..characteristics.plan import Plan
    from ..registration.losses import MAD_TO_SIGMA

    dev = result.deviations
    ok = np.asarray(dev.evaluated, bool)
    d = np.where(ok, np.asarray(dev.values, np.float64), np.nan)
    dv = d[ok]
    noise = float(MAD_TO_SIGMA * np.median(np.abs(dv - np.median(dv)))) if dv.size \
        else float("nan")
    return PlanResult(plan=Plan.default(), alignment=registration_alignment(result.registration),
                      characteristics=(), verdict=result.verdict,
                      points=np.asarray(dev.points_model, np.float64), deviations=d,
                      face=np.asarray(dev.face), evaluated=ok, noise=noise, section=None,
                      timings={"alignment": 0.0, "characteristics": 0.0})
