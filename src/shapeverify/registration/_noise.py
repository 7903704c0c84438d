"""The scan's own noise, from the scan alone: the yardstick of a registration's residuals.

A right pose leaves residuals at the sensor's noise (plus the part's form deviations); a wrong
minimum leaves them at a fraction of the features it missed.  The fit distance the registration
warns at (4 model spacings, or 0.5 % of the size) knows neither: on the impeller a pose 105 deg
off converged at a robust scale of 0.86 mm, under that bar, with a sensor noise of 0.02 mm.
:func:`scan_noise` measures the noise as the scatter of scan points about a quadric fitted to
their neighbours (which absorbs the surface's curvature): the median absolute residual of the
points themselves, each scaled by its leverage, as a standard deviation.

One sheet of surface per quadric: the neighbours of a point on a thin wall (an impeller's blade
1-2 mm thick scanned at 1 mm) hold points of both sides, and a quadric through both read the
noise 8-17 x too high.  So the neighbourhood is split first: the plane that gathers the tightest
:data:`SEED` neighbours (among the planes through triples of near neighbours, and the
neighbourhood's principal plane) seeds a quadric, which grows to the neighbours within 3 robust
sigmas of it (studentized residuals: a quadric through few points fits them too well); the
neighbours it leaves grow a second quadric, and the point is measured against the one of the two
sheets nearest to it.  Copies of a point (each point twice in a merged file) are no neighbours
of it: counted twice, a point's own noise pulls the quadric onto it.  A point its sheet's
quadric misses by more than :data:`MISS` of that sheet's scatter (an outlier, a wall's rim
where no quadric holds) tells nothing about the noise and is left out.

The per-point work (the copies' test, the seed plane, the sheets, the point's residual and
leverage) runs compiled, one point at a time (:mod:`._noise_kernels`: 0.09 s for the 1,000
points of a 30,000-point scan, against 0.30 s for the vectorised numpy it replaced, with the
same numbers to round-off).  :func:`noise_of` keeps which subsample it measured
(:class:`NoiseEstimate`): the registration's estimate travels on ``Registration.noise`` and the
inspection reuses it where it would measure the same points.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> x, y = rng.uniform(-10, 10, (2, 20000))
>>> P = np.c_[x, y, 0.01 * (x ** 2 + y ** 2) + rng.normal(0, 0.02, x.size)]
>>> round(scan_noise(P), 2)
0.02
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from shapeverify._lazy import cKDTree

__all__ = ["scan_noise", "NoiseEstimate", "noise_of"]

#: scan points whose scatter is measured
POINTS = 1000
#: neighbours of each, for its quadric
K = 24
#: rounds of each quadric's growth: refitted on the neighbours within 3 robust sigmas of it
ROUNDS = 5
#: points whose quadric predicts them with more than this variance (in noise variances) are
#: left out, and fewer than MIN_POINTS left give no estimate
MAX_LEVERAGE = 1.0
MIN_POINTS = 50
#: neighbours in the seed of a sheet (the tightest this many about a candidate plane); a
#: second sheet needs as many points left over
SEED = 10
#: candidate planes through triples of the NEAR nearest neighbours, kept when the triangle's
#: shape quality (1 for an equilateral one, 0 for collinear points) is at least QMIN
NEAR = 8
QMIN = 0.2
#: a seed (and a sheet) must span the plane: the smaller in-plane second moment at least this
#: share of the larger (a raster's row alone fixes no normal)
FLAT = 1.0 / 25.0
#: the second sheet is taken when it lies farther than SEP x (the two sheets' sigmas summed)
#: from the first at the point, and nearer to the point
SEP = 3.0
#: neighbours within COPY x the distance of the (COPIES x K)-th neighbour of the point or of a
#: nearer neighbour are copies of it, left out
COPY, COPIES = 0.07, 3
#: points farther than this many of their sheet's sigmas off its quadric are left out
MISS = 6.0

_TRIPLES = np.array(list(combinations(range(NEAR), 3)))


def _neighbours(P, idx):
    """The K neighbours of each point ``P[idx]`` about it (m, K, 3), copies left out, and
    whether K were found.

    A neighbour closer than :data:`COPY` x the distance of the (COPIES x K)-th to the point or
    to a nearer neighbour is a copy (a doubled exposure, a merged file): its noise is the
    other's, and counted twice it pulled the quadric onto the point (a scan with each point
    twice read a third of its noise)."""
    from . import _noise_kernels

    kk = min(COPIES * K + 1, P.shape[0])
    d, nb = cKDTree(P).query(P[idx], k=kk)
    Q = P[nb] - P[idx][:, None, :]                      # (m, kk, 3), the point itself first
    delta = COPY * d[:, -1]
    # which of two copies stays is decided by the file's order, not by the distance: the copy
    # nearer to the point is the one whose noise is nearer to the point's (two passes with
    # independent noise read half their noise)
    seq = np.concatenate([np.zeros((len(idx), 1), np.int64),
                          1 + np.argsort(nb[:, 1:], axis=1, kind="stable")], axis=1)
    order, full = _noise_kernels.copies(Q, np.ascontiguousarray(d), seq, delta ** 2, K)
    return np.take_along_axis(Q, order[..., None], 1), full


@dataclass(frozen=True)
class NoiseEstimate:
    """A scan's noise as :func:`noise_of` measured it, and on which points: every ``step``-th
    of the ``n`` points it was given (what another caller checks before it reuses ``sigma``
    for the same points; the noise does not change when the points move rigidly)."""

    sigma: float
    n: int
    step: int

    def reusable_for(self, n: int, most: int) -> bool:
        """Whether :func:`noise_of` of ``n`` points (the same points, in the same order) with
        at most ``most`` measured would measure the same subsample."""
        return self.n == n and self.step == _step(n, most)


def _step(n: int, most: int) -> int:
    return max(1, n // most)


def noise_of(P, most: int) -> NoiseEstimate:
    """:func:`scan_noise` of every ``max(1, n // most)``-th of the points P (n, 3), with the
    subsample it measured."""
    n = np.shape(P)[0]
    step = _step(n, most)
    return NoiseEstimate(scan_noise(P[::step]), n, step)


def scan_noise(P) -> float:
    """Noise sigma (mm) of the scan points P (n, 3) about their local quadrics, or nan with
    fewer than ``K + 1`` points (copies counted once) or :data:`MIN_POINTS` well-fixed
    quadrics."""
    P = np.asarray(P, np.float64)
    n = P.shape[0]
    if n <= K:
        return float("nan")
    # evenly spaced in the file's order (no random draw: a simulated scan's outliers drawn with
    # the same seed were once exactly the points measured)
    idx = np.arange(n) if n <= POINTS else np.linspace(0, n - 1, POINTS).astype(np.int64)
    X, full = _neighbours(P, idx)                      # (m, K, 3) neighbours about the point
    # per point (compiled, :mod:`._noise_kernels`): the frame of its seed plane, one or two
    # quadric sheets grown from it, the point's residual off its sheet and the leverage there
    from . import _noise_kernels

    r, lev, ok = _noise_kernels.centres(np.ascontiguousarray(X), full, _TRIPLES, SEED, QMIN,
                                        FLAT, ROUNDS, SEP, MAX_LEVERAGE, MISS)
    if np.count_nonzero(ok) < MIN_POINTS:
        return float("nan")
    z = r[ok] / np.sqrt(1.0 + lev[ok])
    return float(1.4826 * np.median(np.abs(z)))
