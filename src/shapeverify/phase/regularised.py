"""CAD-regularised unwrapping with a predicted phase, and the predict-unwrap-register loop (Paper V).

The data alone cannot tell a jump of ``s`` from one of ``s - 2*pi`` (thesis Ch. 4.1, Fig. 7), so a
step of more than ``pi`` in the measured surface is lost by every data-only unwrapper.  A
*reference* phase predicted from the CAD model at its approximate pose carries that information.

Method (:func:`unwrap_with_reference`)
--------------------------------------
1. ``d = W(psi - reference)``: the wrapped disagreement between data and prediction.  Where the
   part follows the model, ``d`` is small and smooth -- the predicted steps are gone from it.
2. ``d`` is unwrapped by a data-only method (default: :func:`unwrap_mcf`).  This, rather than
   taking ``reference + d`` pixel by pixel, makes the result robust to an *approximate* reference:
   a pose error, a wrong phase offset or a slowly varying model error may make ``psi - reference``
   drift by many ``2*pi`` across the map; it is still recovered, because only its local
   changes must stay below ``pi``.
3. ``phi = reference + unwrapped d``, made exactly congruent with ``psi``.  Each 4-connected
   region of the mask then gets the multiple ``2*pi*k`` that brings the *median* of
   ``phi - reference`` closest to 0 (robust to local defects).  Regions separated by the mask,
   which no data-only method can relate, are thereby placed correctly too.

``method="nearest"`` instead takes ``phi = reference + W(psi - reference)`` pixel by pixel (the
pure regularisation: exact whenever the reference is within ``pi`` of the truth everywhere, and
then insensitive to any noise level and discontinuity, but with no tolerance for a reference
that drifts).

Where the reference places a discontinuity a few pixels away from the measured one, the strip
between the two edges is wrong by a multiple of ``2*pi`` (neither data nor reference can decide
it); registering the points and predicting again moves the predicted edge onto the measured one:
:func:`iterate_unwrap` runs that loop with the camera / registration steps passed in as callables.

References
----------
Bergström (2011), thesis Ch. 4 and Paper V, Sec. 4 (iterative phase unwrapping regularised by the
CAD model).  The algorithmic details above (difference unwrapping, median offsets) are this
package's; the thesis text available to the project does not give Paper V's objective function.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from .minimum_norm import unwrap_lp, unwrap_ls, unwrap_wls
from .network_flow import unwrap_mcf
from .path_following import unwrap_filtered, unwrap_quality
from .wrap import TWO_PI, check_map_like, check_phase_map, wrap
from shapeverify._renamed import grouped_keywords

log = logging.getLogger(__name__)

__all__ = ["UnwrapStop", "unwrap_with_reference", "ReferenceUnwrap", "iterate_unwrap", "IterativeUnwrap",
           "DATA_METHODS"]

#: data-only methods: name -> (function, how `quality` is passed)
DATA_METHODS = {
    "auto": (unwrap_mcf, "quality"),
    "mcf": (unwrap_mcf, "quality"),
    "filtered": (unwrap_filtered, "quality"),
    "quality": (unwrap_quality, "quality"),
    "ls": (unwrap_ls, None),
    "wls": (unwrap_wls, "weights"),
    "lp": (unwrap_lp, "weights"),
}


def unwrap_data(psi, method="auto", mask=None, quality=None):
    """Dispatch to a data-only unwrapper by name (see :data:`DATA_METHODS`)."""
    if method not in DATA_METHODS:
        names = ", ".join(repr(k) for k in DATA_METHODS)
        extra = " ('nearest' needs a reference)" if method == "nearest" else ""
        raise ValueError(f"unknown unwrapping method {method!r}{extra}; choose one of {names}")
    fn, qname = DATA_METHODS[method]
    if quality is not None:
        if qname is None:
            raise ValueError(f"method={method!r} is unweighted and takes no quality map; "
                             "use method='wls' for weighted least squares")
        return fn(psi, mask=mask, **{qname: quality})
    return fn(psi, mask=mask)


@dataclass(frozen=True, repr=False)
class ReferenceUnwrap:
    """Result of :func:`unwrap_with_reference`.

    Attributes
    ----------
    phase : (H, W) float64
        Unwrapped phase, congruent with the data, NaN outside the mask.
    offsets : (R,) int64
        Multiple of ``2*pi`` added to each 4-connected region of the mask (labels 1..R) to bring
        its median disagreement with the reference closest to 0.
    far_fraction : float
        Fraction of valid pixels where ``|phase - reference| > pi``: the part deviates from the
        prediction by more than half a fringe there (a real defect, a misplaced predicted edge, or
        a reference too far off to be trusted).
    method : str
        Method used on the difference (or ``"nearest"``).
    """

    phase: np.ndarray
    offsets: np.ndarray
    far_fraction: float
    method: str

    def __repr__(self):
        return (f"ReferenceUnwrap(shape={self.phase.shape}, regions={len(self.offsets)}, "
                f"far_fraction={self.far_fraction:.3g}, method={self.method!r})")


def unwrap_with_reference(psi, reference, mask=None, quality=None, method="auto"):
    """Unwrap a phase map regularised by a predicted unwrapped phase (e.g. rendered from CAD).

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    reference : (H, W) array_like of float
        Predicted *unwrapped* phase (same scale and sign as the data).  It may be approximate:
        it may differ from the truth by a constant, and by a smooth field whose change between
        neighbouring pixels stays well below ``pi``.  It must be finite on valid pixels.
    mask : (H, W) bool or None
        True where valid (``None``: NaN pixels of `psi` are masked).
    quality : (H, W) array_like of float or None
        Passed to the method used on the difference (path order or weights).
    method : str
        ``"nearest"`` (pixel-wise, see the module notes) or any data-only method
        (``"auto"``, ``"filtered"``, ``"quality"``, ``"ls"``, ``"wls"``, ``"lp"``) applied to
        ``W(psi - reference)``.

    Returns
    -------
    ReferenceUnwrap

    Raises
    ------
    ValueError
        Bad `psi`/`mask`/`quality` (as :func:`shapeverify.phase.unwrap`), `reference` of the
        wrong shape or not finite on a valid pixel, unknown method.

    References
    ----------
    Bergström (2011), Paper V, Sec. 4.

    Examples
    --------
    >>> y, x = np.mgrid[0:50, 0:60]
    >>> true = 0.1 * x + np.where(x > 30, 3.4 * np.pi, 0.0)       # a 3.4 pi step
    >>> ref = true + 0.3 * np.sin(y / 7.0) + 2 * np.pi * 5          # approximate, offset
    >>> res = unwrap_with_reference(wrap(true), ref)
    >>> bool(np.allclose(res.phase, true + 2 * np.pi * 5))
    True
    """
    p, m = check_phase_map(psi, mask)
    ref = check_map_like(reference, p.shape, "reference", m)
    d = np.where(m, wrap(p - ref), 0.0)
    if method == "nearest":
        if quality is not None:
            check_map_like(quality, p.shape, "quality", m)
        phi = ref + d
    else:
        dphi = unwrap_data(d, method=method, mask=m, quality=quality)
        phi = ref + np.where(m, dphi, 0.0)
    # exact congruence with the data
    phi = p + TWO_PI * np.rint((phi - p) / TWO_PI)
    labels, n_regions = ndimage.label(m)
    offsets = np.zeros(n_regions, np.int64)
    if n_regions:
        diff = (phi - ref)[m]
        lab = labels[m]
        order = np.argsort(lab, kind="stable")
        lab_s = lab[order]
        starts = np.searchsorted(lab_s, np.arange(1, n_regions + 1))
        ends = np.searchsorted(lab_s, np.arange(1, n_regions + 1), side="right")
        diff_s = diff[order]
        for r in range(n_regions):
            med = float(np.median(diff_s[starts[r]:ends[r]]))
            offsets[r] = -int(np.rint(med / TWO_PI))
        phi = phi + TWO_PI * np.concatenate(([0], offsets))[labels]
    phi[~m] = np.nan
    far = float(np.mean(np.abs(phi[m] - ref[m]) > np.pi))
    return ReferenceUnwrap(phase=phi, offsets=offsets, far_fraction=far, method=method)


# ---------------------------------------------------------------- the iterative loop (Paper V)

@dataclass(frozen=True, repr=False)
class IterativeUnwrap:
    """Result of :func:`iterate_unwrap`.

    Attributes
    ----------
    phase : (H, W) float64
        Last unwrapped phase (NaN outside the mask and where the prediction was NaN).
    T_model_scan : (4, 4) float64
        Last pose returned by ``register``.
    iterations : int
    converged : bool
        The pose changed by less than the tolerances and no pixel changed its multiple of
        ``2*pi`` in the last iteration.
    history : tuple of dict
        Per iteration: ``rotation_change`` (rad), ``translation_change`` (model units),
        ``pixels_changed`` (valid pixels whose ``2*pi`` multiple changed; -1 in the first),
        ``far_fraction``.
    message : str
    """

    phase: np.ndarray
    T_model_scan: np.ndarray
    iterations: int
    converged: bool
    history: tuple = field(default=())
    message: str = ""

    def __repr__(self):
        return (f"IterativeUnwrap(shape={self.phase.shape}, iterations={self.iterations}, "
                f"converged={self.converged}, message={self.message!r})")


def _check_pose(T, what):
    a = np.asarray(T, dtype=np.float64)
    if a.shape != (4, 4) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be a finite (4, 4) homogeneous transform, got shape {a.shape}")
    return a


def _pose_change(T_old, T_new):
    dR = T_new[:3, :3] @ T_old[:3, :3].T
    c = np.clip((np.trace(dR) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.arccos(c)), float(np.linalg.norm(T_new[:3, 3] - T_old[:3, 3]))


@dataclass(frozen=True)
class UnwrapStop:
    """When :func:`iterate_unwrap` stops (its ``stop=``; the loose keywords of these names
    still work, with a DeprecationWarning): after ``max_iterations`` rounds, or when the pose
    changed by less than ``rotation_tol`` (rad) and ``translation_tol`` (mm)."""

    max_iterations: int = 10
    rotation_tol: float = 1e-07
    translation_tol: float = 1e-05


@grouped_keywords("stop", UnwrapStop)
def iterate_unwrap(psi, predict_phase, points_from_phase, register, T_model_scan, *, mask=None,
                   quality=None, method="auto", stop: UnwrapStop = UnwrapStop()):
    """Predict -> unwrap with the prediction -> 3-D points -> register, until nothing changes.

    Paper V's loop: the pose of the part is only known approximately, so the predicted phase has
    its discontinuities slightly misplaced and the regularised unwrapping is wrong in thin strips;
    registering the resulting points to the model improves the pose, and predicting again moves
    the edges to the right place.

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    predict_phase : callable ``(T_model_scan (4, 4)) -> (H, W)``
        Unwrapped phase predicted from the CAD model at that pose (e.g. rays of the camera
        intersected with the model, optical path converted to phase).  NaN marks pixels where the
        model is not seen; they are left out of that iteration (NaN in the returned phase).
    points_from_phase : callable ``(phase (H, W)) -> (N, 3)``
        3-D points (scan frame) of the valid pixels, e.g. :func:`phase_to_points` on the
        camera's rays.  NaN rows are not allowed.
    register : callable ``(points (N, 3)) -> (4, 4)``
        Pose of the part, ``T_model_scan`` (model = R @ scan + t), e.g. a closure around
        :func:`shapeverify.register` that warm-starts from its previous answer.
    T_model_scan : (4, 4) array_like
        Initial pose.
    mask, quality, method
        As :func:`unwrap_with_reference`.
    stop : UnwrapStop
        Groups ``max_iterations``, ``rotation_tol``, ``translation_tol`` (described below);
        the loose keywords still work, with a DeprecationWarning.
    max_iterations : int >= 1
    rotation_tol, translation_tol : float
        Convergence: pose change below both (radians, model units) and no pixel changed.

    Returns
    -------
    IterativeUnwrap

    Raises
    ------
    ValueError
        Bad `psi`/`mask`/pose, or a callable returned an array of the wrong shape or with
        non-finite values where finite ones are needed.

    References
    ----------
    Bergström (2011), Paper V, Sec. 4 (iterative phase unwrapping).
    """
    max_iterations = stop.max_iterations
    rotation_tol = stop.rotation_tol
    translation_tol = stop.translation_tol
    p, m = check_phase_map(psi, mask)
    T = _check_pose(T_model_scan, "T_model_scan")
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations!r}")
    history = []
    phi_prev = None
    phi = None
    converged = False
    message = f"stopped after max_iterations={max_iterations}"
    it = 0
    for it in range(1, int(max_iterations) + 1):
        ref = np.asarray(predict_phase(T), dtype=np.float64)
        if ref.shape != p.shape:
            raise ValueError(f"predict_phase returned shape {ref.shape}, expected {p.shape}")
        m_it = m & np.isfinite(ref)
        if not m_it.any():
            raise ValueError(f"iteration {it}: the prediction is NaN on every valid pixel "
                             "(the model is not seen at this pose)")
        res = unwrap_with_reference(np.where(m_it, p, np.nan), ref, mask=m_it, quality=quality,
                                    method=method)
        phi = res.phase
        pts = np.asarray(points_from_phase(phi), dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 3 or not np.all(np.isfinite(pts)):
            raise ValueError(f"points_from_phase must return finite (N >= 3, 3) points, got shape "
                             f"{pts.shape}" + ("" if np.all(np.isfinite(pts)) else " with NaN/inf"))
        T_new = _check_pose(register(pts), "register(...) result")
        d_rot, d_trans = _pose_change(T, T_new)
        if phi_prev is None:
            changed = -1
        else:
            both = np.isfinite(phi) & np.isfinite(phi_prev)
            changed = int(np.count_nonzero(np.rint((phi[both] - phi_prev[both]) / TWO_PI)))
            changed += int(np.count_nonzero(np.isfinite(phi) != np.isfinite(phi_prev)))
        history.append({"iteration": it, "rotation_change": d_rot, "translation_change": d_trans,
                        "pixels_changed": changed, "far_fraction": res.far_fraction})
        log.debug("iterate_unwrap %d: dR=%.3g rad dt=%.3g changed=%d far=%.3g", it, d_rot,
                  d_trans, changed, res.far_fraction)
        T = T_new
        if changed == 0 and d_rot <= rotation_tol and d_trans <= translation_tol:
            converged = True
            message = f"converged after {it} iterations"
            break
        phi_prev = phi
    return IterativeUnwrap(phase=phi, T_model_scan=T, iterations=it, converged=converged,
                           history=tuple(history), message=message)
