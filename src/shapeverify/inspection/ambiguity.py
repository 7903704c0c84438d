"""Near-symmetric copies: the verdict at a second pose that fits the scan alike.

Why: a part with a near-symmetry (a plate whose one chamfered corner tells its ends apart, a
1 x 1 x 1.2 mm box) seen in a sensor's frame can be registered onto a copy of its true pose:
the copy fits all but the few points of the feature that breaks the symmetry, the global
search's subset of 400 points does not see them, and the good part failed ("material
missing" at the chamfer) with only a warning that another start fits nearly as well.

How: when the registration names such alternatives (``Registration.alternatives``, the global
search's hypotheses that fit nearly as well), :func:`shapeverify.inspect` registers from each
and evaluates it (:func:`resolve`).  A profile tolerance without datums is met when some placement of the part
puts every point within the zone (a best fit): so when an alternative fits the scan alike --
its truncated fit of all scan points, ``mean(max(0, 1 - (d / tau)^2))`` over the deviations
``d`` (0 for a point not evaluated), ``tau`` three times the smaller robust scale, at least
:data:`SHARE` of the first pose's -- and passes the part that the first pose failed, the
alternative's inspection is the result (rule ``within_tolerance``; a note names the failed
pose).  Otherwise the first result stands.  A part that passes is not inspected again.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..registration._features import truncated_fit
from ..registration.rigid import rotation_vector
from .verdict import SYMMETRIC_COPY_SHARE, symmetric_copy_applies, symmetric_copy_fits_alike

__all__ = ["resolve", "SHARE"]

#: the two poses fit alike when the worse fit is at least this share of the better one (the
#: rule itself is :func:`shapeverify.inspection.verdict.symmetric_copy_fits_alike`)
SHARE = SYMMETRIC_COPY_SHARE


def _fit(result, tau: float) -> float:
    dev = result.deviations
    return float(truncated_fit(np.asarray(dev.values, np.float64),
                               np.asarray(dev.evaluated, np.bool_), tau))


def _angle_shift(T1: np.ndarray, T2: np.ndarray, scan: np.ndarray) -> tuple[float, float]:
    """(rotation deg, RMS displacement mm of the scan points) between the two poses."""
    D = T2 @ np.linalg.inv(T1)
    ang = float(np.degrees(np.linalg.norm(rotation_vector(D[:3, :3]))))
    X = scan @ T1[:3, :3].T + T1[:3, 3]
    return ang, float(np.sqrt(np.mean(np.sum((X @ D[:3, :3].T + D[:3, 3] - X) ** 2, axis=1))))


def resolve(result, other, scan: np.ndarray):
    """The inspection at an alternative pose (``other``) when it fits the scan alike and passes
    the part that ``result`` (at the registration's pose) fails; else ``result`` (module
    docstring); the rule (9) is :mod:`.verdict`'s, the fits are computed here."""
    if not symmetric_copy_applies(result.verdict, other.verdict):
        return result
    s1, s2 = result.registration.scale, other.registration.scale
    if not (np.isfinite(s1) and np.isfinite(s2) and min(s1, s2) > 0):
        return result
    tau = 3.0 * min(s1, s2)
    f1, f2 = _fit(result, tau), _fit(other, tau)
    if not symmetric_copy_fits_alike(f1, f2):
        return result                    # the first pose fits clearly better: it is the part's
    ang, shift = _angle_shift(np.asarray(result.registration.T_model_scan, float),
                              np.asarray(other.registration.T_model_scan, float), scan)
    note = (f"pass at a second pose that fits the scan alike (fit {f2:.4f} against {f1:.4f} of "
            f"the scan points within {tau:.3g} mm; {ang:.1f} deg from the pose found first, "
            f"moving the points {shift:.3g} mm RMS): the pose found first, likely a near-"
            f"symmetric copy of the part's, failed it ({result.reasons[0]}); a profile "
            "tolerance without datums is met when some placement puts every point within "
            "tolerance")
    return dataclasses.replace(other, reasons=(other.reasons[0], note) + tuple(other.reasons[1:]),
                               timings=result.timings)
