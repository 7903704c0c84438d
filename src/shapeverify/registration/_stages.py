"""The stages of :func:`~shapeverify.registration.register`, in the order it calls them.

``register`` (in :mod:`.icp`) checks its arguments into a :class:`Request` and then reads like
a recipe (compare KISS-ICP's ``register_frame``)::

    ctx = setup(request)                   # the start pose, scales, coarse subset, settings
    placed = initial_placement(ctx)        # coarse stage from the start (or a global search)
    fit = refine(ctx, placed.state)        # final stage + probe of the least-determined direction
    fit = retry_from_start(ctx, fit, placed)   # the final stage from the start itself
    fit = restart_about_axis(ctx, fit, placed) # spins about a near-symmetry axis
    quality = uncertainty(ctx, fit, placed)    # covariance, undetermined directions, warnings

Each stage takes the frozen :class:`Context` and the current :class:`Fit` and returns a new
one; the switches (probe, its rounds, restart, anneal) come from
:class:`~shapeverify.registration.options.RegistrationOptions`.  The random generator is
drawn from in this order: principal axes (``init='principal-axes'``), the coarse subset, the
global search, the final stage's verification subsets, the restart.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import _basin, _irls, _restart
from ._noise import NoiseEstimate, noise_of
from ._pose_warnings import (WARN_REJECTED_INFO, WARN_RUNNER_UP, _rejected_information,
                             close_runner_up, pose_warnings)
from .losses import Loss, get_loss
from .options import InitMode, Method, RegistrationOptions, StageSettings
from .rigid import pose_covariance, rotation_vector, undetermined_directions

from ..errors import RegistrationError

logger = logging.getLogger("shapeverify.registration.icp")

#: size of the random subset of the coarse stage (all points if the scan is smaller)
COARSE_SUBSET = 800
#: tolerance and iteration cap of the coarse stage
COARSE_TOL = 1e-4
STAGE_CAP = 60
#: scan points (a uniform subset) whose local scatter gives the scan's noise (:mod:`._noise`)
NOISE_POINTS = 200_000
#: "auto" keeps the identity when the coarse stage from it leaves at least this fit
#: (share of the subset on the surface, :func:`.global_search.fit_score`)
AUTO_FIT = 0.5
#: ... and turned the scan by less than this (deg): a scan that "already lies on the model" is
#: near its pose; one the coarse stage had to turn further was not, and the fit of where it
#: ended says little (NIST CTC 01 at random poses: 4 of 4 ended 180 deg off at fits of
#: 0.67-0.93, two with no warning); the global search then decides, the identity's end among
#: its hypotheses
AUTO_MAX_TURN = 30.0


@dataclass(frozen=True, eq=False)
class Request:
    """The checked arguments of :func:`~shapeverify.registration.register`."""

    scan: np.ndarray
    prep: object
    mode: InitMode
    init_pose: "np.ndarray | None"
    method: Method
    loss: Loss
    scale: "float | None"
    max_iterations: int
    rtol: float
    rng: np.random.Generator
    options: RegistrationOptions


@dataclass(frozen=True, eq=False)
class Context:
    """What every stage reads (built once by :func:`setup`)."""

    request: Request
    start: "np.ndarray | None"      # the start pose T0 (None only for 'global')
    how: str                        # how the start was found (Registration.init)
    radius: float                   # RMS radius of the scan about its centroid (mm)
    reach: "float | None"           # "far away" beyond this (mm) at the start
    coarse_points: np.ndarray       # the coarse stage's subset
    coarse: StageSettings
    final: StageSettings
    tau: float                      # the global search's fit distance (mm)
    noise_estimate: NoiseEstimate   # the scan's noise (:func:`._noise.noise_of`)

    @property
    def scan(self) -> np.ndarray:
        return self.request.scan

    @property
    def prep(self):
        return self.request.prep

    @property
    def options(self) -> RegistrationOptions:
        return self.request.options

    @property
    def rng(self) -> np.random.Generator:
        return self.request.rng

    @property
    def noise(self) -> float:
        """The scan's noise sigma (mm, :func:`._noise.scan_noise`)."""
        return self.noise_estimate.sigma


class Fit(NamedTuple):
    """A pose with its evaluation: the state every stage passes on."""

    state: _irls.State
    ev: _irls.Eval
    converged: bool
    why: str


class Placement(NamedTuple):
    """The end of :func:`initial_placement`."""

    state: _irls.State          # the coarse stage's end
    how: str                    # Registration.init
    search: object              # the GlobalAlignment, or None when no search ran
    start: "np.ndarray | None"  # the pose the final stage may restart from


class Quality(NamedTuple):
    """The end of :func:`uncertainty`."""

    covariance: np.ndarray
    undetermined: np.ndarray    # (k, 6) directions e = (rotation vector, translation)
    warnings: tuple
    alternatives: tuple


# ------------------------------------------------------------------------------ 0. setup
def setup(req: Request) -> Context:
    """The start pose (principal axes draw from ``rng``), the scan's scale, the coarse subset
    (drawn next) and the two stages' settings."""
    P, prep, mode = req.scan, req.prep, req.mode
    T0, how = req.init_pose, mode.value
    if mode is InitMode.PRINCIPAL_AXES:
        from .initial import principal_axes_alignment
        T0 = principal_axes_alignment(P, prep, rng=req.rng).T_model_scan
    elif mode in (InitMode.AUTO, InitMode.IDENTITY):
        T0 = np.eye(4)
        how = InitMode.IDENTITY.value
    n = P.shape[0]
    radius = float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1))))
    radius = max(radius, 1e-12)
    floor = 1e-9 * radius
    # "far away": beyond the prepared reach and a fifth of the model's size (ICP still works
    # from a start 10 % of the size off, farther than the default reach of 3 %)
    max_d = getattr(prep, "reach", None)
    size = getattr(getattr(prep, "model", None), "size", None)
    reach = None if max_d is None else max(float(max_d), 0.2 * float(size or 0.0))
    S = P if n <= COARSE_SUBSET else P[np.sort(req.rng.choice(n, COARSE_SUBSET, replace=False))]
    loss = req.loss
    convex = loss if loss.name in ("l2", "huber") else get_loss("huber")
    coarse = StageSettings(req.method.coarse, convex, req.scale, floor, radius,
                           min(req.max_iterations, STAGE_CAP), max(COARSE_TOL, req.rtol))
    final = StageSettings(req.method.final, loss, req.scale, floor, radius, req.max_iterations,
                          req.rtol, overlap=True)
    from .global_search import fit_distance
    return Context(req, T0, how, radius, reach, S, coarse, final, fit_distance(prep),
                   noise_of(P, NOISE_POINTS))


def _state(T, st=None) -> _irls.State:
    """A fresh IRLS state at pose T (carrying on ``st``'s iteration count and history)."""
    if st is None:
        return _irls.State(T[:3, :3].copy(), T[:3, 3].copy())
    return _irls.State(T[:3, :3].copy(), T[:3, 3].copy(), st.iterations, list(st.history))


def pose(st) -> np.ndarray:
    """T_model_scan of an IRLS state."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = st.R, st.t
    return T


# ------------------------------------------------------------------------------ 1. placement
def _far_away(ctx: Context):
    """The first matching's check: at least 6 scan points near the model at the start."""
    reach, max_d = ctx.reach, getattr(ctx.prep, "reach", None)

    def check(d, valid):
        if reach is not None and np.count_nonzero(valid & (np.abs(d) <= reach)) < 6:
            raise RegistrationError(
                f"fewer than 6 scan points lie within {reach:.4g} mm (the prepared reach "
                f"{max_d:.4g} mm, or a fifth of the model's size) of the model at the start "
                "pose: all points are far away.  Give a better init (e.g. init='auto' or "
                "'global'), check the units of scan and model, or prepare with a larger "
                "reach")
    return check


def coarse_stage(ctx: Context, T, check: bool) -> _irls.State:
    """The coarse stage from T: the convex loss on the coarse subset, re-matched every
    iteration (``check``: the reach test on the first matching)."""
    st = _state(T)
    _irls.stage_rematch("coarse", ctx.coarse_points, ctx.prep, st, ctx.coarse,
                        first=_far_away(ctx) if check else None, anneal=ctx.options.anneal)
    return st


def initial_placement(ctx: Context) -> Placement:
    """The coarse stage from the start; with 'auto', from the identity when it already lies
    on the model (fit >= AUTO_FIT, turned < AUTO_MAX_TURN), else -- and with 'global' -- from
    the global search's best hypothesis (the identity's end among them)."""
    mode = ctx.request.mode
    if mode not in (InitMode.AUTO, InitMode.GLOBAL):
        return Placement(coarse_stage(ctx, ctx.start, True), ctx.how, None, ctx.start)
    from .global_search import fit_distance, fit_score, global_alignment
    st, extra = None, ()
    if mode is InitMode.AUTO:
        try:
            st = coarse_stage(ctx, ctx.start, True)
            T_id = pose(st)
            turn = np.degrees(np.linalg.norm(rotation_vector(T_id[:3, :3])))
            if (turn > AUTO_MAX_TURN or fit_score(ctx.prep, ctx.coarse_points, T_id,
                                                  fit_distance(ctx.prep)) < AUTO_FIT):
                extra, st = (("identity+icp", T_id),), None
        except RegistrationError:
            st = None
    if st is not None:
        return Placement(st, ctx.how, None, None)
    ga = global_alignment(ctx.scan, ctx.prep, rng=ctx.rng, extra=extra)
    return Placement(coarse_stage(ctx, ga.T_model_scan, False), "global: " + ga.source, ga,
                     ga.T_model_scan)


# ------------------------------------------------------------------------------ 2. refine
def final_stage(ctx: Context, st) -> Fit:
    """The requested loss on every point (point-to-plane against verified tangent planes,
    or point-to-point re-matched every iteration)."""
    if ctx.final.method is Method.POINT_TO_PLANE:
        return Fit(st, *_irls.stage_final_plane(ctx.scan, ctx.prep, st, ctx.final, ctx.rng))
    return Fit(st, *_irls.stage_rematch("final", ctx.scan, ctx.prep, st, ctx.final))


def probe(ctx: Context, fit: Fit) -> Fit:
    """Another minimum along the least-determined direction (thin walls, :mod:`._basin`),
    refined by the final stage and taken when it fits better; up to ``probe_rounds`` rounds."""
    opts = ctx.options
    for _ in range(opts.probe_rounds if opts.probe else 0):
        ev, st = fit.ev, fit.state
        c0 = _irls.centroid(ev.X, ev.w)
        null0 = _irls.null_directions(ev, _irls.model_points(ctx.prep),
                                      _irls.system(ev.Y, ev.Y, ev.N, ev.w, c0)[0], c0,
                                      ctx.radius)
        sigma0, best, moved = ev.sigma, ev.objective, False
        for R_alt, t_alt in _basin.probe(ctx.scan, ctx.prep, ev, st.R, st.t, ctx.final, null0,
                                         ctx.tau):
            # carries on the iterations of the best pose so far (it may be an earlier alt)
            cur = fit.state
            alt = final_stage(ctx, _irls.State(R_alt, t_alt, cur.iterations, list(cur.history)))
            obj = _irls._mean_rho(alt.ev, sigma0)
            if obj < best:
                logger.info("registration: another minimum along the direction resting on "
                            "the fewest points fits better (objective %.4g < %.4g): taken",
                            obj, best)
                best, fit, moved = obj, alt, True
        if not moved:
            break
    return fit


def refine(ctx: Context, st) -> Fit:
    """The final stage from ``st``, then the probe."""
    return probe(ctx, final_stage(ctx, st))


def _better(fit: Fit, alt: Fit) -> "tuple[bool, float, float]":
    """``alt`` fits better: compared at the sharper of the two robust scales (the right pose
    fits to the noise level, a wrong minimum only loosely; at its own broad scale both look
    alike).  Returns (better, objective of alt, objective of fit)."""
    s0 = min(fit.ev.sigma, alt.ev.sigma)
    obj, obj0 = _irls._mean_rho(alt.ev, s0), _irls._mean_rho(fit.ev, s0)
    return obj < obj0, obj, obj0


# ------------------------------------------------------------------------------ 3. retry
def retry_from_start(ctx: Context, fit: Fit, placed: Placement) -> Fit:
    """The final stage from the start itself, kept when it fits better, where the points the
    robust loss rejected hold more information than the kept ones.

    The coarse stage's subset can drift along a direction that few points fix (a flat face
    seen from above: the outline fixes the slide and spin; 0.2 deg from the true pose) and the
    final stage then rejects the points that would bring it back."""
    if placed.start is None or (_rejected_information(fit.ev, fit.ev.w, ctx.radius)
                                <= WARN_REJECTED_INFO):
        return fit
    alt = refine(ctx, _state(placed.start, fit.state))
    if _better(fit, alt)[0]:
        logger.info("registration: the final stage from the start fits better than from "
                    "the coarse stage's end: taken")
        return alt
    return fit


# ------------------------------------------------------------------------------ 4. restart
def determined(ctx: Context, ev) -> bool:
    """The data determine every pose direction (no free spin or slide)."""
    c = _irls.centroid(ev.X, ev.w)
    H, _ = _irls.system(ev.Y, ev.Y, ev.N, ev.w, c)
    return _irls.null_directions(ev, _irls.model_points(ctx.prep), H, c,
                                 ctx.radius).shape[0] == 0


def restart_about_axis(ctx: Context, fit: Fit, placed: Placement) -> Fit:
    """Spin restarts about the model's near-symmetry axis (:mod:`._restart`) of a pose flagged
    as a wrong minimum (not converged, or a warning), or found by the global search, on a
    near-axisymmetric part; the best copy is refined and kept when it fits better.

    The global search's hypotheses hold few spins, and a wrong spin can fit its subset well
    enough to pass every check (an impeller seen at an angle: 31 deg off at 16 x the noise,
    converged, no warning).  A free spin or slide is not a wrong minimum: no restart where the
    data leave one."""
    if not ctx.options.restart:
        return fit
    suspect = not fit.converged or any(True for _ in pose_warnings(
        fit.ev, fit.ev.w, None, ctx.tau, ctx.radius, noise=ctx.noise))
    if not ((suspect or (placed.search is not None and _restart._model_axis(ctx.prep) is not None))
            and determined(ctx, fit.ev)):
        return fit
    T_alt = _restart.restart(ctx.scan, ctx.prep,
                             ctx.start if ctx.start is not None else np.eye(4),
                             pose(fit.state), ctx.radius, ctx.rng, in_place=not suspect)
    if T_alt is None:
        return fit
    alt = refine(ctx, _state(T_alt, fit.state))
    better, obj, obj0 = _better(fit, alt)
    if better:
        logger.info("registration: the restart about the model's near-symmetry axis "
                    "fits better (objective %.4g < %.4g): taken", obj, obj0)
        return alt
    return fit


# ------------------------------------------------------------------------------ 5. quality
def uncertainty(ctx: Context, fit: Fit, placed: Placement) -> Quality:
    """The pose's covariance (sandwich estimate), the directions the data leave undetermined,
    the signs of a wrong minimum (:func:`._pose_warnings.pose_warnings`) and the global
    search's alternatives that fit nearly as well."""
    ev, w, prep, radius = fit.ev, fit.ev.w, ctx.prep, ctx.radius
    center = _irls.centroid(ev.X, w)
    H, _ = _irls.system(ev.Y, ev.Y, ev.N, w, center)
    mp = _irls.model_points(prep)
    undet_c = _irls.null_directions(ev, mp, H, center, radius)
    if undet_c.shape[0]:
        Q, Nq = _irls.information_points(ev, mp)
    else:
        Q, Nq = ev.Y, ev.N
    undet = undetermined_directions(undet_c, center, radius)
    cov = pose_covariance(Q, Nq, ev.d, w, center, radius, undet,
                          loss=ev.loss if ev.sigma > 0 else None, sigma=ev.sigma)
    T = pose(fit.state)
    ga = placed.search
    notes = tuple(pose_warnings(ev, w, ga, ctx.tau, radius, T, undet, ctx.noise, prep=prep))
    return Quality(cov, undet, notes, _alternatives(ga, T, undet, ctx.tau, radius))


def _alternatives(ga, T, undet, tau, radius) -> tuple:
    """The global search's other poses that fit nearly as well as its best (at least
    WARN_RUNNER_UP of its fit), when the runner-up is one that is not a free spin of T."""
    if not close_runner_up(ga, T, undet, tau, radius):
        return ()
    return tuple(np.array(P) for f, P in ga.others if f >= WARN_RUNNER_UP * ga.fit)
