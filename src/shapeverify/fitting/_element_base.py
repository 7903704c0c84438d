"""Shared machinery of the geometric-element fits (private).

Result ``__repr__`` base (:class:`_Repr`), input checks at the public boundary, the robust
losses (those of :mod:`shapeverify.robust`, the one module), the outer IRLS loop (:func:`_irls`),
a Levenberg-Marquardt solver with steps in a local chart (:func:`_lm`) and small vector helpers.

Robust losses: ``loss="huber" | "tukey" | "cauchy" | "welsch"`` solves the M-estimation problem
by iteratively reweighted least squares.  The residual scale is the MAD,
``1.4826 * median(|r|)``, re-estimated in every reweighting step unless ``scale`` is given; the
tuning constants give 95 % asymptotic efficiency at the normal distribution.  Redescending
losses (Tukey, Welsch, Cauchy) start from a few Huber steps.

References
----------
P. W. Holland and R. E. Welsch, "Robust regression using iteratively reweighted least-squares", 1977.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .. import robust as _robust

#: The robust losses (:data:`shapeverify.robust.LOSSES`: name -> Loss, with its constant ``c``).
LOSSES = _robust.LOSSES


# ----------------------------------------------------------------------------------------------
# result objects
# ----------------------------------------------------------------------------------------------
def _fmt(value) -> str:
    if isinstance(value, np.ndarray):
        if value.size <= 3:
            return np.array2string(value, precision=6, separator=", ")
        return f"<{value.dtype} array {value.shape}>"
    if isinstance(value, float):
        return f"{value:.6g}"
    return repr(value)


class _Repr:
    def __repr__(self) -> str:
        # a subclass's own fields first, then the keyword-only ones it inherits (_ElementFit's)
        fields = sorted(dataclasses.fields(self), key=lambda f: bool(f.kw_only))
        parts = [f"{f.name}={_fmt(getattr(self, f.name))}" for f in fields]
        return f"{type(self).__name__}({', '.join(parts)})"


@dataclasses.dataclass(frozen=True, repr=False, kw_only=True)
class _ElementFit(_Repr):
    """What every geometric-element fit reports besides its geometry: the rms of the residuals,
    the residuals (signed or not: each subclass says), the robust weights, the residual scale,
    the loss, the number of iterations and whether they converged.  Keyword-only, so a subclass
    lists its geometry first; :func:`_fit_stats` fills them."""
    rms: float
    residuals: np.ndarray
    weights: np.ndarray
    scale: float
    loss: str
    iterations: int
    converged: bool


def _fit_stats(r, w, s, loss, iterations, converged) -> dict:
    """The :class:`_ElementFit` fields of residuals ``r`` with weights ``w`` and scale ``s``."""
    r = np.asarray(r)
    return dict(rms=float(np.sqrt(np.mean(r * r))), residuals=r, weights=w, scale=s, loss=loss,
                iterations=iterations, converged=converged)


# ----------------------------------------------------------------------------------------------
# input checks and robust weights
# ----------------------------------------------------------------------------------------------
def _check_points(points, dims: tuple[int, ...], minimum: int, what: str,
                  spread: int = 1) -> np.ndarray:
    """``points`` as float64 after checking shape, count, finiteness and that they span at least
    ``spread`` directions (1: not all the same point, 2: not all on one line): degenerate data
    would otherwise give a zero radius or an arbitrary normal reported as converged."""
    x = np.asarray(points, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] not in dims:
        want = " or ".join(f"(N, {d})" for d in dims)
        raise ValueError(f"{what}: points must have shape {want}, got {x.shape}")
    if x.shape[0] < minimum:
        raise ValueError(f"{what}: needs at least {minimum} points, got {x.shape[0]}")
    if not np.all(np.isfinite(x)):
        bad = int(np.count_nonzero(~np.isfinite(x).all(axis=1)))
        raise ValueError(f"{what}: {bad} point(s) contain NaN or inf; remove them before fitting")
    _check_spread(x, spread, what)
    return x


def _check_spread(x: np.ndarray, spread: int, what: str) -> None:
    y = x - x.mean(axis=0)
    rms = np.sqrt(np.clip(np.linalg.eigvalsh(y.T @ y), 0.0, None) / len(x))[::-1]  # descending
    size = float(np.abs(x).max())
    if not rms[0] > 1e-12 * size:
        raise ValueError(f"{what}: all {len(x)} points are the same point {x[0].tolist()}; "
                         "nothing to fit")
    if spread >= 2 and not rms[1] > 1e-10 * rms[0]:
        raise ValueError(f"{what}: the {len(x)} points lie on a straight line (rms spread "
                         f"{rms[1]:.3g} across it, {rms[0]:.3g} along it); a {what[4:]} needs "
                         "points spread in two directions")


def _check_loss(loss: str, scale) -> None:
    if loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}; choose one of {sorted(LOSSES)}")
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive finite number or None, got {scale!r}")


def robust_weights(residuals: np.ndarray, loss: str, scale: float) -> np.ndarray:
    """IRLS weights ``w(r) = psi(r) / r`` of an M-estimator (:func:`shapeverify.robust.robust_weights`).

    Parameters
    ----------
    residuals : (N,) float64
    loss : {"l2", "huber", "tukey", "cauchy", "welsch"}
    scale : float
        Residual scale (e.g. ``1.4826 * median(|r|)``); the tuning constant multiplies it.

    Returns
    -------
    (N,) float64 weights in [0, 1].
    """
    return _robust.robust_weights(residuals, loss, scale)


def _mad_scale(residuals: np.ndarray, floor: float) -> float:
    return _robust.robust_scale(residuals, floor)


# ----------------------------------------------------------------------------------------------
# iteration: IRLS outer loop, Levenberg-Marquardt inner solve
# ----------------------------------------------------------------------------------------------
def _irls(solve, state, dist, loss, scale, n, floor, max_iterations, tol, robust_start=False):
    """Outer IRLS loop shared by all elements.

    solve(state, weights) -> (state, inner_converged, inner_iterations);
    dist(state) -> (N,) residuals used for weighting.  ``robust_start``: the start is already
    robust (LMedS), so reweighting starts from it instead of from the least-squares solution.
    Returns (state, weights, scale, iterations, converged).
    """
    w = np.ones(n)
    if loss == "l2":
        state, ok, iters = solve(state, w)
        return state, w, float("nan"), iters, ok
    total = 0
    if robust_start:
        stages = [loss]
    else:
        state, _, total = solve(state, w)
        stages = ["huber", loss] if loss in ("tukey", "welsch", "cauchy") else [loss]
    converged, s = False, float("nan")
    for stage in stages:
        converged = False
        for _ in range(max_iterations):
            r = dist(state)
            s = float(scale) if scale is not None else _mad_scale(r, floor)
            w_new = robust_weights(r, stage, s)
            if np.count_nonzero(w_new > 0) < 3:
                raise ValueError("robust fit: fewer than 3 points keep a non-zero weight; "
                                 "give a larger `scale` or use a softer loss")
            state, ok, iters = solve(state, w_new)
            total += iters
            change = float(np.max(np.abs(w_new - w)))
            w = w_new
            if change < tol:
                converged = ok
                break
    return state, w, s, total, converged


def _lm(state, fun, retract, w, length, max_iterations=100, tol=1e-12):
    """Levenberg-Marquardt on the weighted sum of squares, with steps in a local chart.

    fun(state) -> (r (M,), J (M, k)): residuals and Jacobian w.r.t. the local step at ``state``.
    retract(state, step) -> new state.  ``w``: (M,) non-negative row weights.
    Returns (state, converged, iterations).
    """
    r, J = fun(state)
    sw = np.sqrt(w)
    cost = float(np.sum(w * r * r))
    lam = 1e-4
    for it in range(1, max_iterations + 1):
        A = sw[:, None] * J
        d = np.sqrt(np.maximum(np.einsum("ij,ij->j", A, A), 1e-300))
        while True:
            aug = np.vstack([A, np.diag(np.sqrt(lam) * d)])
            rhs = np.concatenate([-sw * r, np.zeros(J.shape[1])])
            step = np.linalg.lstsq(aug, rhs, rcond=None)[0]
            new = retract(state, step)
            r_new, J_new = fun(new)
            cost_new = float(np.sum(w * r_new * r_new))
            small = np.max(np.abs(step)) <= tol * (1.0 + length)
            if cost_new <= cost:
                state, r, J = new, r_new, J_new
                done = small or (cost - cost_new) <= 1e-15 * cost
                cost = cost_new
                lam = max(lam / 10.0, 1e-12)
                if done:
                    return state, True, it
                break
            if small or lam > 1e12:
                return state, True, it
            lam *= 10.0
    return state, False, max_iterations


# ----------------------------------------------------------------------------------------------
# vector helpers
# ----------------------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    # v / np.linalg.norm(v), bit for bit (norm of a real vector is sqrt(v.dot(v))) without
    # norm's dispatch: this runs a few times per Levenberg-Marquardt step
    return v / math.sqrt(float(v.dot(v)))


def _cross3(a, b) -> np.ndarray:
    """``np.cross(a, b)`` of two (3,) vectors, bit for bit (the same products and differences
    in float64), without np.cross's axis handling (which costs ~60 times the arithmetic)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _perp_basis(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to unit ``a`` and to each other."""
    k = int(np.argmin(np.abs(a)))
    e = np.zeros(3)
    e[k] = 1.0
    u = _unit(_cross3(a, e))
    return u, _cross3(a, u)
