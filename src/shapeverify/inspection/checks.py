"""The checks of an inspection's inputs: :func:`check_scan` and
:func:`default_evaluation_distance` (they live in the leaf :mod:`shapeverify.measures.checks`,
which the characteristics read without running this package; this module keeps the old import
path ``shapeverify.inspection.checks``)."""

from ..measures.checks import (MAX_COPY_FRACTION, MIN_SCAN_POINTS, _bbox_diagonal,  # noqa: F401
                               _refuse_copies, _unit_message, check_scan,
                               default_evaluation_distance)

__all__ = ["check_scan", "default_evaluation_distance", "MIN_SCAN_POINTS", "MAX_COPY_FRACTION"]
