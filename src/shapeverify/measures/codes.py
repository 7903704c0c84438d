"""The reason codes of a scan point's deviation (:attr:`shapeverify.inspection.Deviations.reason`).

A leaf (no imports): the inspection (:mod:`shapeverify.inspection.deviations`, which re-exports
them) and the characteristics both read them.  See :mod:`shapeverify.inspection.deviations` for
what each means.

>>> REASON_NAMES[TOO_FAR]
'too_far'
"""

__all__ = ["EVALUATED", "TOO_FAR", "ON_BOUNDARY", "OUTSIDE_FACES", "REASON_NAMES"]

#: Reason codes in :attr:`shapeverify.inspection.Deviations.reason`.
EVALUATED, TOO_FAR, ON_BOUNDARY, OUTSIDE_FACES = 0, 1, 2, 3
REASON_NAMES = {EVALUATED: "evaluated", TOO_FAR: "too_far", ON_BOUNDARY: "on_boundary",
                OUTSIDE_FACES: "outside_faces"}
