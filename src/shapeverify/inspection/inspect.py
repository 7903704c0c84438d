"""One inspection: register the scan, compute deviations, statistics, defect regions, verdict."""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from .. import _arrays
from ..errors import EmptyModelError, ScanError
from .deviations import _deviations
from .regions import MIN_POINTS, find_regions
from .result import InspectionResult
from .verdict import Tolerance, decide, per_face_statistics, statistics

logger = logging.getLogger(__name__)

__all__ = ["inspect", "inspect_registered", "check_scan", "MIN_SCAN_POINTS"]

#: A rigid registration has six unknowns.
MIN_SCAN_POINTS = 6

# Unit factors to mm tried when a scan's size does not match the model's.
_UNITS = ((1000.0, "metres"), (25.4, "inches"), (10.0, "centimetres"), (1e-3, "micrometres"))


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
    scan = np.asarray(scan, dtype=np.float64)
    if scan.ndim != 2 or scan.shape[1] != 3:
        raise ScanError(f"scan must be an (N, 3) array of x, y, z points, got shape {scan.shape}")
    if scan.shape[0] == 0:
        raise ScanError("the scan is empty (0 points); nothing to inspect")
    if _arrays.count_nonfinite_rows(scan):
        finite = np.isfinite(scan).all(axis=1)
        raise ScanError(f"the scan has {int((~finite).sum())} of {scan.shape[0]} points with NaN/inf "
                        "coordinates; remove them first (scan = scan[np.isfinite(scan).all(axis=1)])")
    if scan.shape[0] < MIN_SCAN_POINTS:
        raise ScanError(f"the scan has only {scan.shape[0]} points; at least {MIN_SCAN_POINTS} are "
                        "needed to register it")
    size = _bbox_diagonal(scan)
    if size == 0:
        raise ScanError(f"all {scan.shape[0]} scan points are the same point {scan[0].tolist()}")
    if model_size is not None and model_size > 0:
        ratio = size / model_size
        if ratio < 0.01 or ratio > 50:
            raise ScanError(_unit_message(size, model_size, ratio))
    return scan


def _unit_message(size: float, model_size: float, ratio: float) -> str:
    rel = (f"{1 / ratio:.0f} times smaller than" if ratio < 1 else f"{ratio:.0f} times larger than")
    msg = (f"scale mismatch: the scan's extent ({size:.4g}) is {rel} the model's ({model_size:.4g} mm)")
    # A scan usually covers 20-100 % of the part: pick the unit factor that brings it there.
    fits = [(abs(math.log(ratio * f / 0.6)), f, name) for f, name in _UNITS
            if 0.05 <= ratio * f <= 3.0]
    if fits:
        _, f, name = min(fits)
        return msg + (f"; the scan seems to be in {name}: multiply its coordinates by {f:g} "
                      "to get millimetres")
    return msg + "; check the units of the scan and the model (both must be in mm)"


def _report(progress, stage: str, fraction: float) -> None:
    if progress is not None:
        progress(stage, fraction)


def inspect(prep, scan, tolerance=0.2, max_distance: float | None = 1.0, lower=None, upper=None,
            init=None, register_kwargs: dict | None = None, progress=None, *, per_face=None,
            min_region_points: int = MIN_POINTS, min_inlier_fraction: float = 0.5,
            min_evaluated_fraction: float = 0.5) -> InspectionResult:
    """Register a scan to the model, compute its deviations and decide pass / fail / error.

    Parameters
    ----------
    prep : shapeverify.nearest.Prepared
        Prepared model.
    scan : (N, 3) array_like
        Scan points (mm) in the scanner's frame.
    tolerance : float or Tolerance, optional
        Symmetric tolerance ±mm (default 0.2), or a :class:`Tolerance`.
    max_distance : float, optional
        Scan points farther than this from the CAD surface after registration are not evaluated
        (background, fixtures). Default 1.0 mm; None: ``max(1 mm, 5 x the largest |limit|)``.
    lower, upper : float, optional
        Separate signed limits (mm), overriding ``tolerance``: e.g. ``lower=-0.1, upper=0.3``.
    init : (4, 4) array_like or 'principal-axes', optional
        Initial ``T_model_scan`` for the registration (None: identity, i.e. the scan is roughly
        in the model's frame already; 'principal-axes': coarse global alignment).
    register_kwargs : dict, optional
        More arguments for :func:`shapeverify.register` (``method``, ``loss``, ...).
    progress : callable(stage: str, fraction: float), optional
        Called at the start of each stage ('register', 'deviations', 'regions') and with
        ('done', 1.0) at the end.
    per_face : dict {face: tolerance or (lower, upper)}, optional
        Per-face tolerance overrides.
    min_region_points : int
        Smallest out-of-tolerance cluster that counts as a defect (default 5; see
        :mod:`shapeverify.inspection.regions`).
    min_inlier_fraction, min_evaluated_fraction : float
        Below these the verdict is 'error' (see :mod:`shapeverify.inspection.verdict`).

    Returns
    -------
    InspectionResult

    Raises
    ------
    ScanError
        Empty scan, NaN coordinates, too few points, a unit mismatch with the model (the message
        says which factor to apply), or a scan that ``init`` (identity if None) places nowhere
        near the model (bounding boxes more than half the model's size apart).
    EmptyModelError
        The prepared model has no surface points.
    ValueError
        Bad tolerance or max_distance.
    RegistrationError
        The registration could not start (from :func:`shapeverify.register`).

    Examples
    --------
    >>> res = inspect(prep, scan, tolerance=0.2)      # doctest: +SKIP
    >>> res.verdict, res.statistics.p95               # doctest: +SKIP
    """
    from ..registration import register

    t_start = time.perf_counter()
    timings = {}
    tol, max_distance = _check_limits(tolerance, lower, upper, per_face, max_distance)
    scan = check_scan(scan, _model_size(prep))
    if init is None or not isinstance(init, str):
        _check_near(scan, init, getattr(prep, "model", None))
    timings["validate"] = time.perf_counter() - t_start

    _report(progress, "register", 0.0)
    t0 = time.perf_counter()
    reg = register(scan, prep, init=init, **(register_kwargs or {}))
    timings["register"] = time.perf_counter() - t0
    logger.info("registration: rms %.4g mm, %d iterations, converged %s, inliers %.1f %%",
                reg.rms, reg.iterations, reg.converged, 100 * reg.inlier_fraction)

    result = _evaluate(prep, scan, reg, tol, max_distance, progress, min_region_points,
                       min_inlier_fraction, min_evaluated_fraction, timings)
    timings["total"] = time.perf_counter() - t_start
    logger.info("inspection: %s (%d regions, %d outliers) in %.3f s", result.verdict,
                len(result.regions), result.outliers.n, timings["total"])
    return result


def inspect_registered(prep, scan, registration, tolerance=0.2, max_distance: float | None = 1.0,
                       lower=None, upper=None, *, per_face=None, min_region_points: int = MIN_POINTS,
                       min_inlier_fraction: float = 0.5,
                       min_evaluated_fraction: float = 0.5) -> InspectionResult:
    """:func:`inspect` for a scan that is already registered (``registration.T_model_scan``).

    ``registration`` is any object with ``T_model_scan``, ``rms``, ``iterations``, ``converged``,
    ``inlier_fraction`` and optionally ``weights`` and ``message`` (e.g. a
    :class:`shapeverify.registration.Registration`). Use it to re-evaluate a scan with other
    tolerances without registering it again. Parameters, result and errors as :func:`inspect`.
    """
    t_start = time.perf_counter()
    timings = {}
    tol, max_distance = _check_limits(tolerance, lower, upper, per_face, max_distance)
    scan = check_scan(scan, _model_size(prep))
    timings["validate"] = time.perf_counter() - t_start
    result = _evaluate(prep, scan, registration, tol, max_distance, None, min_region_points,
                       min_inlier_fraction, min_evaluated_fraction, timings)
    timings["total"] = time.perf_counter() - t_start
    return result


def _check_near(scan: np.ndarray, init, model) -> None:
    """Raise ScanError when the scan, placed by ``init`` (identity if None), is nowhere near the
    model: its bounding box more than half the model's size away from the model's box. A local
    registration (ICP) cannot bridge such a gap."""
    bounds = getattr(model, "bounds", None)
    if bounds is None:
        return
    T = np.eye(4) if init is None else np.asarray(init, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return                                   # register() reports a bad init itself
    q = scan @ T[:3, :3].T + T[:3, 3]
    lo, hi = _arrays.bounds(q)
    mlo, mhi = np.asarray(bounds[0]), np.asarray(bounds[1])
    gap = float(np.linalg.norm(np.maximum(0.0, np.maximum(mlo - hi, lo - mhi))))
    size = float(np.linalg.norm(mhi - mlo))
    if gap > 0.5 * size:
        start = "the identity" if init is None else "init"
        raise ScanError(
            f"the scan is nowhere near the model: placed by {start} its bounding box "
            f"[{', '.join(f'{x:.4g}' for x in lo)}] .. [{', '.join(f'{x:.4g}' for x in hi)}] is "
            f"{gap:.4g} mm from the model's [{', '.join(f'{x:.4g}' for x in mlo)}] .. "
            f"[{', '.join(f'{x:.4g}' for x in mhi)}] (model size {size:.4g} mm). Registration "
            "refines a rough pose; give init= a rough T_model_scan (4x4), or "
            "init='principal-axes' for a coarse global alignment")


def _check_limits(tolerance, lower, upper, per_face, max_distance):
    tol = Tolerance.from_args(tolerance, lower, upper, per_face)
    if max_distance is None:
        max_distance = max(1.0, 5.0 * tol.max_abs)
    max_distance = float(max_distance)
    if not max_distance > 0:
        raise ValueError(f"max_distance must be > 0 mm, got {max_distance}")
    return tol, max_distance


def _model_size(prep):
    n_model = getattr(prep, "n_points", None)          # cheap; prep.points may be rebuilt
    if n_model is None:
        n_model = len(getattr(getattr(prep, "points", None), "points", (0,)))
    if n_model == 0:
        raise EmptyModelError("the prepared model has no surface points (a model without faces?)")
    model = getattr(prep, "model", None)
    return float(model.size) if model is not None and hasattr(model, "size") else None


def _evaluate(prep, scan, reg, tol, max_distance, progress, min_region_points,
              min_inlier_fraction, min_evaluated_fraction, timings) -> InspectionResult:
    """Deviations, statistics, regions and verdict of a registered scan (trusted input)."""
    _report(progress, "deviations", 0.6)
    t0 = time.perf_counter()
    T = np.asarray(reg.T_model_scan, dtype=np.float64)
    dev = _deviations(scan, prep, T, max_distance)
    timings["deviations"] = time.perf_counter() - t0

    _report(progress, "regions", 0.9)
    t0 = time.perf_counter()
    ev = dev.evaluated
    within = tol.within(dev.values, dev.face)
    v_ev = dev.values[ev]
    f_ev = dev.face[ev]
    w_ev = within[ev]
    above_ev = v_ev > 0
    stats = statistics(v_ev, w_ev, above_ev)
    per_face_stats = per_face_statistics(v_ev, f_ev, w_ev, above_ev) if v_ev.size else {}
    weights = getattr(reg, "weights", None)
    if weights is not None and np.shape(weights) != (scan.shape[0],):
        weights = None
    regions, outliers, spacing = find_regions(dev.foot_points, dev.values, ev, within, dev.face,
                                              dev.normals, weights, min_points=min_region_points)
    verdict, reasons = decide(reg, dev, regions, min_inlier_fraction=min_inlier_fraction,
                              min_evaluated_fraction=min_evaluated_fraction)
    if verdict == "pass" and outliers.n:
        reasons = (f"{outliers.n} isolated out-of-tolerance points treated as measurement outliers "
                   f"({outliers.n_low_weight} rejected by the registration)",)
    timings["regions"] = time.perf_counter() - t0
    _report(progress, "done", 1.0)
    return InspectionResult(
        verdict=verdict, reasons=tuple(reasons), registration=reg, deviations=dev,
        statistics=stats, per_face=per_face_stats, regions=tuple(regions), outliers=outliers,
        tolerance=tol, timings=timings, spacing=spacing)
