"""NURBS curves and surfaces on numpy arrays (thesis chapter 7), with numba kernels behind them.

:class:`NurbsCurve` and :class:`NurbsSurface` are small frozen dataclasses that validate their data
once and evaluate points and derivatives at many parameters in one call.  :func:`pack_surfaces`
flattens many surfaces into contiguous arrays for the numba kernels of other modules
(closest points, ray intersection), see :class:`PackedSurfaces`.  :func:`circle`,
:func:`sphere` and :func:`cylinder` build exact analytic shapes as rational NURBS.

References
----------
Bergström (2011), thesis §7.1-7.2, eqs. (18)-(25).
Piegl & Tiller, The NURBS Book, 2nd ed., algorithms A2.1-A2.3, A3.2, A3.6, A4.2, A4.4,
sections 7.5 (circle) and 8.5 (surfaces of revolution).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .._arrays import readonly as _readonly

# The numba kernels (``from . import _kernels``) are imported where they are called, not here:
# building surfaces and models (e.g. for ``shapeverify info``) then needs no numba (~1.3 s).

logger = logging.getLogger(__name__)

__all__ = [
    "NurbsCurve",
    "NurbsSurface",
    "PackedSurfaces",
    "pack_surfaces",
    "evaluate_packed",
    "circle",
    "sphere",
    "cylinder",
]


# ------------------------------------------------------------------------------- validation
def _check_degree(p, name: str) -> int:
    if isinstance(p, bool) or not isinstance(p, (int, np.integer)) or p < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {p!r}")
    return int(p)


def _check_knots(knots, p: int, n_ctrl: int, name: str) -> np.ndarray:
    U = np.asarray(knots, dtype=np.float64)
    if U.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {U.shape}")
    if U.shape[0] != n_ctrl + p + 1:
        raise ValueError(
            f"{name} has {U.shape[0]} knots but degree {p} with {n_ctrl} control points needs "
            f"n + p + 1 = {n_ctrl + p + 1}"
        )
    if not np.all(np.isfinite(U)):
        raise ValueError(f"{name} contains non-finite values")
    if np.any(np.diff(U) < 0):
        i = int(np.flatnonzero(np.diff(U) < 0)[0])
        raise ValueError(f"{name} must be non-decreasing, but {name}[{i}] = {U[i]} > "
                         f"{name}[{i + 1}] = {U[i + 1]}")
    if not U[p] < U[n_ctrl]:
        raise ValueError(f"{name} gives an empty domain [{U[p]}, {U[n_ctrl]}] "
                         f"({name}[p] must be < {name}[n])")
    return _readonly(U)


def _check_weights(weights, shape: tuple, name: str = "weights"):
    if weights is None:
        return None
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != shape:
        raise ValueError(f"{name} must have shape {shape} (one per control point), got {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ValueError(f"{name} must be finite and > 0 (min is {np.nanmin(w)!r}); "
                         "pass weights=None for a non-rational shape")
    return _readonly(w)


def _params(t, lo: float, hi: float, name: str) -> np.ndarray:
    """Scalar or 1-D parameters -> (N,) float64 inside [lo, hi].

    Values a hair outside the domain are clamped onto it: up to ``1e-9 * (hi - lo)`` (plus a few
    ulps of the bounds' magnitude) -- a trim loop's vertices evaluated from a STEP file's pcurves
    land 1e-15 .. 3e-11 outside ``[0, pi]`` by rounding (NIST CTC/FTC parts).  Farther out is an
    error.
    """
    a = np.asarray(t, dtype=np.float64)
    if a.ndim > 1:
        raise ValueError(f"{name} must be a scalar or 1-D array, got shape {a.shape}")
    a = np.atleast_1d(a)
    if a.size == 0:
        return a
    amin, amax = a.min(), a.max()  # NaN propagates: one pass each instead of isfinite + min/max
    if not (np.isfinite(amin) and np.isfinite(amax)):
        bad = ~np.isfinite(a)
        raise ValueError(f"{name} has {int(bad.sum())} non-finite value(s) "
                         f"(first at index {int(np.flatnonzero(bad)[0])})")
    tol = 1e-9 * (hi - lo) + 4 * np.finfo(np.float64).eps * max(abs(lo), abs(hi), hi - lo)
    if amin < lo - tol or amax > hi + tol:
        raise ValueError(f"{name} must lie in the domain [{lo!r}, {hi!r}]; "
                         f"got values in [{amin!r}, {amax!r}]")
    if amin < lo or amax > hi:
        a = np.clip(a, lo, hi)
    return np.ascontiguousarray(a)


def _check_order(order, allowed: range, what: str) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order not in allowed:
        raise ValueError(f"{what} derivative order must be one of {list(allowed)}, got {order!r}")
    return int(order)


def _homogeneous(control: np.ndarray, weights) -> np.ndarray:
    w = np.ones(control.shape[:-1]) if weights is None else weights
    return _readonly(np.concatenate([control * w[..., None], w[..., None]], axis=-1))


# ------------------------------------------------------------------------------------ curve
@dataclass(frozen=True, eq=False, repr=False)
class NurbsCurve:
    """A NURBS curve of degree p in R^d (thesis eq. 18).

    Parameters
    ----------
    degree : int >= 1
    knots : (n + degree + 1,) float64, non-decreasing
    control : (n, d) float64 control points
    weights : (n,) float64 > 0, or None for a non-rational curve

    Raises
    ------
    ValueError
        On wrong shapes, a wrong knot count, decreasing knots, non-finite values or weights <= 0.

    Examples
    --------
    >>> c = circle(2.0)
    >>> bool(np.allclose(np.linalg.norm(c.evaluate([0.1, 0.7]), axis=1), 2.0))
    True
    """

    degree: int
    knots: np.ndarray
    control: np.ndarray
    weights: np.ndarray | None = None
    _pw: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        p = _check_degree(self.degree, "degree")
        P = np.asarray(self.control, dtype=np.float64)
        if P.ndim != 2 or P.shape[0] < p + 1 or P.shape[1] < 1:
            raise ValueError(f"control must have shape (n, d) with n >= degree + 1 = {p + 1}, "
                             f"got {P.shape}")
        if not np.all(np.isfinite(P)):
            raise ValueError("control contains non-finite values")
        object.__setattr__(self, "degree", p)
        object.__setattr__(self, "control", _readonly(P))
        object.__setattr__(self, "knots", _check_knots(self.knots, p, P.shape[0], "knots"))
        object.__setattr__(self, "weights", _check_weights(self.weights, (P.shape[0],)))
        object.__setattr__(self, "_pw", _homogeneous(self.control, self.weights))

    @property
    def domain(self) -> tuple[float, float]:
        """(t0, t1) = (knots[p], knots[n])."""
        return float(self.knots[self.degree]), float(self.knots[self.control.shape[0]])

    @property
    def rational(self) -> bool:
        return self.weights is not None

    @property
    def dim(self) -> int:
        return self.control.shape[1]

    def derivatives(self, t, order: int = 1) -> np.ndarray:
        """Points and derivatives: (N, order+1, d), ``[:, k]`` = k-th derivative (A3.2, A4.2).

        ``t``: scalar or (N,); ``order``: 0 .. max(degree, 2) + 1 (above the degree the
        derivatives of a non-rational curve are zero, those of a rational one are not).

        Raises ValueError for NaN or out-of-domain parameters or an order out of range.
        """
        order = _check_order(order, range(0, max(self.degree, 2) + 2), "curve")
        t = _params(t, *self.domain, "t")
        out = np.empty((t.shape[0], order + 1, self.dim))
        from . import _kernels

        _kernels.curve_derivs(self.degree, self.knots, self._pw, t, order, out)
        return out

    def evaluate(self, t) -> np.ndarray:
        """Points (N, d) at parameters t (scalar or (N,))."""
        return self.derivatives(t, 0)[:, 0]

    def __repr__(self) -> str:
        return (f"NurbsCurve(degree={self.degree}, n_control={self.control.shape[0]}, "
                f"dim={self.dim}, rational={self.rational}, domain={self.domain})")


# ---------------------------------------------------------------------------------- surface
@dataclass(frozen=True, eq=False, repr=False)
class NurbsSurface:
    """A NURBS surface in R^3 (thesis eq. 22).

    Parameters
    ----------
    degree_u, degree_v : int >= 1
    knots_u : (nu + degree_u + 1,) float64;  knots_v : (nv + degree_v + 1,) float64
    control : (nu, nv, 3) float64 control net
    weights : (nu, nv) float64 > 0, or None for a non-rational surface

    Raises
    ------
    ValueError
        On wrong shapes, wrong knot counts, decreasing knots, non-finite values or weights <= 0.

    Examples
    --------
    >>> s = sphere(3.0)
    >>> bool(np.allclose(np.linalg.norm(s.evaluate([0.2, 0.9], [0.3, 0.6]), axis=1), 3.0))
    True
    """

    degree_u: int
    degree_v: int
    knots_u: np.ndarray
    knots_v: np.ndarray
    control: np.ndarray
    weights: np.ndarray | None = None
    _pw: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        p = _check_degree(self.degree_u, "degree_u")
        q = _check_degree(self.degree_v, "degree_v")
        P = np.asarray(self.control, dtype=np.float64)
        if P.ndim != 3 or P.shape[2] != 3 or P.shape[0] < p + 1 or P.shape[1] < q + 1:
            raise ValueError(f"control must have shape (nu, nv, 3) with nu >= {p + 1}, "
                             f"nv >= {q + 1}, got {P.shape}")
        if not np.all(np.isfinite(P)):
            raise ValueError("control contains non-finite values")
        object.__setattr__(self, "degree_u", p)
        object.__setattr__(self, "degree_v", q)
        object.__setattr__(self, "control", _readonly(P))
        object.__setattr__(self, "knots_u", _check_knots(self.knots_u, p, P.shape[0], "knots_u"))
        object.__setattr__(self, "knots_v", _check_knots(self.knots_v, q, P.shape[1], "knots_v"))
        object.__setattr__(self, "weights", _check_weights(self.weights, P.shape[:2]))
        object.__setattr__(self, "_pw", _homogeneous(self.control, self.weights))

    @property
    def domain(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((u0, u1), (v0, v1))."""
        nu, nv = self.control.shape[:2]
        return ((float(self.knots_u[self.degree_u]), float(self.knots_u[nu])),
                (float(self.knots_v[self.degree_v]), float(self.knots_v[nv])))

    @property
    def rational(self) -> bool:
        return self.weights is not None

    def _uv(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        (u0, u1), (v0, v1) = self.domain
        u = _params(u, u0, u1, "u")
        v = _params(v, v0, v1, "v")
        try:
            u, v = np.broadcast_arrays(u, v)
        except ValueError:
            raise ValueError(f"u and v must broadcast to one (N,) shape, got {u.shape} and "
                             f"{v.shape}") from None
        return np.ascontiguousarray(u), np.ascontiguousarray(v)

    def derivatives(self, u, v, order: int = 1) -> np.ndarray:
        """Partial derivatives (N, order+1, order+1, 3) (A3.6 + A4.4).

        ``out[:, k, l] = d^(k+l) S / du^k dv^l`` for ``k + l <= order``; entries with
        ``k + l > order`` are NaN (not computed).  ``u``, ``v``: scalars or (N,), broadcast.

        Raises ValueError for NaN or out-of-domain parameters, or order not in {0, 1, 2}.
        """
        order = _check_order(order, range(0, 3), "surface")
        u, v = self._uv(u, v)
        out = np.empty((u.shape[0], order + 1, order + 1, 3))
        from . import _kernels

        # one kernel for every degree and order (a copy compiled for degree 3 was 1.3x faster
        # per point, same bits, but cost 10 s of compiling on a fresh install)
        _kernels.surface_derivs(self.degree_u, self.degree_v, self.knots_u, self.knots_v,
                                self._pw, u, v, order, out)
        return out

    def evaluate(self, u, v) -> np.ndarray:
        """Points (N, 3)."""
        return self.derivatives(u, v, 0)[:, 0, 0]

    def normal(self, u, v) -> np.ndarray:
        """Unit normals (N, 3) along Su x Sv (not oriented by any face).

        Where Su x Sv vanishes (a pole: Su = 0 or Sv = 0, e.g. on a sphere), the limit normal is
        taken from the mixed derivative (Suv x Sv or Su x Suv, signed by the side of the domain
        the point lies on).  Rows where that also fails are NaN (logged).
        """
        d = self.derivatives(u, v, 1)
        su, sv = d[:, 1, 0], d[:, 0, 1]
        n = np.cross(su, sv)
        ln = np.linalg.norm(n, axis=1)
        nsu = np.linalg.norm(su, axis=1)
        nsv = np.linalg.norm(sv, axis=1)
        # a vanishing Su or Sv is rounding noise in a random direction: do not trust its cross
        bad = (nsu <= 1e-10 * nsv) | (nsv <= 1e-10 * nsu) | ~(ln > 1e-12 * nsu * nsv)
        if bad.any():
            uu, vv = self._uv(u, v)
            idx = np.flatnonzero(bad)
            d2 = self.derivatives(uu[idx], vv[idx], 2)
            su2, sv2, suv = d2[:, 1, 0], d2[:, 0, 1], d2[:, 1, 1]
            (u0, u1), (v0, v1) = self.domain
            sgn_v = np.where(vv[idx] > 0.5 * (v0 + v1), -1.0, 1.0)
            sgn_u = np.where(uu[idx] > 0.5 * (u0 + u1), -1.0, 1.0)
            su_small = (np.linalg.norm(su2, axis=1) <= np.linalg.norm(sv2, axis=1))
            alt = np.where(su_small[:, None], sgn_v[:, None] * np.cross(suv, sv2),
                           sgn_u[:, None] * np.cross(su2, suv))
            n[idx] = alt
            ln[idx] = np.linalg.norm(alt, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = n / ln[:, None]
        nan = ~np.isfinite(n).all(axis=1) | (ln == 0)
        if nan.any():
            n[nan] = np.nan
            logger.warning("normal undefined at %d of %d (u, v) (degenerate surface point)",
                           int(nan.sum()), n.shape[0])
        return n

    def __repr__(self) -> str:
        return (f"NurbsSurface(degrees=({self.degree_u}, {self.degree_v}), "
                f"control={self.control.shape[:2]}, rational={self.rational}, "
                f"domain={self.domain})")


# ----------------------------------------------------------------------------------- packed
@dataclass(frozen=True, eq=False, repr=False)
class PackedSurfaces:
    """Many NURBS surfaces as flat contiguous arrays, for numba kernels of other modules.

    Attributes (F faces)
    --------------------
    degrees : (F, 2) int64              (p, q)
    knot_offsets : (F, 2) int64         start of U, V of face f in ``knots``
    knot_lengths : (F, 2) int64         len(U), len(V)
    knots : (M,) float64                all knot vectors concatenated
    ctrl_offsets : (F,) int64           first row of face f in ``ctrl``
    shapes : (F, 2) int64               (nu, nv); control point (i, j) of face f is row
                                        ctrl_offsets[f] + i*nv + j
    ctrl : (K, 4) float64               homogeneous control points (w*x, w*y, w*z, w)
    domains : (F, 2, 2) float64         ((u0, u1), (v0, v1)) per face (not a kernel argument)

    In njit code call (``args = packed.kernel_args``)::

        _kernels.surface_derivs_packed(degrees, knot_offsets, knot_lengths, knots,
                                       ctrl_offsets, shapes, ctrl, f, u, v, order, out)

    which writes ``out[k, l] = d^(k+l)S/du^k dv^l`` (``out`` (order+1, order+1, 3), NaN where
    ``k + l > order``); or ``surface_derivs_packed_ws(..., out, work)`` with a caller-owned
    ``work = np.empty(_kernels.surface_work_size(pmax, qmax, order))`` in hot loops.
    All arrays are read-only.
    """

    degrees: np.ndarray
    knot_offsets: np.ndarray
    knot_lengths: np.ndarray
    knots: np.ndarray
    ctrl_offsets: np.ndarray
    shapes: np.ndarray
    ctrl: np.ndarray
    domains: np.ndarray

    @property
    def kernel_args(self) -> tuple:
        """The 7 arrays in the order the ``surface_derivs_packed*`` kernels take them."""
        return (self.degrees, self.knot_offsets, self.knot_lengths, self.knots,
                self.ctrl_offsets, self.shapes, self.ctrl)

    def __len__(self) -> int:
        return self.degrees.shape[0]

    def __repr__(self) -> str:
        return (f"PackedSurfaces(n_faces={len(self)}, n_knots={self.knots.shape[0]}, "
                f"n_control={self.ctrl.shape[0]})")


def pack_surfaces(surfaces) -> PackedSurfaces:
    """Flatten a list of :class:`NurbsSurface` into a :class:`PackedSurfaces`.

    Raises ValueError for an empty list or an item that is not a NurbsSurface.
    """
    surfaces = list(surfaces)
    if not surfaces:
        raise ValueError("pack_surfaces needs at least one NurbsSurface, got an empty list")
    for i, s in enumerate(surfaces):
        if not isinstance(s, NurbsSurface):
            raise ValueError(f"item {i} is a {type(s).__name__}, not a NurbsSurface")
    F = len(surfaces)
    degrees = np.array([[s.degree_u, s.degree_v] for s in surfaces], dtype=np.int64)
    knot_lengths = np.array([[s.knots_u.size, s.knots_v.size] for s in surfaces], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(knot_lengths.ravel())[:-1]]).astype(np.int64)
    knot_offsets = starts.reshape(F, 2)
    knots = np.concatenate([k for s in surfaces for k in (s.knots_u, s.knots_v)])
    shapes = np.array([s.control.shape[:2] for s in surfaces], dtype=np.int64)
    sizes = shapes[:, 0] * shapes[:, 1]
    ctrl_offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    ctrl = np.concatenate([s._pw.reshape(-1, 4) for s in surfaces])
    domains = np.array([s.domain for s in surfaces], dtype=np.float64)
    return PackedSurfaces(*(_readonly(a) for a in (degrees, knot_offsets, knot_lengths, knots,
                                                   ctrl_offsets, shapes, ctrl, domains)))


def evaluate_packed(packed: PackedSurfaces, face_ids, uv, order: int = 0) -> np.ndarray:
    """Derivatives at many (face, u, v): (N, order+1, order+1, 3), as NurbsSurface.derivatives.

    Parameters
    ----------
    packed : PackedSurfaces
    face_ids : (N,) int, each in [0, F)
    uv : (N, 2) float64, inside each point's face domain (a few ulps outside are clamped)
    order : 0, 1 or 2

    Raises
    ------
    ValueError
        On bad shapes, face ids out of range, NaN or out-of-domain (u, v).
    """
    order = _check_order(order, range(0, 3), "surface")
    f = np.asarray(face_ids)
    if f.ndim != 1 or not (np.issubdtype(f.dtype, np.integer) or f.size == 0):
        raise ValueError(f"face_ids must be a 1-D integer array, got shape {f.shape} "
                         f"dtype {f.dtype}")
    f = f.astype(np.int64)
    uv = np.asarray(uv, dtype=np.float64)
    if uv.shape != (f.shape[0], 2):
        raise ValueError(f"uv must have shape (N, 2) = ({f.shape[0]}, 2), got {uv.shape}")
    if f.size and (f.min() < 0 or f.max() >= len(packed)):
        raise ValueError(f"face_ids must lie in [0, {len(packed)}), got [{f.min()}, {f.max()}]")
    if not np.all(np.isfinite(uv)):
        raise ValueError(f"uv has {int((~np.isfinite(uv)).any(axis=1).sum())} row(s) with "
                         "non-finite values")
    dom = packed.domains[f]  # (N, 2, 2)
    lo, hi = dom[:, :, 0], dom[:, :, 1]
    tol = 4 * np.finfo(np.float64).eps * np.maximum(np.maximum(abs(lo), abs(hi)), hi - lo)
    outside = ((uv < lo - tol) | (uv > hi + tol)).any(axis=1)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise ValueError(f"{int(outside.sum())} (u, v) lie outside their face's domain; first: "
                         f"row {i}, face {f[i]}, uv {tuple(uv[i])} not in "
                         f"u {tuple(dom[i, 0])} x v {tuple(dom[i, 1])}")
    uv = np.clip(uv, lo, hi)
    out = np.empty((f.shape[0], order + 1, order + 1, 3))
    from . import _kernels

    _kernels.surface_derivs_packed_many(*packed.kernel_args, f, np.ascontiguousarray(uv[:, 0]),
                                        np.ascontiguousarray(uv[:, 1]), order, out)
    return out


# ------------------------------------------------------------------------- analytic shapes
_S = np.sqrt(0.5)
# unit circle as 9-point rational quadratic (NURBS Book ex. 7.2 / fig. 7.16)
_CIRCLE_XY = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1],
                       [1, 0]], dtype=np.float64)
_CIRCLE_W = np.array([1, _S, 1, _S, 1, _S, 1, _S, 1])
_CIRCLE_KNOTS = np.array([0, 0, 0, .25, .25, .5, .5, .75, .75, 1, 1, 1], dtype=np.float64)
# half circle from (0, -1) to (0, 1) through (1, 0): the meridian of a sphere
_HALF_XZ = np.array([[0, -1], [1, -1], [1, 0], [1, 1], [0, 1]], dtype=np.float64)
_HALF_W = np.array([1, _S, 1, _S, 1])
_HALF_KNOTS = np.array([0, 0, 0, .5, .5, 1, 1, 1], dtype=np.float64)


def _center(center, dims=(3,)) -> np.ndarray:
    c = np.asarray(center, dtype=np.float64)
    if c.ndim != 1 or c.shape[0] not in dims or not np.all(np.isfinite(c)):
        raise ValueError(f"center must be a finite vector of length {' or '.join(map(str, dims))}"
                         f", got {center!r}")
    return c


def _radius(r, name="radius") -> float:
    r = float(r)
    if not (np.isfinite(r) and r > 0):
        raise ValueError(f"{name} must be finite and > 0, got {r!r}")
    return r


def circle(radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> NurbsCurve:
    """Exact full circle as a degree-2 rational NURBS (9 control points, t in [0, 1]).

    Lies in the plane z = center[2] (3-D center) or in R^2 (2-D center); starts at
    center + (radius, 0) and runs counter-clockwise.  Not arc-length parametrised.
    """
    r = _radius(radius)
    c = _center(center, (2, 3))
    P = np.zeros((9, c.shape[0]))
    P[:, :2] = r * _CIRCLE_XY
    return NurbsCurve(2, _CIRCLE_KNOTS, P + c, _CIRCLE_W)


def sphere(radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> NurbsSurface:
    """Exact sphere as a rational surface of revolution about z (degrees (2, 2), net 9 x 5).

    u in [0, 1] runs around the z axis (counter-clockwise from +x), v in [0, 1] from the south
    pole (v=0) to the north pole (v=1); Su x Sv points outwards.
    """
    r = _radius(radius)
    c = _center(center)
    P = np.empty((9, 5, 3))
    P[:, :, 0] = _CIRCLE_XY[:, 0, None] * _HALF_XZ[None, :, 0]
    P[:, :, 1] = _CIRCLE_XY[:, 1, None] * _HALF_XZ[None, :, 0]
    P[:, :, 2] = _HALF_XZ[None, :, 1]
    W = _CIRCLE_W[:, None] * _HALF_W[None, :]
    return NurbsSurface(2, 2, _CIRCLE_KNOTS, _HALF_KNOTS, r * P + c, W)


def cylinder(radius: float = 1.0, height: float = 1.0, center=(0.0, 0.0, 0.0)) -> NurbsSurface:
    """Exact cylinder (lateral face) about the z axis through ``center``, z in [c_z, c_z + height].

    Degrees (2, 1), net 9 x 2; u in [0, 1] around the axis, v in [0, 1] along it; Su x Sv points
    outwards.
    """
    r = _radius(radius)
    h = _radius(height, "height")
    c = _center(center)
    P = np.empty((9, 2, 3))
    P[:, :, 0] = r * _CIRCLE_XY[:, 0, None]
    P[:, :, 1] = r * _CIRCLE_XY[:, 1, None]
    P[:, :, 2] = np.array([0.0, h])[None, :]
    W = np.repeat(_CIRCLE_W[:, None], 2, axis=1)
    return NurbsSurface(2, 1, _CIRCLE_KNOTS, np.array([0.0, 0, 1, 1]), P + c, W)
