"""Robust ICP registration of a scan to a prepared model (IRLS-ICP, thesis ch. 5-6, Paper II).

``register`` finds ``T_model_scan`` (model = R @ scan + t) minimising ``sum_k rho(d_k)``, with
``d_k`` the signed distance of the moved scan point k to its closest model point, by iteratively
re-weighted least squares: closest points, a robust scale ``sigma = 1.4826 * median |d|``, the
weights ``w(d) = rho'(d)/d`` with the 95 %-efficiency constant ``k = c * sigma`` (so nobody
tunes k), and a weighted rigid step -- point-to-plane (thesis eq. 12-13) or point-to-point
(eq. 7-10).  Scan points whose closest model point lies on the model's free boundary get
weight 0 (the scan runs past the CAD's edge).

Stages, each a function of :mod:`shapeverify.registration._stages` that :func:`register` calls
in this order (see :mod:`shapeverify.registration._irls` for the iterations and the
convergence test):

1. ``initial_placement`` -- *coarse*: Huber (convex: one optimum, so it works from a rough
   fixture's misalignment, where a redescending loss would reject the very points that must
   pull the scan into place) on a random subset of 800 points, re-matched every iteration,
   from the start (with no start, from the identity or the global search's best hypothesis);
2. ``refine`` -- *final*: the requested loss on every point.  Point-to-plane iterates against
   the tangent planes of one matching and then verifies them by re-matching a random subset
   (re-matching everything only when that asks for a correction); point-to-point re-matches
   every iteration, with Anderson acceleration.  Then *other minima* (``probe``): the pose
   direction resting on the fewest points (90 % of its information on at most 10 % of them:
   an impeller's spin on its thin blades) is probed for another minimum
   (:mod:`shapeverify.registration._basin`); a better one found is refined by the final stage
   and kept only if it fits all points better;
3. ``retry_from_start``: where the points the robust loss rejected hold more information than
   the kept ones, the final stage also runs from the start itself, kept if it fits better;
4. ``restart_about_axis`` -- *restarts*: a pose still flagged as a wrong minimum (not
   converged, or a warning of ``Registration.warnings``) of a part that is nearly a solid of
   revolution (an impeller, whose hub leaves x, y and the spin to the few blade points, so a
   start half a blade pitch off converges onto the wrong blades) is restarted from spins about
   the model's own near-symmetry axis (:mod:`shapeverify.registration._restart`); of the
   copies that fit alike, the one nearest the start is refined by the final stage and kept
   only if it fits better (at the sharper of the two robust scales);
5. ``uncertainty``: the covariance, the undetermined directions and the warnings.

The switches (probe and its rounds, restart, the graduated coarse scale) are the fields of
:class:`~shapeverify.registration.options.RegistrationOptions`.

The final stage's robust scale is overlap-aware (:func:`._irls.overlap_scale`): when most of a
partial view lies off the reference (a point cloud has no outline to exclude them), the scale
of the residuals near zero replaces the broken-down MAD scale.

Only the final stage decides ``converged`` (the test is stated in :func:`register`'s Notes).
With no start (``init=None``, 'auto'), the identity is kept when the coarse stage from it fits
without turning the scan by more than :data:`AUTO_MAX_TURN`, otherwise
:mod:`shapeverify.registration.global_search` finds the start.  ``rng`` defaults to
a fixed seed: identical input gives bit-identical results in every run and process.
"""
from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._arrays import check_points
from .._random import generator

from . import _stages
# the stages' constants (the stages themselves and their switches: :mod:`._stages`)
from ._stages import AUTO_FIT, AUTO_MAX_TURN, COARSE_SUBSET, NOISE_POINTS  # noqa: F401
from ._irls import IterationRecord
from .losses import get_loss
from .options import InitMode, InitName, LossName, Method, MethodName, RegistrationOptions

from .._renamed import renamed_keywords
from ..errors import RegistrationError, ScanError  # noqa: F401 (initial.py's)

__all__ = ["register", "Registration", "IterationRecord", "DegenerateGeometryWarning"]

logger = logging.getLogger(__name__)

class DegenerateGeometryWarning(UserWarning):
    """The scan's geometry does not determine every pose direction (flat or cylindrical scan)."""


@dataclass(frozen=True, eq=False, repr=False)
class Registration:
    """Result of :func:`register`.

    Attributes
    ----------
    T_model_scan : (4, 4) float64
        model_point = R @ scan_point + t.
    rms : float
        RMS residual (signed distance) of the inliers at the final pose (mm).
    iterations : int
        Rigid steps taken over all stages.
    converged : bool
        True when the final stage met the tolerance; False when it hit ``max_iterations`` or
        its closest points kept changing (``message`` says which).
    weights : (N,) float64
        Final IRLS weights in [0, 1] (0 where the closest model point is on the model's free
        boundary).
    inlier_fraction : float
        Fraction of scan points with a valid closest point and ``|d| <= k = c * sigma``.
    covariance : (6, 6) float64
        Covariance of the pose error ``e = (rotation vector rad, translation mm)`` acting on the
        left in model coordinates (``T_true ~ exp(e) @ T_model_scan``): the sandwich estimate of
        :func:`~shapeverify.registration.rigid.pose_covariance`; ``inf`` in the entries an
        undetermined direction touches.
    history : tuple of IterationRecord
        One record per evaluation (stage, loss, scale, objective, step, re-matched or not).
    scale : float
        Final robust scale sigma (mm).
    message : str
    undetermined : tuple of str
        The pose directions the data leave undetermined (empty normally), one readable line
        each, in model coordinates (mm): e.g. ``"rotation about axis [0.000, 0.000, 1.000]
        through (0, 0, 0)"`` (a turned part's spin) or ``"translation along [1.000, 0.000,
        0.000]"`` (a plate's slide).  The deviations do not depend on these motions.
    method, loss : str
    undetermined_directions : (k, 6) float64
        The same directions as unit vectors ``e = (rotation vector, translation)`` in the
        parameterisation of ``covariance`` (model frame, about the model origin); e.g.
        ``(0, 0, 0, 1, 0, 0)`` is sliding along x.
    warnings : tuple of str
        Signs that the pose may not be the right minimum although the iterations stopped (a low
        inlier fraction, a systematic mean residual, another start that fits about as well).
        Empty for a clean registration.
    init : str
        How the start was found: ``"given"`` (a 4x4 init), ``"identity"``,
        ``"principal-axes"``, or ``"global: <hypothesis>"`` (see
        :func:`shapeverify.registration.global_search.global_alignment`).
    alternatives : tuple of (4, 4) float64
        Other poses that fit nearly as well: the global search's refined hypotheses within the
        runner-up rule of its best when the warning "another start fits nearly as well" is
        given (symmetric copies, or the true pose when this one is a copy), else ().  Where
        this pose fails the part, :func:`shapeverify.inspect` registers from each and passes
        the part at one that fits alike and puts every point within tolerance.
    noise : NoiseEstimate or None
        The scan's own noise that the registration measured (its yardstick of a wrong minimum,
        :func:`shapeverify.registration._noise.noise_of`) and the subsample it measured it on;
        the inspection reuses it where it would measure the same points.
    """

    T_model_scan: np.ndarray
    rms: float
    iterations: int
    converged: bool
    weights: np.ndarray
    inlier_fraction: float
    covariance: np.ndarray
    history: tuple = field(default=())
    scale: float = float("nan")
    message: str = ""
    undetermined: tuple = ()
    method: MethodName = "point-to-plane"
    loss: LossName = "tukey"
    undetermined_directions: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    warnings: tuple = ()
    init: str = "given"
    alternatives: tuple = ()
    noise: object = None

    @property
    def R(self) -> np.ndarray:
        """Rotation (3, 3) of T_model_scan."""
        return self.T_model_scan[:3, :3]

    @property
    def t(self) -> np.ndarray:
        """Translation (3,) of T_model_scan."""
        return self.T_model_scan[:3, 3]

    def __repr__(self) -> str:
        return (f"Registration(method={self.method!r}, loss={self.loss!r}, rms={self.rms:.4g}, "
                f"scale={self.scale:.3g}, iterations={self.iterations}, "
                f"converged={self.converged}, inlier_fraction={self.inlier_fraction:.3f}, "
                f"n={self.weights.shape[0]}, undetermined={len(self.undetermined)}, "
                f"warnings={len(self.warnings)}, init={self.init!r})")


# ------------------------------------------------------------------------------ validation
def _check_scan(scan) -> np.ndarray:
    P = check_points(scan, "scan", single=False, error=ScanError)
    if P.shape[0] < 6:
        raise ScanError(f"scan has {P.shape[0]} points; registration needs at least 6 "
                        "(six pose parameters)")
    return P


def validate_pose(T, what: str = "init") -> np.ndarray:
    """A rigid (4, 4) T_model_scan, re-orthonormalised; ValueError naming what is wrong."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"{what} must be a (4, 4) T_model_scan, got shape {T.shape}")
    if not np.isfinite(T).all():
        raise ValueError(f"{what} contains NaN/inf")
    R = T[:3, :3]
    if (not np.allclose(T[3], [0, 0, 0, 1], atol=1e-9)
            or not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0):
        raise ValueError(f"{what} must be a rigid transform: orthonormal R with det +1 and "
                         "last row [0, 0, 0, 1]")
    U, _, Vt = np.linalg.svd(R)
    T = T.copy()
    T[:3, :3] = U @ Vt
    return T


#: names of the automatic starts
INIT_MODES = ("auto", "identity", "principal-axes", "global")


# ------------------------------------------------------------------------------ helpers
def _describe(undet: np.ndarray) -> list[str]:
    """Readable form of undetermined directions e = (omega, tau) (model frame, about the origin)."""
    out = []
    for e in undet:
        om, tau = e[:3], e[3:]
        if np.linalg.norm(om) < 1e-9 * max(np.linalg.norm(tau), 1e-300):
            out.append("translation along [%.3f, %.3f, %.3f]" % tuple(tau / np.linalg.norm(tau)))
        else:
            a = om / np.linalg.norm(om)
            p = np.cross(om, tau) / (om @ om)   # point of the screw axis closest to the origin
            p = np.where(np.abs(p) < 1e-6, 0.0, p) + 0.0
            pitch = float(tau @ om) / (om @ om)
            txt = ("rotation about axis [%.3f, %.3f, %.3f] through (%.4g, %.4g, %.4g)"
                   % (*a, *p))
            if abs(pitch) > 1e-6:
                txt += " with %.4g mm per rad along it" % pitch
            out.append(txt)
    return out


@renamed_keywords(tolerance="rtol")
def register(scan, prep, init: "InitName | InitMode | np.ndarray | None" = None,
             method: "MethodName | Method" = "point-to-plane", loss: "LossName" = "tukey",
             scale: float | None = None, max_iterations: int = 100, rtol: float = 1e-7,
             rng=0, options: "RegistrationOptions | None" = None) -> Registration:
    """Robust ICP: register a scan to a prepared model (IRLS-ICP with automatic scale).

    Parameters
    ----------
    scan : (N, 3) float64
        Scan points in scan coordinates (mm), N >= 6.
    prep : Prepared
        From :func:`shapeverify.prepare`; only ``prep.closest(points, exact=...)`` is used.
    init : None, 'auto', 'identity', 'principal-axes', 'global' or (4, 4) float64
        The start.  None = 'auto': keep the identity when the scan already overlaps the model
        (the coarse stage from the identity leaves a fit of at least :data:`AUTO_FIT`: half
        the coarse subset on the surface, see
        :func:`~shapeverify.registration.global_search.fit_score`, and turns the scan by less
        than :data:`AUTO_MAX_TURN` degrees), otherwise run the global
        search of :func:`~shapeverify.registration.global_search.global_alignment`
        (principal axes with all axis flips, FPFH + RANSAC, the refined identity; the best
        fit wins).  'identity': start at the identity, no search.  'principal-axes': the
        coarse alignment of :func:`~shapeverify.registration.initial.principal_axes_alignment`.
        'global': always search.  A matrix: the start T_model_scan (e.g. a fixture pose, see
        :func:`~shapeverify.registration.initial.read_init`).  ``Registration.init`` says
        which start was used.
    method : {'point-to-plane', 'point-to-point', 'point-then-plane'}
        Rigid step: linearised point-to-plane least squares (thesis eq. 12-13) composed exactly
        onto the pose, or the weighted SVD solution (eq. 7-10) towards the closest points.
        'point-then-plane' is the strategy of the thesis' Section 5.2.2: the coarse stage takes
        point-to-point steps (robust far from the solution, where the tangent planes of the
        closest points mislead), the final stage point-to-plane steps (fast near it).
    loss : {'tukey', 'huber', 'cauchy', 'welsch', 'l2'}
        Robust rho-function; its tuning constant is ``c * sigma`` (95 % efficiency).
    scale : float or None
        Fixed residual scale sigma (mm); None re-estimates ``1.4826 * median|r|`` every
        iteration.
    max_iterations : int
        Limit of rigid steps of the final stage (the coarse stage stops at 60);
        ``converged`` is False when the final stage hits it.
    rtol : float
        Inner stopping rule of each stage (a relative threshold; ``tolerance=``, its old name,
        still works with a :class:`DeprecationWarning`): the objective (at the previous
        iteration's scale) decreased by less than ``rtol`` relative, and the pose change still
        to come -- the last step's length in standard deviations of the pose
        (``sqrt(v^T H v) / sigma``, ``H = sum w J^T J``), extrapolated by the observed rate of
        convergence -- is below ``sqrt(rtol * n_valid)``.  (1e-7 with 30,000 points: 0.05
        standard deviation.)
    rng : int, Generator or None
        Seeds the random subsets (coarse stage, verification, global search).  The default
        (0, also for None) makes the result bit-identical on every run and in every process;
        the operating system is never asked for entropy.
    options : RegistrationOptions, optional
        Which safeguards against a wrong minimum run (the probe of the least-determined
        direction, the restart about a near-symmetry axis, the graduated coarse scale);
        default: :class:`~shapeverify.registration.options.RegistrationOptions` ().

    Notes
    -----
    ``converged`` is True when the robust objective and the pose stopped changing at a
    minimum: the final stage's inner rule above was met against the matched tangent planes
    and then fresh closest points at the final pose (a subset of up to 4,000 scan points)
    ask for a Gauss-Newton correction, in the directions the data determine, that is below
    0.1 standard deviation of the pose, or moves no scan point by more than 0.05 sigma
    (``|omega| * r + |tau|``, r the scan's RMS radius, sigma the robust residual scale) while
    changing the objective by less than 1 %.  Undetermined directions (a turned part's spin,
    a plate's slide) are projected out of every step, so they never block convergence; they
    are named in ``Registration.undetermined``.  A pose that met the test but looks like a
    wrong minimum (few inliers, a systematic mean residual, another hypothesis of the
    global search fitting about as well) is flagged in ``Registration.warnings``.

    Returns
    -------
    Registration

    Raises
    ------
    ScanError (a ValueError)
        scan not (N, 3), fewer than 6 points, NaN/inf.
    ValueError
        Bad method, loss, init, scale, max_iterations or rtol.
    RegistrationError
        With a given start ('identity', 'principal-axes' or a matrix): fewer than 6 scan
        points within ``max(prep.reach, 0.2 * model size)`` of the model at the start
        (every point far away), fewer than 6 with a closest point off the
        model's free boundary, or the robust loss left fewer than 6 weighted points.

    Warns
    -----
    DegenerateGeometryWarning
        When the geometry leaves pose directions undetermined (flat or cylindrical scan); they
        are listed in ``Registration.undetermined`` and ``message``.

    References
    ----------
    Bergström (2011), thesis Algorithms 1-3, eq. 7-13, 17; Paper II (IRLS-ICP).

    Examples
    --------
    A simulated scan of the small example panel, 2 degrees and 3 mm off its true pose:

    >>> import numpy as np, shapeverify as sv
    >>> from shapeverify.cad.examples import wavy_panel
    >>> from shapeverify.simulate import virtual_scan
    >>> prep = sv.prepare(wavy_panel(), spacing=2.0)
    >>> sim = virtual_scan(prep, pixel=2.0, noise=0.02, motion=(2.0, 3.0), rng=1)
    >>> reg = sv.register(sim.scan, prep)
    >>> reg.T_model_scan.shape, reg.converged
    ((4, 4), True)
    >>> bool(np.abs(reg.T_model_scan - sim.T_model_scan).max() < 0.05)   # the true pose, recovered
    True
    """
    req = _request(scan, prep, init, method, loss, scale, max_iterations, rtol, rng, options)
    ctx = _stages.setup(req)                            # start pose, scales, coarse subset
    placed = _stages.initial_placement(ctx)             # coarse stage (or a global search first)
    fit = _stages.refine(ctx, placed.state)             # final stage, probe of the weakest direction
    fit = _stages.retry_from_start(ctx, fit, placed)    # final stage from the start itself
    fit = _stages.restart_about_axis(ctx, fit, placed)  # spins about a near-symmetry axis
    quality = _stages.uncertainty(ctx, fit, placed)     # covariance, undetermined, warnings
    return _result(req, fit, placed, quality, ctx.noise_estimate)


def _request(scan, prep, init, method, loss, scale, max_iterations, rtol, rng,
             options) -> _stages.Request:
    """register's arguments, checked (the errors of its Raises section)."""
    P = _check_scan(scan)
    if not callable(getattr(prep, "closest", None)):
        raise ValueError("prep must be a Prepared model (from shapeverify.prepare) with a "
                         f".closest method, got {type(prep).__name__}")
    options = options if options is not None else RegistrationOptions()
    if not isinstance(options, RegistrationOptions):
        raise TypeError(f"options= takes a RegistrationOptions, got {type(options).__name__}")
    method = Method.parse(method)
    lossobj = get_loss(loss)
    if scale is not None:
        scale = float(scale)
        if not (np.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be a positive number of mm or None, got {scale}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"max_iterations must be a positive integer, got {max_iterations}")
    tolerance = float(rtol)     # the stages' relative stopping threshold
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"rtol must be positive, got {rtol}")
    rng = generator(rng)
    mode, T0 = InitMode.parse(init, validate_pose)
    return _stages.Request(P, prep, mode, T0, method, lossobj, scale, int(max_iterations),
                           tolerance, rng, options)


def _result(req, fit, placed, quality, noise=None) -> Registration:
    """The Registration of the final fit; warns once when directions are undetermined."""
    st, ev, undet = fit.state, fit.ev, quality.undetermined
    msg = (f"converged in {st.iterations} iterations" if fit.converged else
           f"not converged: {fit.why}")
    desc = tuple(_describe(undet))
    if undet.shape[0]:
        txt = ("scan geometry leaves %d pose direction(s) undetermined: %s"
               % (undet.shape[0], "; ".join(desc)))
        msg += "; " + txt
        # once (also in the result); stacklevel: the caller of register (past the wrapper
        # of renamed_keywords)
        warnings.warn(txt, DegenerateGeometryWarning, stacklevel=4)
    for txt in quality.warnings:
        logger.info("registration: %s", txt)             # in Registration.warnings
    if not fit.converged:
        logger.info("registration %s", msg)              # in Registration.message
    return Registration(T_model_scan=_stages.pose(st), rms=ev.rms, iterations=st.iterations,
                        converged=fit.converged, weights=ev.w,
                        inlier_fraction=float(ev.inliers.mean()), covariance=quality.covariance,
                        history=tuple(st.history), scale=ev.sigma, message=msg,
                        undetermined=desc, method=req.method.value, loss=req.loss.name,
                        undetermined_directions=undet, warnings=quality.warnings,
                        init=placed.how, alternatives=quality.alternatives, noise=noise)
