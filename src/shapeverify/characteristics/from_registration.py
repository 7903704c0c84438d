"""An inspection's registration as the characteristics' alignment result.

A leaf of :mod:`shapeverify.characteristics` (the inspection and the plan evaluation both read
it; it imports nothing of :mod:`shapeverify.inspection`: no import cycle between the folders).
"""

from __future__ import annotations

import numpy as np

__all__ = ["registration_alignment"]


def registration_alignment(registration):
    """The inspection's registration as an :class:`~shapeverify.characteristics.AlignmentResult`
    (a free best fit of all faces: every degree of freedom fitted, none locked).

    A plan's pose (:class:`shapeverify.inspection.plan_link.PlanPose`) gives back the plan's
    own alignment.  Otherwise the pose, rms and covariance are the registration's
    (``registration.covariance``; inf where undetermined) and ``details`` say where they came
    from.
    """
    from .alignment import AlignmentResult
    from .plan import DOF_NAMES

    own = getattr(registration, "alignment", None)     # a plan's pose (PlanPose)
    if isinstance(own, AlignmentResult):
        return own
    w = getattr(registration, "weights", None)
    cov = getattr(registration, "covariance", None)
    cov = np.full((6, 6), np.inf) if cov is None else np.asarray(cov, np.float64)
    details = {"source": "registration", "iterations": int(registration.iterations),
               "converged": bool(registration.converged),
               "inlier_fraction": float(registration.inlier_fraction),
               "loss": getattr(registration, "loss", None),
               "scale": float(getattr(registration, "scale", float("nan"))),
               "n_points": None if w is None else int(np.count_nonzero(np.asarray(w) > 0))}
    return AlignmentResult(np.asarray(registration.T_model_scan, np.float64), cov,
                           np.zeros(0), float(registration.rms), DOF_NAMES, (), "best_fit",
                           details)
