"""Tolerances, deviation statistics and the verdict.

The verdict rules (:func:`decide`), in order; the first that applies decides, and its name is
the result's ``rule``:

1. ``error`` (rule ``no_data``): no scan point lies within the evaluation distance of the
   inspected CAD faces (wrong scan, wrong model, failed registration, or a scan nowhere near the
   part);
2. ``error`` (rule ``registration``): the registration did not converge and its robust
   residual scale exceeds the evaluation distance: the scan fits the model at no pose found (a
   wrong part, a wrong scan, wrong units);
2b. ``error`` (rule ``registration``): the registration says its pose is a wrong minimum -- the
   scan fits better elsewhere (a warning whose ``wrong_minimum`` is True, :func:`_wrong_minimum`);
   checked before the coverage, which a wrong pose spoils;
3. ``incomplete`` (rule ``coverage``): less than ``min_coverage`` (default 20 %) of the inspected
   CAD area has evaluated scan points near it (:mod:`.coverage`). A part that was not seen is never
   passed and never failed; the reasons say how much was seen, where the largest gap is, whether
   out-of-tolerance regions were found in what was seen, and any registration problem (a small
   patch often cannot fix the pose: that too is a matter of not having seen enough);
4. ``error`` (rule ``registration``): the registration is not trustworthy: it did not converge,
   or its inlier fraction is below ``min_inlier_fraction`` (default 0.25);
5. ``fail`` (rule ``regions``): at least one region fails the part: a connected out-of-tolerance
   surface area (``kind="deviation"``, :mod:`.regions`) or measured material where the CAD has
   none (``kind="material"``, :mod:`.material`), or CAD surface the scan sees through, a hole
   or cut-out the CAD does not have (``kind="missing"``, :mod:`.missing`, on by default: the
   scan sees points *behind* that surface; surface merely not seen only lowers the coverage);
6. ``incomplete`` (rule ``undecided``): no region fails the part, but the measurement cannot
   decide that it conforms (ISO 14253-1: conformance is proven only inside the tolerance zone
   reduced by the measurement uncertainty): the scan's own noise (sigma about local quadrics,
   :func:`shapeverify.registration._noise.scan_noise`) exceeds ``MAX_NOISE_SHARE`` (0.6) of
   the tolerance zone's half width h -- the surface is judged by neighbourhood medians of about
   9 points, whose expanded uncertainty is ``U = 2 x 1.25 sigma / 3 = 0.84 sigma``: at
   ``sigma = 0.6 h`` it takes half the zone's half width -- or more than ``MAX_OUTLIER_SHARE``
   (10 %) of the evaluated points are
   out of tolerance as isolated outliers (a scan with 0.15 mm noise at +-0.2 mm: 19 % of its
   points, which passed as "isolated outliers");
7. ``pass`` (rule ``within_tolerance``) otherwise. Isolated out-of-tolerance points (measurement
   outliers) are counted and reported but do not fail the part.

Rules 1-7 are the functions of :data:`RULES`, in order (a new rule is one function put in its
place there).  Two rules act on the result of rules 1-7:

8. with an inspection plan (:mod:`shapeverify.characteristics`): a failing characteristic fails
   a passing part (rule ``characteristics``), an undecided one makes it ``incomplete`` (rule
   ``undecided``); error and incomplete stand (:func:`with_characteristics_rule`; applied by
   :func:`shapeverify.inspection.plan_link.with_characteristics`);
9. a near-symmetric copy: a part failed at the registration's pose passes when an alternative
   pose fits the scan alike and passes it (:func:`symmetric_copy_applies`,
   :func:`symmetric_copy_fits_alike`; the fits are computed in :mod:`.ambiguity`).

Every verdict value has one row in :data:`VERDICT_TABLE` (exit code, report colour, word,
terminal colour, severity): the CLI's exit codes, the HTML, PNG and PDF reports, the history's
SQL CHECK and batch's counts read it.  Exit codes of ``shapeverify inspect``: 0 pass, 1 fail,
2 error, 3 incomplete.

References
----------
Bergström (2011), Paper III; ISO 1101 (profile of a surface: a tolerance zone between two offset
surfaces, here ``lower <= deviation <= upper`` along the CAD normal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Tolerance", "Statistics", "statistics", "per_face_statistics", "decide",
           "Verdict", "VERDICTS", "VERDICT_TABLE", "VerdictStyle", "verdict_style", "most_severe",
           "RULES", "with_characteristics_rule", "symmetric_copy_applies",
           "symmetric_copy_fits_alike", "SYMMETRIC_COPY_SHARE", "MIN_INLIER_FRACTION", "MAX_NOISE_SHARE", "MAX_OUTLIER_SHARE"]


from ..measures.tolerance import Tolerance, _check_pair, _limit  # noqa: F401 (re-exported)
from ..verdict_table import (VERDICT_TABLE, VERDICTS, Verdict, VerdictStyle, most_severe,
                             verdict_style)

#: Default least inlier fraction of the registration.
MIN_INLIER_FRACTION = 0.25
#: Largest scan noise sigma, as a share of the tolerance zone's half width, that can pass a part
#: (the surface's neighbourhood-median uncertainty U = 0.84 sigma then reaches half of it; a
#: clean scan at +-2 sigma passes, 0.15 mm noise at +-0.2 mm cannot).
MAX_NOISE_SHARE = 0.6
#: Largest share of the evaluated points that may be isolated out-of-tolerance outliers in a pass.
MAX_OUTLIER_SHARE = 0.10


@dataclass(frozen=True)
class Statistics:
    """Summary of signed deviations (mm); NaN fields when ``n == 0``."""

    n: int
    mean: float
    std: float
    rms: float
    min: float
    max: float
    p05: float
    p95: float
    in_tolerance_fraction: float
    n_above: int = 0   # points above the upper limit
    n_below: int = 0   # points below the lower limit
    #: share of the evaluated points that are isolated out-of-tolerance outliers (an
    #: inspection's statistics; their in_tolerance_fraction counts every evaluated point)
    outlier_fraction: float = 0.0

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and math.isnan(v) else v)
                for k, v in self.__dict__.items()}

    def __repr__(self) -> str:
        return (f"Statistics(n={self.n}, mean={self.mean:+.4f}, std={self.std:.4f}, "
                f"min={self.min:+.4f}, max={self.max:+.4f}, p05={self.p05:+.4f}, p95={self.p95:+.4f}, "
                f"in_tolerance={100 * self.in_tolerance_fraction:.2f}%"
                + (f", outliers={100 * self.outlier_fraction:.2f}%" if self.outlier_fraction else "")
                + ")")


def statistics(values: np.ndarray, within: np.ndarray | None = None,
               above: np.ndarray | None = None) -> Statistics:
    """Statistics of evaluated deviations.

    Parameters
    ----------
    values : (n,) float64
        Finite deviations (only the evaluated ones).
    within : (n,) bool, optional
        Which values are inside their tolerance zone.
    above : (n,) bool, optional
        Which of the out-of-tolerance values lie above the upper limit (the rest: below).
    """
    n = int(values.shape[0])
    if n == 0:
        nan = float("nan")
        return Statistics(0, nan, nan, nan, nan, nan, nan, nan, nan)
    p05, p95 = np.percentile(values, [5.0, 95.0])
    n_in = n if within is None else int(np.count_nonzero(within))
    if within is None:
        n_above = n_below = 0
    else:
        out = ~within
        n_above = int(np.count_nonzero(out & above)) if above is not None else 0
        n_below = int(np.count_nonzero(out)) - n_above
    return Statistics(
        n=n, mean=float(values.mean()), std=float(values.std()),
        rms=float(np.sqrt(np.mean(values * values))), min=float(values.min()),
        max=float(values.max()), p05=float(p05), p95=float(p95),
        in_tolerance_fraction=n_in / n, n_above=n_above, n_below=n_below)


def per_face_statistics(values: np.ndarray, face: np.ndarray, within: np.ndarray,
                        above: np.ndarray) -> dict[int, Statistics]:
    """:func:`statistics` for each face that has evaluated points: ``{face: Statistics}``."""
    if face.shape[0] and face.min() == face.max():     # one face: its points are all of them
        return {int(face[0]): statistics(values, within, above)}
    order = np.argsort(face, kind="stable")
    f_sorted = face[order]
    faces, starts = np.unique(f_sorted, return_index=True)
    bounds = np.append(starts, f_sorted.shape[0])
    out = {}
    for k, f in enumerate(faces):
        idx = order[bounds[k]:bounds[k + 1]]
        out[int(f)] = statistics(values[idx], within[idx], above[idx])
    return out


@dataclass(frozen=True)
class _Facts:
    """What the inspection rules of :func:`decide` read (one object: a rule is one function)."""

    registration: object
    deviations: object
    regions: tuple
    coverage: object
    min_inlier_fraction: float
    noise: float | None
    tolerance: object
    n_outliers: int
    errors: tuple           # the registration's problems (rules 2 and 4), in words

    @property
    def listed(self) -> list[str]:
        listed = [f"region {i + 1}: {r.describe()}" for i, r in enumerate(self.regions[:5])]
        if len(self.regions) > 5:
            listed.append(f"... and {len(self.regions) - 5} more regions")
        return listed


def _registration_errors(registration, min_inlier_fraction: float) -> tuple[str, ...]:
    errors = []
    if registration is not None:
        if not bool(registration.converged):
            msg = getattr(registration, "message", "") or ""
            errors.append(f"registration did not converge after {registration.iterations} iterations"
                          + (f" ({msg})" if msg else ""))
        inl = float(registration.inlier_fraction)
        if not inl >= min_inlier_fraction:
            errors.append(f"registration inlier fraction {100 * inl:.1f} % is below the required "
                          f"{100 * min_inlier_fraction:.0f} % (scan does not match the model)")
    return tuple(errors)


def _rule_no_data(f: _Facts):
    dev = f.deviations
    if dev.n_evaluated == 0:
        return Verdict.ERROR, (f"no scan point lies within {dev.evaluation_distance:g} mm "
                               f"(the evaluation distance) of the inspected CAD faces ({dev.n_too_far} of {dev.n} too "
                               f"far, {dev.n_on_boundary} past the CAD's edges); is this the right "
                               "scan and model?",) + f.errors, "no_data"
    return None


def _rule_does_not_fit(f: _Facts):
    reg, dev = f.registration, f.deviations
    scale = float(getattr(reg, "scale", float("nan"))) if reg is not None else float("nan")
    if f.errors and not bool(reg.converged) and scale > dev.evaluation_distance:
        # not a patch too small to fix the pose: the scan fits the model at no pose found
        return Verdict.ERROR, (f"the scan does not fit the model: at the best pose found its "
                               f"robust residual scale is {scale:.3g} mm, more than the "
                               f"evaluation distance {dev.evaluation_distance:g} mm (a wrong "
                               "part, a wrong scan or wrong units?)",) + f.errors, \
            "registration"
    return None


def _rule_wrong_minimum(f: _Facts):
    """Rule 2b: a pose the scan fits better elsewhere than at (a wrong-minimum warning of the
    registration) is an error of the registration, not a part that was not seen (issue 30)."""
    wrong = _wrong_minimum(f.registration)
    if not wrong:
        return None
    return Verdict.ERROR, (f"the registration ended in a wrong minimum: {wrong[0]}",) \
        + tuple(wrong[1:]) + f.errors, "registration"


def _rule_coverage(f: _Facts):
    coverage, regions = f.coverage, f.regions
    if coverage is None or coverage.sufficient:
        return None
    from ..quantities import area_text

    why = (f"incomplete: only {100 * coverage.fraction:.1f} % of the inspected CAD area "
           f"({area_text(coverage.covered_area)} of {area_text(coverage.area)}) has evaluated "
           f"scan points; "
           f"at least {100 * coverage.min_coverage:.0f} % must be seen to pass or fail the part")
    gap = coverage.describe_gap()
    reasons = [why] + ([gap] if gap else []) + list(f.errors)
    if regions:
        reasons.append(f"{len(regions)} region{'s' if len(regions) > 1 else ''} out of tolerance "
                       "in the part that was seen:")
        reasons += f.listed
    return Verdict.INCOMPLETE, tuple(reasons), "coverage"


def _rule_registration(f: _Facts):
    return (Verdict.ERROR, f.errors, "registration") if f.errors else None


def _rule_regions(f: _Facts):
    regions = f.regions
    if not regions:
        return None
    n_mat = sum(1 for r in regions if getattr(r, "kind", "deviation") == "material")
    n_mis = sum(1 for r in regions if getattr(r, "kind", "deviation") == "missing")
    n_dev = len(regions) - n_mat - n_mis
    parts = ([f"{n_dev} out-of-tolerance region{'s' if n_dev != 1 else ''}"] if n_dev else []) + \
            ([f"{n_mat} region{'s' if n_mat != 1 else ''} of material the CAD does not have"]
             if n_mat else []) + \
            ([f"{n_mis} region{'s' if n_mis != 1 else ''} of CAD surface the scan sees "
              "through (material missing)"] if n_mis else [])
    return Verdict.FAIL, tuple([f"fail: {' and '.join(parts)} (most severe first)"] + f.listed), \
        "regions"


def _rule_undecided(f: _Facts):
    why = _undecided(f.noise, f.tolerance, f.n_outliers, f.deviations.n_evaluated)
    return (Verdict.INCOMPLETE, tuple(why), "undecided") if why else None


def _rule_within_tolerance(f: _Facts):
    coverage, n_eval = f.coverage, f.deviations.n_evaluated
    seen = f"; {100 * coverage.fraction:.1f} % of the inspected area seen" if coverage is not None else ""
    return Verdict.PASS, (f"pass: all {n_eval} evaluated points are within tolerance except isolated "
                          f"measurement outliers{seen}",), "within_tolerance"


#: The inspection's rules in order (module docstring, rules 1-7): each takes the facts and gives
#: ``(verdict, reasons, rule)`` or None (does not apply); the first that applies decides.  A new
#: rule is one function inserted here at its place (e.g. a rule of its own for missing material
#: would go between ``_rule_registration`` and ``_rule_regions``).
RULES = (_rule_no_data, _rule_does_not_fit, _rule_wrong_minimum, _rule_coverage,
         _rule_registration,
         # slot: a rule for missing material (inspection/missing.py) goes here, before regions
         _rule_regions, _rule_undecided, _rule_within_tolerance)


def decide(registration, deviations, regions, coverage=None, *,
           min_inlier_fraction: float = MIN_INLIER_FRACTION, noise: float | None = None,
           tolerance=None, n_outliers: int = 0) -> tuple[Verdict, tuple[str, ...], str]:
    """The verdict, its reasons and the rule that decided (see the module docstring; the rules
    are :data:`RULES`, in order).

    Parameters
    ----------
    registration : object with ``converged``, ``inlier_fraction``, ``iterations``, ``message``
        (None: the pose was given, nothing to check)
    deviations : Deviations
    regions : sequence of DefectRegion
        Deviation and material regions, most severe first.
    coverage : Coverage, optional
        None: the coverage rule is not applied.
    noise : float, optional
        The scan's own noise sigma (mm); with ``tolerance``, rule 6 (``undecided``).
    tolerance : Tolerance, optional
        The tolerance zone (its narrowest per-face zone is the yardstick of the noise).
    n_outliers : int
        Isolated out-of-tolerance points (measurement outliers) among the evaluated points.

    Returns
    -------
    verdict : Verdict
    reasons : tuple of str
        Why; the first says which rule decided.
    rule : {'registration', 'no_data', 'coverage', 'regions', 'undecided', 'within_tolerance'}
    """
    facts = _Facts(registration, deviations, tuple(regions), coverage, min_inlier_fraction,
                   noise, tolerance, n_outliers,
                   _registration_errors(registration, min_inlier_fraction))
    for rule in RULES:
        decision = rule(facts)
        if decision is not None:
            return decision
    raise AssertionError("the last rule (within_tolerance) always applies")   # pragma: no cover


def with_characteristics_rule(verdict, rule: str, reasons, failed, undecided):
    """Rule 8, the plan's: the inspection's verdict combined with its characteristics' (names of
    the failed and the undecided ones).  A failing characteristic fails a passing part (rule
    ``characteristics``), an undecided one (ISO 14253-1) makes it ``incomplete`` (rule
    ``undecided``); error and incomplete verdicts stand.

    Returns
    -------
    verdict, rule, reasons : Verdict, str, tuple of str
    """
    reasons = list(reasons)
    lines = []
    if failed:
        lines.append(f"characteristic{'s' if len(failed) > 1 else ''} out of tolerance: "
                     f"{', '.join(failed)}")
    if undecided:
        lines.append(f"characteristic{'s' if len(undecided) > 1 else ''} that cannot be decided "
                     f"within the measurement uncertainty (ISO 14253-1): {', '.join(undecided)}")
    if verdict in (Verdict.PASS, Verdict.FAIL) and failed:
        if verdict == Verdict.PASS:
            verdict, rule = Verdict.FAIL, "characteristics"
            reasons = [f"fail: {lines[0]}"] + lines[1:] + reasons[1:]
        else:
            reasons = reasons[:1] + lines + reasons[1:]
    elif verdict == Verdict.PASS and undecided:
        verdict, rule = Verdict.INCOMPLETE, "undecided"
        reasons = [f"incomplete: {lines[0]}"] + reasons[1:]
    else:
        reasons = reasons[:1] + lines + reasons[1:]
    return verdict, rule, tuple(reasons)


#: Rule 9: two poses fit the scan alike when the worse fit is at least this share of the better
#: one (the registration's own rule for "another start fits nearly as well").
SYMMETRIC_COPY_SHARE = 0.97


def symmetric_copy_applies(first, other) -> bool:
    """Rule 9, the symmetric copy's, first part: may an inspection at an alternative pose
    (``other``, its verdict) replace the first (``first``)?  Only a failed part that the
    alternative passes (then :func:`symmetric_copy_fits_alike` decides)."""
    return str(first) == Verdict.FAIL and str(other) == Verdict.PASS


def symmetric_copy_fits_alike(fit_first: float, fit_other: float) -> bool:
    """Rule 9, second part: the alternative's fit of the scan (:mod:`.ambiguity` computes it) is
    at least :data:`SYMMETRIC_COPY_SHARE` of the first pose's: its pass is the result."""
    return not fit_other < SYMMETRIC_COPY_SHARE * fit_first


def _wrong_minimum(registration) -> list[str]:
    """Rule 2b ``wrong_minimum`` (issue 30): the registration's warnings that say the scan fits
    better elsewhere than at its pose (``PoseWarning.wrong_minimum``, see
    :mod:`shapeverify.registration._pose_warnings`).  Such a pose is ``error (registration)``,
    never ``incomplete (coverage)``: its small coverage is the pose's fault, not the scan's."""
    if registration is None:
        return []
    return [str(w) for w in (getattr(registration, "warnings", ()) or ())
            if getattr(w, "wrong_minimum", False)]


def _undecided(noise, tolerance, n_outliers: int, n_eval: int) -> list[str]:
    """Why the measurement cannot decide that the part conforms (rule 6), or []."""
    why = []
    if tolerance is not None and noise is not None and np.isfinite(noise):
        zones = [(tolerance.lower, tolerance.upper)] + [(lo, hi) for _, lo, hi in tolerance.per_face]
        half = min((hi - lo) / 2.0 for lo, hi in zones)
        if noise > MAX_NOISE_SHARE * half:
            why.append(f"the scan's own noise (sigma {noise:.3g} mm; the surface's expanded "
                       f"uncertainty U = 0.84 sigma = {0.84 * noise:.3g} mm) is "
                       f"{noise / half:.2f} of the tolerance zone's half width {half:.3g} mm "
                       f"(more than {MAX_NOISE_SHARE:.2f})")
    share = n_outliers / n_eval if n_eval else 0.0
    if share > MAX_OUTLIER_SHARE:
        why.append(f"{100 * share:.1f} % of the {n_eval} evaluated points are out of tolerance "
                   f"as isolated outliers (more than {100 * MAX_OUTLIER_SHARE:.0f} %)")
    if why:
        why.insert(0, "undecided (ISO 14253-1): no region fails the part, but the measurement "
                      "uncertainty does not allow a decision that it conforms")
        why.append("measure with less noise (or a wider tolerance) to decide")
    return why
