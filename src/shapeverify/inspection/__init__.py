"""Inspection (thesis Paper III): signed deviations from the CAD model, tolerance verdict,
statistics and defect regions.

Read in this order: :mod:`.deviations` (scan point -> signed deviation along the CAD normal),
:mod:`.verdict` (tolerances, statistics, the pass / fail / error / incomplete rules),
:mod:`.regions` (connected out-of-tolerance surface vs measurement outliers), :mod:`.material`
(measured surface where the CAD has none), :mod:`.coverage` (how much was seen), :mod:`.result` and
:mod:`.inspect` (the whole inspection in one call).

The building blocks the characteristics share with it (the tolerance zone, the scan checks, the
deviation reason codes, the spacing helpers and grid kernels) live in the leaf package
:mod:`shapeverify.measures`; the names below re-export them.
"""

from .coverage import MIN_COVERAGE, Coverage, compute_coverage
from .deviations import EVALUATED, ON_BOUNDARY, OUTSIDE_FACES, TOO_FAR, Deviations, deviations
from .inspect import check_scan, default_evaluation_distance, inspect, inspect_registered
from .material import find_material
from .regions import DefectRegion, Outliers, find_regions
from .result import InspectionResult
from .verdict import Statistics, Tolerance, Verdict, decide, per_face_statistics, statistics
from .views import ViewSummary, inspect_views

__all__ = ["inspect_views", "ViewSummary", 
    "deviations", "Deviations", "EVALUATED", "TOO_FAR", "ON_BOUNDARY", "OUTSIDE_FACES",
    "inspect", "inspect_registered", "check_scan", "default_evaluation_distance", "InspectionResult",
    "Coverage", "compute_coverage", "MIN_COVERAGE", "find_material",
    "Tolerance", "Statistics", "statistics", "per_face_statistics", "decide", "Verdict",
    "find_regions", "DefectRegion", "Outliers",
]
