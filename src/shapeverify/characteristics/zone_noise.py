"""The scan noise's part of a zone width read from extreme points, removed and bounded.

A zone width (flatness, an orientation zone) is the spread of the points' heights ``v_i``
across the zone: ``max v - min v``.  On a scan each height carries noise ``e_i`` (sigma, from
:mod:`.support`), and the largest of many noisy heights is larger than the largest true one:
on a flat 100 x 50 mm face sampled at 1 mm with 0.02 mm noise the width reads 0.147 for a true
0.000, on the same face tilted 0.2 deg 0.097 over its true 0.349.  An uncertainty that only
covers that bias (``2 z_n sigma``, :func:`.support.extreme_quantile`) leaves every width
within about ``4 z_n sigma`` of its limit undecided: NIST FTC 06's GT16 (perpendicularity
0.3048) on a face tilted 0.2 deg read 0.432 +- 0.189 at 1 mm, undecided, and flatness zones of
a few noise sigmas were undecided on perfect parts.

The bias is an expected value, so it is removed (GUM 3.2.4: a known systematic effect is
corrected) and only its uncertainty stays:

1. **the surface under the noise**: each height near an extreme is replaced by a local linear
   fit (``v`` on the tangent-plane coordinates, least squares) of its :data:`NEIGHBOURS`
   nearest points: ``s_i``, exact on a plane at any tilt and at an edge, its noise about
   ``sigma / 5``;
2. **the expected extreme of that surface plus noise**: ``P(max <= t) = prod Phi((t - s_i) /
   sigma)`` over the points within :data:`WINDOW` sigma of ``max s`` (all of a flat face, a
   few around a bump's top), integrated for the mean and the variance; the bias of a side is
   that mean less ``max s``; the same for the lowest side;
3. **value** = width - both biases; where that is not above 0 (on a small flat face the
   expected noise can take all of the width: 36 of 200 faces of 40 points), the width of the
   fitted surface (which the fits' own noise only widens), U reaching back down to 0.  A
   side whose measured
   extreme stands apart from the fitted surface plus noise (above the ``1 - APART`` quantile
   of its expected extreme: a sharp feature the fits flatten, a small bump's top) is not
   corrected;
4. **U** (k) = ``k sqrt(var_top + var_bottom)`` (the spread of the two extremes) + ``2 z
   sigma_s`` (``z`` the k-level extreme quantile of the competing points, ``sigma_s`` the local
   fits' noise: the fitted surface's own noise flattens the competition, so the correction is
   a little too small, +0.03 mm on a flat face) + how far a measured extreme lies over its
   expected one (a small sharp feature not apart enough to tell: the value may be up to it).
   ``sigma`` is the zone's own noise, from the local fits' residuals (a wall seen obliquely
   carries less of a scanner's line-of-sight noise across its normal than the scan's sigma).

Measured (``benchmarks/check_zone_noise.py --trials 50``: a 100 x 50 mm panel sampled at
random at 1 mm, 0.02 mm noise; error = value - true width, mean +- sd; U mean; in how many of
the 50 scans ``|error| <= U``):

=========================== ================ ================ ====== =======
surface                     raw error        corrected error  U      covered
=========================== ================ ================ ====== =======
flat                        +0.148 +- 0.008  +0.031 +- 0.009  0.054  50
tilt 0.2 deg                +0.098 +- 0.012  +0.016 +- 0.014  0.058  50
bump 0.3 mm, 6 mm across    +0.085 +- 0.020  +0.026 +- 0.020  0.077  50
bump 0.1 mm, 3 mm across    +0.091 +- 0.018  -0.016 +- 0.032  0.065  47
dent 0.1 mm, 10 mm across   +0.094 +- 0.014  +0.009 +- 0.020  0.081  50
wave 0.1 mm over 40 mm      +0.126 +- 0.010  +0.018 +- 0.009  0.059  50
=========================== ================ ================ ====== =======

The old U (``2 z_n sigma``) was 0.177 for all of them; at 0.05 mm noise, at 0.7 mm and at
1.5 mm / 0.01 mm every error is within U (20 scans each).  A filter alone (the zone of ``s``)
would cut a 0.3 mm bump 6 mm across to 0.14: the value keeps the extreme points; only the
expected noise is taken off.  Used by flatness, the planar orientation zones (of faces and of
a median plane), circularity and cylindricity (radii from the zone's centre or axis over
``(R theta, h)``, the arc wrapping: :func:`cylinder_coords`, ``period``), straightness of line
elements (a band of points: a nearly 1-D neighbourhood, the fit's ridge keeps it a line fit;
a line 100 mm at 1 mm, 0.02 noise: flat +0.095 -> +0.014, U 0.053 against 0.140, 30/30) and
circular and total runout.  On a cylinder r 10 x 30 mm at 1 mm, 0.02 mm noise
(``benchmarks/check_zone_noise_cylinder.py --trials 30``):

=========================== ============ ================ ================ ====== =======
shape                       zone         raw error        corrected error  U      covered
=========================== ============ ================ ================ ====== =======
perfect                     circularity  +0.118 +- 0.008  +0.044 +- 0.009  0.060  28
perfect                     cylindricity +0.127 +- 0.009  +0.024 +- 0.011  0.051  29
lobing 0.05 (3 lobes)       circularity  +0.095 +- 0.007  +0.024 +- 0.008  0.070  30
lobing 0.05 (3 lobes)       cylindricity +0.106 +- 0.007  +0.010 +- 0.010  0.053  30
bump 0.1 mm, 3 mm across    circularity  +0.058 +- 0.018  -0.015 +- 0.018  0.063  30
bump 0.1 mm, 3 mm across    cylindricity +0.070 +- 0.017  -0.030 +- 0.020  0.053  26
bump 0.3 mm, 6 mm across    circularity  +0.039 +- 0.015  -0.026 +- 0.018  0.082  30
bump 0.3 mm, 6 mm across    cylindricity +0.055 +- 0.015  -0.037 +- 0.015  0.059  29
taper 0.05 mm               circularity  +0.113 +- 0.008  +0.039 +- 0.009  0.059  29
taper 0.05 mm               cylindricity +0.098 +- 0.008  +0.010 +- 0.012  0.053  30
=========================== ============ ================ ================ ====== =======

(old U: 0.147 circularity, a section's points; 0.169 cylindricity.)  Circularity is the
largest of 10 sections' corrected zones: that maximum keeps +0.04 on a perfect cylinder.  A
bump is over-corrected on a cylinder (-0.03): the minimum-zone fit moves the axis towards the
bump and balances its top against the opposite side's noisy extremes, so the points' zone
already carries less noise than independent extremes would (the correction does not see the
fit's choice).  A profile (``2 max |d|``) is not corrected: there the two sides compete for
one extreme, and a 0.1 mm
bump 3 mm across (5 sigma) was under-read by 0.07 +- 0.06 (4 of 20 within U) when tried.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["NoisePart", "noise_part", "corrected_width", "corrected_spread", "corrected_value",
           "noise_note", "cylinder_coords", "NEIGHBOURS", "WINDOW"]

#: neighbours of each local linear fit (the point included)
NEIGHBOURS = 32
#: points whose fitted height is within this many sigma of a side's extreme compete for it
WINDOW = 8.0
#: a measured extreme above the (1 - APART) quantile of the fitted surface's expected one
#: stands apart (a sharp feature the fits flatten): that side is not corrected
APART = 0.001
#: fitted points that give the zone its own noise (fewer: the scan's)
MIN_OWN = 50
#: points tested at once in the local fits (memory: CHUNK x NEIGHBOURS x 3 floats, a few times)
CHUNK = 20_000
#: the integration grid over the extreme, in sigma from the fitted extreme
_GRID = np.linspace(-6.0, 9.0, 601)


@dataclass(frozen=True)
class NoisePart:
    """The noise part of a width ``max v - min v`` (mm).

    bias : expected excess of the noisy width over the surface's, removed from the value
    u : expanded uncertainty (k) of the corrected width from the noise
    competitors : points that compete for the top and for the bottom extreme
    fit_sigma : noise of the local fits (mm)
    sigma : the zone's own noise (mm), from the local fits' residuals
    apart : per side, whether its measured extreme stands apart from the fitted surface (not
        corrected)
    fitted_zone : the width of the fitted surface (mm): larger than the true one by the fits'
        own noise, the value's floor
    """

    bias: float
    u: float
    competitors: tuple
    fit_sigma: float
    sigma: float
    apart: tuple = ()
    fitted_zone: float = 0.0

    def to_dict(self) -> dict:
        return {"noise_bias": self.bias, "u_noise": self.u,
                "competitors": list(self.competitors), "fit_sigma": self.fit_sigma,
                "zone_noise": self.sigma, "extreme_apart": list(self.apart),
                "fitted_zone": self.fitted_zone,
                "fit_neighbours": NEIGHBOURS,
                "rule": "width less the expected noise of its extremes (zone_noise.py)"}


def noise_part(T, v, sigma: float, k: float = 2.0, period=None) -> NoisePart:
    """The noise part of the width ``max v - min v`` of heights ``v`` (mm) of points at
    surface coordinates ``T`` ((N, 2), mm: across a plane zone's normal; arc length and
    height on a cylinder) (module docstring).  ``sigma``: the scan's noise (mm); NaN or 0, or
    fewer points than a fit needs: no correction, ``u = 2 z_n sigma`` as before.  ``period``:
    the first coordinate wraps with this period (mm: ``2 pi r`` for the arc length on a
    circle), so a point near ``theta = 0`` has its neighbours across the seam.

    >>> rng = np.random.default_rng(0)
    >>> T = np.column_stack([rng.uniform(0, 100, 5000), rng.uniform(0, 50, 5000)])
    >>> v = T[:, 0] * np.tan(np.radians(0.2)) + rng.normal(0, 0.02, 5000)
    >>> p = noise_part(T, v, 0.02)
    >>> raw = v.max() - v.min(); true = 100 * np.tan(np.radians(0.2))
    >>> print(f"{raw - true:.3f} {raw - p.bias - true:.3f} {p.u:.3f}")
    0.115 0.043 0.062
    """
    from .support import extreme_quantile

    T = np.asarray(T, np.float64)
    v = np.asarray(v, np.float64)
    n = v.size
    if not (np.isfinite(sigma) and sigma > 0) or n < NEIGHBOURS:
        u = 2.0 * extreme_quantile(max(n, 2), k) * (sigma if np.isfinite(sigma) else 0.0)
        return NoisePart(0.0, float(u), (n, n), float("nan"), float(sigma))
    sig0 = sigma
    s, g, sigma = _fitted(T, v, sigma, k, period)
    if sigma > sig0:     # a rougher zone than the scan: its wider window fitted
        s, g, sigma = _fitted(T, v, sigma, k, period)
    biases, variances, comps, fit_sig = [], [], [], []
    apart, over = [], []
    for h, measured in ((s, v.max()), (-s, -v.min())):
        top = float(h.max())
        comp = h >= top - WINDOW * sigma
        b, var, below = _extreme_moments(h[comp] - top, sigma, measured - top)
        apart.append(below > 1.0 - APART)
        if apart[-1]:
            # the measured extreme stands apart from the fitted surface plus noise: a sharp
            # feature (a small bump's top) the local fits flatten; its own noise, not the
            # competition the fits show, is what it carries: not corrected, sigma in U
            b, var = 0.0, sigma ** 2
        # a measured extreme over the expected one may be a small sharp feature's top that
        # the fits flatten (not apart enough to tell): the value may be up to it
        over.append(0.0 if apart[-1] else max(measured - top - b, 0.0))
        biases.append(b)
        variances.append(var)
        comps.append(int(np.count_nonzero(comp)))
        fit_sig.append(sigma * float(np.sqrt(np.median(g[comp]))))
    bias = float(sum(biases))
    s_fit = max(fit_sig)
    zc = extreme_quantile(max(max(comps), 1), k)
    u = k * float(np.sqrt(sum(variances))) + 2.0 * zc * s_fit + sum(over)
    return NoisePart(bias, float(u), tuple(comps), float(s_fit), float(sigma), tuple(apart),
                     float(s.max() - s.min()))


def _fitted(T, v, sigma, k, period=None):
    """The local fits of the points within reach of either extreme, and the zone's own noise:
    ``1.4826 median |v - s| / sqrt(1 - g)`` over them (a wall seen obliquely carries less of a
    scanner's line-of-sight noise across its normal than the scan's sigma says; a rough face
    more); the scan's ``sigma`` when fewer than :data:`MIN_OWN` points were fitted."""
    from .support import extreme_quantile

    reach = (WINDOW + 2.0 * extreme_quantile(v.size, k)) * sigma
    near = np.flatnonzero((v >= v.max() - reach) | (v <= v.min() + reach))
    s, g = _local_fit(T, v, near, period)
    if near.size >= MIN_OWN:
        r = (v[near] - s) / np.sqrt(np.clip(1.0 - g, 1e-3, None))
        own = 1.4826 * float(np.median(np.abs(r)))
        if own > 0:
            sigma = own
    return s, g, sigma


def corrected_width(width: float, X, normal, sigma: float, k: float = 2.0):
    """``(value, u_noise, details)``: ``width``, the zone of points ``X`` across the unit
    ``normal`` (mm), less its expected noise part -- where that takes all of the width (on a
    small flat face: 36 of 200 faces of 40 points), the width of the fitted surface, which the
    fits' own noise only widens, with U reaching back down to the corrected width -- the
    noise's expanded uncertainty, and the details a result records (``zone_of_points``: the
    width of the points as measured)."""
    from .gdt_zones import tangent_basis

    X = np.asarray(X, np.float64)
    normal = np.asarray(normal, np.float64)
    return corrected_spread(width, X @ tangent_basis(normal).T, X @ normal, sigma, k)


def corrected_spread(width: float, T, v, sigma: float, k: float = 2.0, period=None):
    """``(value, u_noise, details)`` as :func:`corrected_width`, the heights ``v`` (mm; their
    spread is the zone: radial distances from a zone's axis, deviations across a line) and
    the surface coordinates ``T`` given (:func:`noise_part`; ``period``: the first one wraps,
    :func:`cylinder_coords`)."""
    p = noise_part(T, v, sigma, k, period)
    value = corrected_value(width, p.bias, p.fitted_zone)
    # where the expected noise takes all of the width, U reaches back down to the corrected width
    lift = value - (float(width) - p.bias)
    return value, p.u + lift, {"zone_of_points": float(width), **p.to_dict(),
                               "u_noise": p.u + lift}


def corrected_value(width: float, bias: float, fitted_zone: float) -> float:
    """``width - bias`` where that is above 0; else the fitted surface's width (which the fits'
    noise only widens): a zone that the expected noise takes all of is not read as 0.

    >>> round(corrected_value(0.15, 0.11, 0.03), 6), corrected_value(0.10, 0.11, 0.03)
    (0.04, 0.03)
    """
    rest = float(width) - float(bias)
    return rest if rest > 0.0 else float(fitted_zone)


def noise_note(details, sep: str = " ") -> str | None:
    """What a report prints under a zone corrected for its noise (the ``details`` of a
    result, or None where nothing was taken off): the points' own zone and the noise's
    expected part, so that a flatness reading 0.04 where the points span 0.15 says why;
    ``sep`` between its parts (a narrow table cell: a new line).

    >>> noise_note({"zone_of_points": 0.152, "noise_bias": 0.118, "fitted_zone": 0.01})
    'points 0.1520 − noise 0.1180'
    >>> noise_note({"zone_of_points": 0.10, "noise_bias": 0.11, "fitted_zone": 0.03})
    'points 0.1000, all noise: fitted 0.0300'
    >>> noise_note({"zone_of_points": 0.10, "noise_bias": 0.0}) is None
    True
    """
    w, b = (details or {}).get("zone_of_points"), (details or {}).get("noise_bias")
    if w is None or b is None or not float(b) > 0.0:
        return None
    if float(w) - float(b) > 0.0:
        return f"points {float(w):.4f}{sep}− noise {float(b):.4f}"
    return (f"points {float(w):.4f},{sep}all noise:{sep}fitted "
            f"{float(details.get('fitted_zone', 0.0)):.4f}")


def cylinder_coords(X, point, axis):
    """``(T, rho, period)`` of points ``X`` about the axis through ``point`` along ``axis``:
    surface coordinates ``T = (R theta, h)`` (``R`` the median radius, ``h`` along the axis),
    the radial distances ``rho`` (the heights of a circularity, cylindricity or runout zone on
    a cylinder) and the arc's period ``2 pi R`` (``theta`` wraps: :func:`noise_part`)."""
    from .gdt_zones import tangent_basis

    X = np.asarray(X, np.float64)
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    q = X - np.asarray(point, np.float64)
    h = q @ a
    e1, e2 = tangent_basis(a)
    x, y = q @ e1, q @ e2
    rho = np.hypot(x, y)
    R = float(np.median(rho)) if rho.size else 0.0
    theta = np.mod(np.arctan2(y, x), 2.0 * np.pi)
    return np.column_stack([R * theta, h]), rho, 2.0 * np.pi * R


def _local_fit(T, w, idx, period=None):
    """Heights ``w[idx]`` replaced by the intercept of a least-squares plane ``w ~ a + b.t``
    over the :data:`NEIGHBOURS` nearest points (``t``: surface coordinates ``T``, centred on
    the point), and the intercept's variance factor ``(A^T A)^-1_00``.  ``period``: the first
    coordinate wraps (the points are searched among copies shifted by one period each way)."""
    from scipy.spatial import cKDTree

    if period is not None and period > 0:
        shift = np.array([period, 0.0])
        Ts = np.concatenate([T, T + shift, T - shift])
        tree = cKDTree(Ts)
        w = np.concatenate([w, w, w])
        T, Tq = Ts, T
    else:
        tree = cKDTree(T)
        Tq = T
    s = np.empty(idx.size)
    g = np.empty(idx.size)
    for a in range(0, idx.size, CHUNK):
        part = idx[a:a + CHUNK]
        _, nb = tree.query(Tq[part], k=NEIGHBOURS)
        dx = T[nb, 0] - Tq[part, 0][:, None]
        dy = T[nb, 1] - Tq[part, 1][:, None]
        wn = w[nb]
        # the normal equations of [1, dx, dy] (a degenerate, collinear neighbourhood gets a
        # tiny ridge on its slopes), solved for the intercept by Cramer's rule
        a01, a02 = dx.sum(1), dy.sum(1)
        a11, a12, a22 = (dx * dx).sum(1) + 1e-12, (dx * dy).sum(1), (dy * dy).sum(1) + 1e-12
        b0, b1, b2 = wn.sum(1), (dx * wn).sum(1), (dy * wn).sum(1)
        a00 = float(nb.shape[1])
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        det = a00 * c00 + a01 * c01 + a02 * c02
        s[a:a + CHUNK] = (c00 * b0 + c01 * b1 + c02 * b2) / det
        g[a:a + CHUNK] = c00 / det
    return s, g


def _extreme_moments(z, sigma, at):
    """Mean and variance of ``max_i (z_i + e_i)`` less 0 (``z <= 0`` the fitted heights less
    their largest, ``e ~ N(0, sigma^2)``): ``F(t) = prod Phi((t - z_i) / sigma)`` on a grid
    (heights binned at sigma / 50); and ``F(at)`` (``at``: the measured extreme less the fitted
    one, mm): how probable a measured extreme this low is.  The grid ends 9 sigma over the
    fitted extreme: a measured one beyond it has ``F = 1``."""
    from scipy.special import log_ndtr

    q = np.round(np.asarray(z) / sigma * 50.0) / 50.0
    val, cnt = np.unique(q, return_counts=True)
    t = _GRID
    logF = np.zeros(t.size)
    for a in range(0, val.size, 2000):
        logF += (cnt[a:a + 2000][None, :]
                 * log_ndtr(t[:, None] - val[a:a + 2000][None, :])).sum(axis=1)
    F = np.exp(logF)
    pmf = np.diff(F)
    mid = 0.5 * (t[1:] + t[:-1])
    mean = float(pmf @ mid + F[0] * t[0])
    var = float(pmf @ mid ** 2 + F[0] * t[0] ** 2 - mean ** 2)
    below = float(np.interp(at / sigma, t, F, left=0.0, right=1.0))
    return mean * sigma, max(var, 0.0) * sigma ** 2, below
