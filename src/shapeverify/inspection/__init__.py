"""Inspection (thesis Paper III): signed deviations from the CAD model, tolerance verdict,
statistics and defect regions.

Read in this order: :mod:`.deviations` (scan point -> signed deviation along the CAD normal),
:mod:`.verdict` (tolerances, statistics, the pass / fail / error rules), :mod:`.regions`
(connected out-of-tolerance clusters vs measurement outliers), :mod:`.result` and
:mod:`.inspect` (the whole inspection in one call).
"""

from .deviations import EVALUATED, ON_BOUNDARY, TOO_FAR, Deviations, deviations
from .inspect import check_scan, inspect, inspect_registered
from .regions import DefectRegion, Outliers, find_regions
from .result import InspectionResult
from .verdict import Statistics, Tolerance, decide, per_face_statistics, statistics

__all__ = [
    "deviations", "Deviations", "EVALUATED", "TOO_FAR", "ON_BOUNDARY",
    "inspect", "inspect_registered", "check_scan", "InspectionResult",
    "Tolerance", "Statistics", "statistics", "per_face_statistics", "decide",
    "find_regions", "DefectRegion", "Outliers",
]
