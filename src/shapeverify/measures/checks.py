"""The checks of an inspection's inputs that other folders use too: the scan
(:func:`check_scan`) and the default evaluation distance (:func:`default_evaluation_distance`).

A leaf (:mod:`shapeverify.measures`): the characteristics (:mod:`shapeverify.characteristics.evaluate`)
read it without running the inspection package, which runs them (issue 31: no import cycle
between folders).  Public names: ``shapeverify.inspection.check_scan``,
``shapeverify.inspection.default_evaluation_distance`` (and the old module
``shapeverify.inspection.checks``, which re-exports this one).
"""

from __future__ import annotations

import numpy as np

from .. import _arrays
from ..errors import ScanError
from ..units import MIXUPS, fitting_factor
from .tolerance import Tolerance

__all__ = ["check_scan", "default_evaluation_distance", "MIN_SCAN_POINTS", "MAX_COPY_FRACTION"]

#: A rigid registration has six unknowns.
MIN_SCAN_POINTS = 6



def _bbox_diagonal(points: np.ndarray) -> float:
    lo, hi = _arrays.bounds(points)
    return float(np.linalg.norm(hi - lo))


def check_scan(scan, model_size: float | None = None) -> np.ndarray:
    """Validate a scan for inspection and return it as a float64 (N, 3) array.

    Parameters
    ----------
    scan : (N, 3) array_like
        Scan points, mm.
    model_size : float, optional
        Bounding-box diagonal of the model (mm); enables the unit check.

    Raises
    ------
    ScanError
        Wrong shape, empty, fewer than 6 points, NaN/inf coordinates, all points coincident, or a
        size that does not fit the model's by a unit factor (a scan in metres against a model in
        millimetres is 1000 times too small): the message names the factor to apply.
    """
    scan = _arrays.check_points(scan, "scan", single=False, error=ScanError)
    if scan.shape[0] == 0:
        raise ScanError("the scan is empty (0 points); nothing to inspect")
    if scan.shape[0] < MIN_SCAN_POINTS:
        n = scan.shape[0]
        raise ScanError(f"the scan has only {n} point{'s' if n > 1 else ''}; at least "
                        f"{MIN_SCAN_POINTS} are needed to register it")
    size = _bbox_diagonal(scan)
    if size == 0:
        raise ScanError(f"all {scan.shape[0]} scan points are the same point {scan[0].tolist()}")
    big = float(np.abs(scan).max())
    if big > 1e12:
        raise ScanError(f"scan coordinates reach {big:.3g}: no part is that large in any unit "
                        "(a corrupt file or a missing scale?); check the scan")
    _refuse_copies(scan)
    if model_size is not None and model_size > 0:
        ratio = size / model_size
        if ratio < 0.01 or ratio > 50:
            raise ScanError(_unit_message(size, model_size, ratio))
    return scan


#: More than this fraction of a scan's points being exact copies of others refuses the scan.
MAX_COPY_FRACTION = 0.01


def _refuse_copies(scan: np.ndarray) -> None:
    """Raise :class:`ScanError` when more than 1 % of the rows of ``scan`` repeat other rows.

    Copies weigh as independent measurements in the outlier and region rules: a scan written
    twice or three times turned its dent into "isolated outliers" (a pass), and two stray
    points, copied three times, into a defect region.  Equal rows are found through a
    projection on an irrational direction (0.7 ms per 25k points) and confirmed exactly.
    """
    h = np.sort(scan @ np.array([1.0, 1.4142135623730951, 1.7320508075688772]))
    if np.count_nonzero(h[1:] == h[:-1]) <= MAX_COPY_FRACTION * scan.shape[0]:
        return
    rows = np.ascontiguousarray(scan).view(np.dtype((np.void, 24))).ravel()
    copies = scan.shape[0] - np.unique(rows).size
    if copies > MAX_COPY_FRACTION * scan.shape[0]:
        raise ScanError(
            f"{copies:,} of the scan's {scan.shape[0]:,} points ({100 * copies / scan.shape[0]:.1f} %) "
            "are exact copies of other points (the file holds parts of the scan more than once?); "
            "copies would count as independent measurements and change the verdict. Remove them "
            "(e.g. numpy.unique(points, axis=0)) and inspect again")


def _unit_message(size: float, model_size: float, ratio: float) -> str:
    times = 1 / ratio if ratio < 1 else ratio
    times = f"{times:.0f}" if times < 1e4 else f"{times:.3g}"
    rel = f"{times} times {'smaller' if ratio < 1 else 'larger'} than"
    msg = (f"scale mismatch: the scan's extent ({size:.4g}) is {rel} the model's ({model_size:.4g} mm)")
    # A scan usually covers 20-100 % of the part: pick the unit factor that brings it there.
    fit = fitting_factor(ratio, MIXUPS, 0.05, 3.0, 0.6)
    if fit:
        _, f, name, _ = fit
        return msg + (f"; the scan seems to be in {name}: multiply its coordinates by {f:g} "
                      "to get millimetres")
    return msg + "; check the units of the scan and the model (both must be in mm)"


def default_evaluation_distance(tolerance, size: float | None = None) -> float:
    """The one default of the evaluation distance (mm): ``max(5 x the largest |limit|, cap)``.

    ``cap`` is 1 mm, or 5 % of the model's size (bounding-box diagonal, mm) when that is
    smaller: on a 3 mm part a 1 mm reach is a third of the part, and outliers beside a convex
    edge project onto the edge as a dense band that looks like a defect.

    Scan points farther than this from the CAD surface after registration are not evaluated
    (background, fixtures, gross outliers); dense such points attached to the part become
    material regions (:mod:`shapeverify.inspection.material`). The API, the CLI, the service
    and batch all use this rule when no distance is given.

    >>> default_evaluation_distance(0.2), default_evaluation_distance(0.5)
    (1.0, 2.5)
    >>> default_evaluation_distance(0.002, size=3.2)  # a 1.86 mm cube
    0.16
    """
    tol = tolerance if isinstance(tolerance, Tolerance) else Tolerance.from_args(tolerance)
    cap = 1.0 if size is None or not size > 0 else min(1.0, 0.05 * float(size))
    return float(round(max(cap, 5.0 * tol.max_abs), 12))
