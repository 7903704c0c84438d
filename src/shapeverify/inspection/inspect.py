"""One inspection: register the scan, compute deviations, coverage, regions, statistics, verdict."""

from __future__ import annotations

import dataclasses
import logging
import time
import warnings
from dataclasses import dataclass

import numpy as np

from .. import _arrays
from ..errors import EmptyModelError, RegistrationError, ScanError
from ..units import unit_hint
from .ambiguity import resolve
from .beyond import join_beyond
# the scan check and the evaluation distance's default live in a leaf (characteristics read them)
from .checks import (MAX_COPY_FRACTION, MIN_SCAN_POINTS, _bbox_diagonal,  # noqa: F401
                     _unit_message, check_scan, default_evaluation_distance)
from .coverage import MIN_COVERAGE, compute_coverage, seen_faces
from .deviations import _deviations
from .material import beside_surface, far_over_surface, find_material, floating_surfaces
from .missing import find_missing
from .plan_link import PlanPose, with_characteristics
from .regions import MIN_POINTS, RegionSearch, find_regions, surface_spacing
from .result import InspectionResult
from .verdict import (MIN_INLIER_FRACTION, Tolerance, decide, per_face_statistics,
                      statistics)

logger = logging.getLogger(__name__)

__all__ = ["inspect", "inspect_registered", "check_scan", "default_evaluation_distance",
           "MIN_SCAN_POINTS"]

def _report(progress, stage: str, fraction: float) -> None:
    if progress is not None:
        progress(stage, fraction)


def inspect(prep, scan, tolerance=None, evaluation_distance: float | None = None, lower=None,
            upper=None, init=None, register_kwargs: dict | None = None, progress=None,
            **options) -> InspectionResult:
    """Register a scan to the model, compute its deviations and decide the verdict.

    Parameters
    ----------
    prep : shapeverify.nearest.Prepared
        Prepared model.
    scan : (N, 3) array_like, or a list of them
        Scan points (mm) in the scanner's frame; a list of (N_i, 3) arrays (or
        :class:`~shapeverify.io.e57.ScanView`) is several views of one part, inspected together
        by :func:`shapeverify.inspection.views.inspect_views` (``init``: then a list of start
        poses, one per view, None for a view to be placed by the global search).
    tolerance : float or Tolerance, optional
        Symmetric tolerance ±mm (None: 0.2, unless ``lower`` and ``upper`` are both given), or
        a :class:`Tolerance`.
    evaluation_distance : float, optional
        Scan points farther than this from the CAD surface after registration are not evaluated
        (mm). None: :func:`default_evaluation_distance` (``max(5 x the largest |limit|,
        min(1 mm, 5 % of the model size))``).
    lower, upper : float, optional
        Separate signed limits (mm), overriding ``tolerance``: e.g. ``lower=-0.1, upper=0.3``.
    init : (4, 4) array_like or str, optional
        Initial ``T_model_scan`` for the registration, or a strategy understood by
        :func:`shapeverify.register`. None: the prepared model's fixture pose
        (``prep.fixture``, ``prepare --fixture``) if it has one, else the registration's
        default (an automatic global search when the scan does not already overlap).
    register_kwargs : dict, optional
        More arguments for :func:`shapeverify.register` (``method``, ``loss``, ...).
    progress : callable(stage: str, fraction: float), optional
        Called at the start of each stage ('register', 'deviations', 'regions') and with
        ('done', 1.0) at the end.
    faces : sequence of int or "seen", optional
        The inspected CAD faces (None: all). Points whose closest CAD point lies on another face
        are not evaluated, and the coverage is measured on these faces only.  ``"seen"``: the
        faces the scan saw, at least 10 % of a face's area covered at the registered pose
        (:func:`~shapeverify.inspection.coverage.seen_faces`; a reason names them and their
        share of the part), so that a partial view (a gear's rim) can pass or fail.
    per_face : dict {face: tolerance or (lower, upper)}, optional
        Per-face tolerance overrides.
    min_coverage : float
        Least covered share of the inspected area (0..1, default 0.2) for a pass or fail verdict;
        below it the verdict is 'incomplete' (see :mod:`shapeverify.inspection.coverage`).
    min_region_points : int
        Fewest dense core points of a defect region, and its least area in squared spacings
        (default 5; see :mod:`shapeverify.inspection.regions`).
    min_inlier_fraction : float
        Below this registration inlier fraction the verdict is 'error' (default 0.25).
    rng : int or numpy Generator
        Seed of the registration's random choices (default 0: the same result every run).
    max_distance : float, optional
        Old name of ``evaluation_distance`` (accepted with a :class:`DeprecationWarning`).
    options : shapeverify.InspectionOptions, optional
        All of the above in one checked object (what the command line, the service and batch
        pass); then give no other option keyword.
    missing : bool
        Fail the part where the scan sees through the CAD surface (on by default, issue 33 row
        3): an unseen area, enclosed by seen surface, with scan points seen *behind* it (the
        wall of a hole the CAD does not have, what lies behind a sheet) becomes a region of kind
        ``"missing"`` (:mod:`shapeverify.inspection.missing`); an area merely not seen (a
        dropout, the far side of a one-sided scan) has no such points and stays a coverage gap.
        ``False``: skip the rule.
    plan : Plan, dict, str or path, optional
        An inspection plan (:mod:`shapeverify.characteristics`: ``plan.yaml``): the scan is
        aligned the plan's way (best fit on faces, constrained, RPS, datums; an array ``init``
        is the fixture pose) and every characteristic of the plan is measured with its
        uncertainty; they are in ``result.characteristics``. A characteristic that fails fails
        the part; one that cannot be decided within its uncertainty (ISO 14253-1) makes an
        otherwise passing part 'incomplete' (rule ``undecided``).

    Returns
    -------
    InspectionResult

    Raises
    ------
    ScanError
        Empty scan, NaN coordinates, too few points, a unit mismatch with the model (the message
        says which factor to apply), or a scan that an explicit ``init`` places nowhere near the
        model.
    EmptyModelError
        The prepared model has no surface points.
    ValueError
        Bad tolerance, evaluation distance, faces or min_coverage.
    RegistrationError
        The registration could not start (from :func:`shapeverify.register`).

    Examples
    --------
    A simulated scan of the small example panel with a 0.5 mm dent, 2 degrees and 3 mm off:

    >>> import shapeverify as sv
    >>> from shapeverify.cad.examples import wavy_panel
    >>> from shapeverify.simulate import ScanEffects, virtual_scan
    >>> prep = sv.prepare(wavy_panel(), spacing=2.0)
    >>> scan = virtual_scan(prep, pixel=2.0, noise=0.02, motion=(2.0, 3.0),
    ...                     effects=ScanEffects(dents=[(0.5, 15.0)]), rng=1).scan
    >>> res = inspect(prep, scan, tolerance=0.2)
    >>> str(res.verdict), res.rule
    ('fail', 'regions')
    """
    given = _given(options, tolerance=tolerance, evaluation_distance=evaluation_distance,
                   lower=lower, upper=upper, init=init, registration=register_kwargs)
    return _inspect(prep, scan, given, progress)


def _given(options: dict, **keywords):
    """The :class:`~shapeverify.options.InspectionOptions` of :func:`inspect`'s (or
    :func:`inspect_registered`'s) keywords, or the one passed as ``options=``."""
    from ..options import InspectionOptions

    given = options.pop("options", None)
    if given is None:
        return InspectionOptions.from_kwargs(**options, **keywords, stacklevel=4)
    if not isinstance(given, InspectionOptions):
        raise TypeError(f"options= takes an InspectionOptions, got {type(given).__name__}")
    extra = sorted(k for k, v in {**options, **keywords}.items() if v is not None)
    if extra:
        raise TypeError(f"give the options either as options= or as keywords, not both "
                        f"(also given: {', '.join(extra)}); use options.replace({extra[0]}=...)")
    return given


def _inspect(prep, scan, given, progress) -> InspectionResult:
    """:func:`inspect` with its options checked (an InspectionOptions)."""
    from ..registration import register
    from .views import inspect_views, is_view_list

    init, plan, rng = given.init_pose, given.plan, given.rng
    if is_view_list(scan):   # several views of one part (inspection.views)
        if plan is not None:
            raise ValueError("an inspection plan with several views is not supported yet: "
                             "merge the views first or inspect them one by one")
        return inspect_views(prep, scan, poses=init, **given.view_kwargs())
    t_start = time.perf_counter()
    timings = {}
    opts = _options(prep, given)
    scan = check_scan(scan, _model_size(prep))
    if init is None and getattr(prep, "fixture", None) is not None:
        init = np.asarray(prep.fixture, dtype=np.float64)
    if init is not None and not isinstance(init, str):
        _check_near(scan, init, getattr(prep, "model", None))
    timings["validate"] = time.perf_counter() - t_start

    _report(progress, "register", 0.0)
    t0 = time.perf_counter()
    kwargs = given.register_kwargs
    kwargs.setdefault("rng", rng)
    if init is not None:
        kwargs["init"] = init
    plan_obj = plan                      # loaded by InspectionOptions
    try:
        if plan_obj is not None and (plan_obj.alignment.type == "constrained"
                                     or (init is not None and not isinstance(init, str))):
            reg = None                   # the plan's alignment starts from the fixture pose
        else:
            reg = register(scan, prep, **kwargs)
    except RegistrationError as exc:
        far = _far_message(scan, init, getattr(prep, "model", None))
        if far is None:
            raise
        raise ScanError(f"{far}, and the global search found no pose that fits it ({exc}); is "
                        "this a scan of this part? If it is, give a rough start pose "
                        "(init=, CLI --init T.json)") from exc
    if plan_obj is not None:
        from ..characteristics import align
        T_start = init if init is not None and not isinstance(init, str) else None
        if T_start is None and reg is not None and plan_obj.alignment.type != "constrained":
            T_start = reg.T_model_scan       # a constrained fit keeps the fixture's pose
        reg = PlanPose(align(scan, prep, plan_obj.alignment, init=T_start, rng=rng,
                             registration=reg), reg)
    timings["register"] = time.perf_counter() - t0
    logger.info("registration: rms %.4g mm, %d iterations, converged %s, inliers %.1f %%",
                reg.rms, reg.iterations, reg.converged, 100 * reg.inlier_fraction)

    result = _evaluate(prep, scan, reg, opts, progress, timings)
    if plan_obj is None and str(result.verdict) == "fail" and getattr(reg, "alternatives", ()):
        result = _at_alternatives(prep, scan, result, reg.alternatives, kwargs, opts, timings)
    if plan_obj is not None:
        from ..characteristics import evaluate_plan
        t0 = time.perf_counter()
        # the characteristics keep their own outlier rule (neighbourhood support), not this
        # inspection's out-of-tolerance outliers (a cut-off at the limit), and reuse its
        # deviations (the same pose and evaluation distance)
        plan_result = evaluate_plan(prep, scan, plan_obj, alignment=reg.alignment,
                                    evaluation_distance=opts.evaluation_distance,
                                    deviations=result.deviations)
        timings["characteristics"] = time.perf_counter() - t0
        result = with_characteristics(result, plan_result)
    timings["total"] = time.perf_counter() - t_start
    logger.info("inspection: %s (%d regions, %d outliers) in %.3f s", result.verdict,
                len(result.regions), result.outliers.n, timings["total"])
    return result


def _at_alternatives(prep, scan, result, poses, kwargs, opts, timings):
    """A failed part inspected again from each of the registration's alternative poses (near-
    symmetric copies that fit nearly as well): the first that fits alike and passes it is the
    result (:mod:`.ambiguity`); else ``result``."""
    from ..registration import register

    t0 = time.perf_counter()
    out = result
    # the scan points of the regions that fail the part: an alternative can pass it only where
    # most of them come within tolerance (a dent does at no pose: no registration for it)
    bad = np.unique(np.concatenate([r.indices for r in result.regions])) \
        if result.regions else np.zeros(0, np.int64)
    lim = 2.0 * max(abs(opts.tol.lower), opts.tol.upper)
    for T in poses:
        if bad.size:
            X = scan[bad] @ np.asarray(T)[:3, :3].T + np.asarray(T)[:3, 3]
            if np.mean(np.abs(prep.closest(X).distances) <= lim) < 0.5:
                continue
        try:
            with warnings.catch_warnings():    # the first registration said what there is
                warnings.simplefilter("ignore")
                reg2 = register(scan, prep, **{**kwargs, "init": T})
        except RegistrationError:
            continue
        out = resolve(result, _evaluate(prep, scan, reg2, opts, None, {}), scan)
        if out is not result:
            break
    timings["alternatives"] = time.perf_counter() - t0
    return out


def inspect_registered(prep, scan, registration, tolerance=None,
                       evaluation_distance: float | None = None, lower=None, upper=None,
                       **options) -> InspectionResult:
    """:func:`inspect` for a scan that is already registered (``registration.T_model_scan``).

    ``registration`` is any object with ``T_model_scan``, ``rms``, ``iterations``, ``converged``,
    ``inlier_fraction`` and optionally ``weights`` and ``message`` (e.g. a
    :class:`shapeverify.registration.Registration`). Use it to re-evaluate a scan with other
    tolerances without registering it again. Parameters, result and errors as :func:`inspect`
    (``init``, ``plan``, ``rng`` and the registration's keywords are not used).
    """
    t_start = time.perf_counter()
    timings = {}
    opts = _options(prep, _given(options, tolerance=tolerance,
                                 evaluation_distance=evaluation_distance, lower=lower,
                                 upper=upper))
    scan = check_scan(scan, _model_size(prep))
    timings["validate"] = time.perf_counter() - t_start
    result = _evaluate(prep, scan, registration, opts, None, timings)
    timings["total"] = time.perf_counter() - t_start
    return result


def _check_near(scan: np.ndarray, init, model) -> None:
    """Raise ScanError when the scan, placed by ``init``, is nowhere near the model: its bounding
    box more than half the model's size away from the model's box. A local registration (ICP)
    cannot bridge such a gap."""
    msg = _far_message(scan, init, model)
    if msg:
        raise ScanError(msg + ". Registration refines a rough pose; give init= a rough "
                        "T_model_scan (4x4), or leave init out for the automatic global search")


def _far_message(scan: np.ndarray, init, model) -> str | None:
    """Why ``scan`` placed by ``init`` (identity if None) is nowhere near ``model``, or None."""
    bounds = getattr(model, "bounds", None)
    if bounds is None:
        return None
    T = np.eye(4) if init is None or isinstance(init, str) else np.asarray(init, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return None                              # register() reports a bad init itself
    q = scan @ T[:3, :3].T + T[:3, 3]
    lo, hi = _arrays.bounds(q)
    mlo, mhi = np.asarray(bounds[0]), np.asarray(bounds[1])
    gap = float(np.linalg.norm(np.maximum(0.0, np.maximum(mlo - hi, lo - mhi))))
    size = float(np.linalg.norm(mhi - mlo))
    if gap <= 0.5 * size:
        return None
    start = "the identity" if init is None or isinstance(init, str) else "init"
    return (f"the scan is nowhere near the model: placed by {start} its bounding box "
            f"[{', '.join(f'{x:.4g}' for x in lo)}] .. [{', '.join(f'{x:.4g}' for x in hi)}] is "
            f"{gap:.4g} mm from the model's [{', '.join(f'{x:.4g}' for x in mlo)}] .. "
            f"[{', '.join(f'{x:.4g}' for x in mhi)}] (model size {size:.4g} mm)")


@dataclass(frozen=True)
class _Options:
    """The checked settings of one inspection."""

    tol: Tolerance
    evaluation_distance: float
    faces: tuple | None
    min_coverage: float
    min_region_points: int
    min_inlier_fraction: float
    missing: bool = True


def _options(prep, given) -> _Options:
    """The settings of ``given`` (an InspectionOptions) resolved against the model: the default
    evaluation distance, the face numbers checked."""
    pf = dict(given.per_face) or None
    tol = Tolerance.from_args(given.tolerance, given.lower, given.upper, pf)
    evaluation_distance = given.evaluation_distance
    if evaluation_distance is None:
        evaluation_distance = default_evaluation_distance(tol, prep.model.size)
    return _Options(tol, float(evaluation_distance), _check_faces(prep, given.faces),
                    MIN_COVERAGE if given.min_coverage is None else given.min_coverage,
                    MIN_POINTS if given.min_region_points is None else given.min_region_points,
                    MIN_INLIER_FRACTION if given.min_inlier_fraction is None
                    else given.min_inlier_fraction, given.missing)


def _check_faces(prep, faces) -> tuple | str | None:
    if faces is None or (isinstance(faces, str) and faces.strip().lower() == "all"):
        return None
    model = getattr(prep, "model", None)
    n_faces = len(getattr(model, "faces", ()) or ())
    seen = isinstance(faces, str) and faces.strip().lower() == "seen"
    if n_faces == 0:
        raise ValueError("faces= names CAD faces, but this model has none (a mesh or point-cloud "
                         "reference); inspect all of it instead" + (
                             ", or limit it to the part the scan saw with "
                             "shapeverify.partial.inspect_partial(prep, scan, seen=True)"
                             if seen else ""))
    if seen:
        return "seen"
    if isinstance(faces, str):
        faces = [f for f in faces.replace(",", " ").split() if f]
    out = []
    for f in faces:
        try:
            i = int(f)
        except (TypeError, ValueError):
            raise ValueError(f"faces must be face numbers 0..{n_faces - 1}, got {f!r}") from None
        if not 0 <= i < n_faces or (not isinstance(f, str) and i != f):
            raise ValueError(f"face {f!r} does not exist: the model has faces 0..{n_faces - 1} "
                             "(see `shapeverify info`)")
        out.append(i)
    supp = sorted(set(out) & set(getattr(model, "supplemental", ())))
    if supp:
        raise ValueError(f"face(s) {', '.join(map(str, supp))} are supplemental geometry (outside "
                         "the part's solid: no scan holds them); name faces of the part "
                         "(see `shapeverify info`)")
    if not out:
        raise ValueError("faces= is empty; name at least one face, or leave it out to inspect all")
    return tuple(sorted(set(out)))


def _model_size(prep):
    n_model = getattr(prep, "n_points", None)          # cheap; prep.points may be rebuilt
    if n_model is None:
        n_model = len(getattr(getattr(prep, "points", None), "points", (0,)))
    if n_model == 0:
        raise EmptyModelError("the prepared model has no surface points (a model without faces?)")
    model = getattr(prep, "model", None)
    return float(model.size) if model is not None and hasattr(model, "size") else None


def _strings(items) -> list[str]:
    """``items`` (None, a tuple of str, or an array of them) as a list of str."""
    return [] if items is None else [str(x) for x in list(items)]


def _evaluate(prep, scan, reg, opts: _Options, progress, timings) -> InspectionResult:
    """Deviations, coverage, regions, statistics and verdict of a registered scan."""
    _report(progress, "deviations", 0.6)
    t0 = time.perf_counter()
    T = np.asarray(reg.T_model_scan, dtype=np.float64)
    dev = _deviations(scan, prep, T, opts.evaluation_distance)
    seen_note = None
    if opts.faces == "seen":             # the faces the scan saw (coverage.seen_faces)
        feet = dev.foot_points[dev.evaluated]
        faces, seen_note = seen_faces(
            prep, feet, surface_spacing(feet, normals=dev.normals[dev.evaluated])
            if feet.shape[0] >= 2 else float("nan"),
            model_size=_model_size(prep))
        opts = dataclasses.replace(opts, faces=faces)
    if opts.faces is not None:
        dev = dev.restricted_to(opts.faces)
    timings["deviations"] = time.perf_counter() - t0

    _report(progress, "regions", 0.9)
    t0 = time.perf_counter()
    tol = opts.tol
    ev = dev.evaluated
    ev_feet = dev.foot_points[ev]
    # the spacing and the coverage are grid searches; the regions build their k-d tree of the
    # evaluated foot points only when there are out-of-tolerance points to look at
    spacing = surface_spacing(ev_feet, normals=dev.normals[ev]) if ev_feet.shape[0] >= 2 \
        else float("nan")
    within = tol.within(dev.values, dev.face)
    weights = getattr(reg, "weights", None)
    if weights is not None and np.shape(weights) != (scan.shape[0],):
        weights = None
    beside = beside_surface(dev)           # regions, material and floating surfaces share it
    regions, outliers, _ = find_regions(
        dev.foot_points, dev.values, ev, within, dev.face, dev.normals, weights,
        limits=tol.limits(dev.face),
        search=RegionSearch(min_points=opts.min_region_points, spacing=spacing,
                            far=far_over_surface(dev, beside)))
    # a bump taller (a dent deeper) than the evaluation distance: its flank's regions and the
    # surface beyond that continues them are one region, measured to its true height
    regions, outliers, joined = join_beyond(dev, regions, outliers, spacing,
                                            tol.limits(dev.face), within, beside, weights,
                                            min_points=opts.min_region_points)
    # material joins the part's measured surface: a measurement outlier inside the part (a
    # reflection copied into a blade) carries no material above it, nor does one lifted over
    # the surface with a step (a reflection's sheet); one rising from the surface can (the ramp
    # up to a corner that the CAD chamfers and the part does not)
    material = find_material(dev, spacing, tol.upper, beside=beside,
                             outliers=np.asarray(outliers.indices, np.int64))
    # CAD surface the scan sees through (issue 33 row 3): regions of kind "missing"
    missing = find_missing(prep, dev, spacing, within, tol, faces=opts.faces, seen_also=joined) \
        if opts.missing else []
    regions = sorted(regions + material + missing, key=lambda r: -r.severity)
    timings["regions"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    model_size = _model_size(prep)
    coverage = compute_coverage(prep, ev_feet, spacing, faces=opts.faces, model_size=model_size,
                                min_coverage=opts.min_coverage)
    timings["coverage"] = time.perf_counter() - t0

    inl = ev.copy()
    inl[outliers.indices] = False
    v, f, w = dev.values[inl], dev.face[inl], within[inl]
    above = v > 0
    stats = statistics(v, w, above)
    n_ev = int(np.count_nonzero(ev))
    if n_ev:
        # the values describe the part (outliers left out); the share in tolerance counts every
        # evaluated point, the outliers' share beside it (19 % outliers read "100 %" before)
        out_ev = ev & ~within
        n_hi = int(np.count_nonzero(out_ev & (dev.values > 0)))
        stats = dataclasses.replace(
            stats, in_tolerance_fraction=1.0 - np.count_nonzero(out_ev) / n_ev, n_above=n_hi,
            n_below=int(np.count_nonzero(out_ev)) - n_hi, outlier_fraction=outliers.n / n_ev)
    noise = _noise(dev, ev, getattr(reg, "noise", None))
    if v.size and f.min() == f.max():           # one face: its statistics are the overall ones
        per_face_stats = {int(f[0]): stats}
    else:
        per_face_stats = per_face_statistics(v, f, w, above) if v.size else {}
    n_material = int(sum(r.n for r in material))
    excluded = {"too_far": dev.n_too_far - n_material, "material": n_material,
                "on_boundary": dev.n_on_boundary, "outside_faces": dev.n_outside_faces,
                "outliers": outliers.n}

    verdict, reasons, rule = decide(reg, dev, regions, coverage,
                                    min_inlier_fraction=opts.min_inlier_fraction, noise=noise,
                                    tolerance=tol, n_outliers=outliers.n)
    notes = [] if seen_note is None else [seen_note]
    from shapeverify.cad.completeness import missing_faces_note  # issue 33 row 2
    if missing_faces_note(prep.model):
        notes.append(missing_faces_note(prep.model))
    hint = unit_hint(_bbox_diagonal(scan), model_size) if model_size else None
    if hint and verdict != "pass":
        notes.append(hint)
    if outliers.n:
        notes.append(f"{outliers.n} isolated out-of-tolerance points treated as measurement "
                     f"outliers ({outliers.n_low_weight} rejected by the registration) and left "
                     "out of the statistics")
    for fs in floating_surfaces(dev, spacing, beside=beside, exclude=joined)[:3]:
        from ..quantities import length_text, point_text

        lo, hi = fs["height"]
        notes.append(f"{fs['n']} scan points form a surface {length_text(lo)} to "
                     f"{length_text(hi)} above the CAD around {point_text(fs['centroid'])}, beyond the "
                     f"evaluation distance ({opts.evaluation_distance:g} mm): a reflection or a "
                     "foreign object? (not evaluated; raise the evaluation distance to evaluate it)")
    for d in _strings(getattr(reg, "undetermined", ())):
        notes.append(f"the scan does not fix the pose along: {d} (the deviations do not depend on it)")
    notes += [f"registration: {w}" for w in _strings(getattr(reg, "warnings", ()))]
    _report(progress, "done", 1.0)
    return InspectionResult(
        verdict=verdict, reasons=tuple(reasons) + tuple(notes), registration=reg, deviations=dev,
        statistics=stats, per_face=per_face_stats, regions=tuple(regions), outliers=outliers,
        tolerance=tol, timings=timings, scan_spacing=spacing, coverage=coverage, rule=rule,
        excluded=excluded, noise=noise)


#: Most evaluated scan points the noise is measured on.
NOISE_POINTS = 50_000


def _noise(dev, ev, known=None) -> float:
    """The scan's own noise sigma (mm) from its evaluated points (NaN when too few).

    ``known``: the noise the registration measured (``Registration.noise``, a
    :class:`~shapeverify.registration._noise.NoiseEstimate`), reused when every scan point is
    evaluated and it measured the same subsample: the evaluated points are then the
    registered scan's points moved rigidly, which leaves their scatter about local quadrics as
    it was (to round-off).  Else (some points not evaluated, a given pose, a registration
    without it) measured here."""
    from ..registration._noise import NoiseEstimate, scan_noise

    n = int(np.count_nonzero(ev))
    if isinstance(known, NoiseEstimate) and n == ev.shape[0] and known.reusable_for(
            n, NOISE_POINTS):
        return float(known.sigma)
    P = dev.points_model[ev]
    return float(scan_noise(P[::max(1, P.shape[0] // NOISE_POINTS)]))
