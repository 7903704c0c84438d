"""Which scan points a characteristic may use: the neighbourhood-support rule for outliers.

A characteristic's value is a measurement of the points it keeps, so the points it leaves out
must be left out for a reason that is not their distance against the limit (a cut-off at the
limit makes the value the cut-off: ``2 x 0.05 = 0.099998`` for a profile whose points reach
0.1 mm).  The rule is the inspection's own (:mod:`shapeverify.inspection.regions`): a deviation
counts when its neighbourhood supports it.  For every evaluated point ``i`` let ``med_i`` be the
median deviation of its (up to) 9 nearest evaluated foot points within 6 median spacings
(itself included, as the inspection's core-point test takes it).  A point is **unsupported**
(a measurement outlier: dust, a spike, a stray reflection) when its deviation departs both from
``med_i`` and from the median of the whole scan by more than ``z sigma``:

* ``sigma`` is the scan's noise, from the differences of the deviations of nearest neighbours
  (``1.4826 median |d_i - d_j| / sqrt 2`` on an even subset of up to 4,000 points): the form of
  the part cancels in a neighbour's difference, so a dented part has the noise of a good one;
* ``z = Phi^-1(1 - alpha / (2 n))`` with ``n`` the evaluated points and ``alpha = 0.01``: Gaussian
  noise of that sigma leaves out no point of a clean scan in 99 % of scans (the threshold is
  relative to the neighbourhood and the noise, never a distance against a tolerance).

A real defect is a surface: its points support each other and stay.  The median of a
neighbourhood is a constant, though, and a steep small defect is not: on a bump 6 mm across at
1 mm spacing most points depart from their neighbours' median by more than ``z sigma`` (the top
by a third of the height), and the old rule left out the top of 35 of 40 such 1 mm bumps sampled
at random (NIST FTC 10's profile GT10 read a 1 mm bump on face 178 as 1.21 mm).  So a point the
median test leaves out **stays when the kept surface around it is smooth through it**
(neighbours on its own CAD face within 6 median spacings, the point itself never one of them):

* it lies within the range of its kept neighbours' deviations (at least 3): it makes no new
  extreme (a point on a steep flank);
* or a kept neighbour ``j`` and a kept point ``k`` beyond it (within 45 degrees of the line
  from the point through ``j``, at least half their distance further) **bracket** it: it lies
  between ``d_j`` and the straight-line extrapolation of ``d_k, d_j`` to it (widened by
  :data:`WIDEN` ``z sigma``), as on any smooth surface from at least one side (a bump's top
  lies below the extrapolation of its flanks);
* rounds repeat, a point kept in one round bracketing the next; then a group of at least
  :data:`GROUP` left-out points on one side, each within 6 spacings of the next, stays when
  each is kept with the others taken as kept too, unless that many together is likely among
  the left-out points scattered at random (:func:`_unlikely_by_chance`): a sampling gap over a
  bump's top, not a crowd of outliers.

A point is never rescued where the bulk surface (a kept point within ``z sigma`` of the scan's
median) is measured within :data:`BESIDE` median spacings of it: a layer over the measured
surface (a reflection, the surface seen under it) is not a defect, which replaces the surface
(without this, 60 of 80 points of 4-point layers 0.5 mm over a random 1 mm panel stayed; layers
of 4/8/15/30 points: 0/30/90/186 of 80/160/300/600 stay, the old rule 3/22/69/150).  A spike on a smooth surface is bracketed by nothing.  On a flat panel sampled at random at 1 mm
(0.02 mm noise, 40 scans each): the extreme of a 0.5-1.5 mm bump 6 mm across is kept in 156 of
160 (old rule 28 of 160; the 4 others keep 64-74 % of it), no spike of 0.5-5 mm (nor 0.15-5) at
1 %, 3 % or 10 % of the points stays (old rule 1.6-1.9 %: those with fewer than 3 neighbours
within 3 spacings, now looked for within 6), a layer's points stay about as often as with the
old rule, and no clean point is left out (``benchmarks/check_outlier_support.py``).

:func:`extreme_quantile` gives the other half of an honest extreme value: the noise part of a
value taken from the largest of ``n`` deviations (a profile's ``2 max |d|``, a flatness zone) is
not ``k sigma`` but the ``k``-level quantile of the largest of ``n`` absolute normal deviates
(about 5 sigma for 10^5 points).
"""
from __future__ import annotations

import numpy as np

__all__ = ["Support", "neighbourhood_support", "extreme_quantile", "ALPHA", "SAMPLE"]

#: probability that a clean scan (Gaussian noise) loses a point to the rule
ALPHA = 0.01
#: evaluated points (an even subset) that give the noise
SAMPLE = 4000
#: neighbours of the median, and half the neighbourhood radius in median spacings (regions.py:
#: the whole radius)
NEIGHBOURS = 9
RADIUS = 3.0
#: points left out by the median test that, close together and on one side, may bracket each
#: other (a steep defect in a sampling gap); fewer are left out as outliers
GROUP = 4
#: a left-out point with a kept point of the bulk (within z sigma of the scan's median) this
#: many median spacings from it is not rescued: the surface is seen beside it (a layer)
BESIDE = 1.5
#: rounds of rescue (a point kept in one round may bracket another in the next)
RESCUE_ROUNDS = 4
#: kept neighbours (within 2 RADIUS spacings) tried for the range and the brackets
BRACKET_NEIGHBOURS = 24
#: a bracket's ``k`` lies at least this many times ``|x_j - x_i|`` beyond ``j`` (so the
#: extrapolation at most doubles the noise of ``d_j - d_k``)
AHEAD = 0.5
#: a bracket is widened by this many ``z sigma`` (a moved boss's wall points read against
#: the face at its foot, 9 sigma off, stayed with 1)
WIDEN = 0.5
#: points tested at once (memory: 25 x 25 neighbour pairs of 3 floats each)
CHUNK = 2000


class Support:
    """Result of :func:`neighbourhood_support`.

    Attributes
    ----------
    unsupported : (N,) bool
        Evaluated points whose deviation their neighbourhood does not support.
    noise : float
        The scan's noise sigma (mm) from neighbour differences (NaN with too few points).
    threshold : float
        ``z sigma`` (mm): the departure from the neighbourhood median that makes a point
        unsupported.
    spacing : float
        Median spacing of the evaluated foot points (mm).
    """

    def __init__(self, unsupported, noise, threshold, spacing, z):
        self.unsupported = unsupported
        self.noise = float(noise)
        self.threshold = float(threshold)
        self.spacing = float(spacing)
        self.z = float(z)

    def to_dict(self) -> dict:
        return {"rule": "neighbourhood support", "noise": self.noise,
                "threshold": self.threshold, "z": self.z, "spacing": self.spacing,
                "n_unsupported": int(np.count_nonzero(self.unsupported))}


def _z(n: int, alpha: float = ALPHA) -> float:
    from scipy.stats import norm

    return float(norm.isf(alpha / (2.0 * max(int(n), 1))))


def extreme_quantile(n: int, k: float = 2.0) -> float:
    """The ``k``-level quantile (normal coverage of ``k``: 95.45 % for 2) of the largest of
    ``n`` absolute standard normal deviates: ``Phi^-1(1 - (1 - p^(1/n)) / 2)``, ``p = 2 Phi(k)
    - 1``.  Equal to ``k`` for ``n = 1``.

    >>> round(extreme_quantile(1), 6), round(extreme_quantile(100_000), 2)
    (2.0, 5.04)
    """
    from scipy.stats import norm

    n = max(int(n), 1)
    p = 1.0 - 2.0 * float(norm.sf(k))
    tail = -np.expm1(np.log(p) / n) / 2.0          # 1 - p^(1/n), halved: both signs
    return float(norm.isf(tail))


def neighbourhood_support(feet, d, ok, alpha: float = ALPHA, faces=None) -> Support:
    """The neighbourhood-support rule (module docstring) on the evaluated points ``ok``.

    Parameters
    ----------
    feet : (N, 3) float64
        Foot points on the CAD (model frame, mm).
    d : (N,) float64
        Signed deviations (any value where not ``ok``).
    ok : (N,) bool
        The evaluated points.
    faces : (N,) int, optional
        The CAD face of each foot: a point the median test leaves out is kept only by
        neighbours on its own face (a moved boss's wall points, read against the face at its
        foot, are smooth with the wall, not with that face).

    Returns
    -------
    Support
    """
    from ..measures._grid_kernels import kernel_array, mark_within
    from ..measures.spacing import median_spacing, neighbourhood_median
    from scipy.spatial import cKDTree

    n = d.shape[0]
    ev = np.flatnonzero(ok)
    none = np.zeros(n, bool)
    if ev.size < 10:
        return Support(none, float("nan"), float("inf"), float("nan"), float("nan"))
    ev_pts = np.ascontiguousarray(feet[ev])
    spacing = median_spacing(None, ev_pts)
    if not np.isfinite(spacing) or spacing <= 0:
        return Support(none, float("nan"), float("inf"), spacing, float("nan"))
    dv = d[ev]
    radius = RADIUS * spacing
    sample = np.arange(0, ev.size, max(1, ev.size // SAMPLE))
    m0 = float(np.median(dv))
    # the noise from neighbour differences on the sample (a tree of the points around it)
    near = np.empty(ev.size, bool)
    mark_within(kernel_array(ev_pts), kernel_array(ev_pts[sample]), 2.0 * radius, near)
    loc = np.flatnonzero(near)
    dist, j = cKDTree(ev_pts[loc]).query(ev_pts[sample], k=2, distance_upper_bound=radius)
    pair = np.isfinite(dist[:, 1])
    if np.count_nonzero(pair) < 10:
        return Support(none, float("nan"), float("inf"), spacing, float("nan"))
    diff = dv[sample[pair]] - dv[loc[j[pair, 1]]]
    noise = 1.4826 * float(np.median(np.abs(diff))) / np.sqrt(2.0)
    z = _z(ev.size, alpha)
    thr = z * noise
    if not thr > 0:
        return Support(none, noise, thr, spacing, z)
    cand = np.flatnonzero(np.abs(dv - m0) > thr)          # within z sigma of the bulk: kept
    out = none.copy()
    if cand.size:
        near = np.empty(ev.size, bool)
        mark_within(kernel_array(ev_pts), kernel_array(ev_pts[cand]), 2 * radius * (1 + 1e-6),
                    near)
        keep = np.flatnonzero(near)
        tree = cKDTree(ev_pts[keep], balanced_tree=False, compact_nodes=False)
        med = neighbourhood_median(tree, keep, dv, ev_pts[cand], 2 * radius, k=NEIGHBOURS)
        cand = cand[np.abs(dv[cand] - med) > thr]
        face = np.zeros(ev.size, np.int64) if faces is None else np.asarray(faces)[ev]
        cand = _rescue(cand, ev_pts, dv - m0, face, spacing, thr)
        out[ev[cand]] = True
    return Support(out, noise, thr, spacing, z)


def _rescue(cand, pts, d, face, spacing, thr) -> np.ndarray:
    """The points of ``cand`` (left out by the median test) that stay left out: those no
    bracket keeps, round by round, and then those not in a :data:`GROUP` of same-sided
    points within 2 :data:`RADIUS` spacings of each other that all pass when they may bracket
    each other (``d``: deviations from the scan's median)."""
    from ..measures._grid_kernels import kernel_array, mark_within
    from ..measures.components import linked_components
    from scipy.spatial import cKDTree

    held = np.ones(len(pts), bool)
    held[cand] = False
    # a layer over the measured surface (a reflection): the surface is seen beside its points,
    # within BESIDE spacings; a defect replaces the surface there, it is not rescued
    bulk = np.flatnonzero(held & (np.abs(d) <= thr))
    if bulk.size:
        seen = cKDTree(pts[bulk]).query_ball_point(pts[cand], BESIDE * spacing,
                                                   return_length=True) > 0
        cand, layer = cand[~seen], cand[seen]
    else:
        layer = cand[:0]
    test = cand
    for _ in range(RESCUE_ROUNDS):                      # a rescued point may bracket the next
        back = test[_bracketed(test, held, pts, d, face, spacing, thr)] if test.size else test
        if not back.size:
            break
        held[back] = True
        cand = cand[~held[cand]]
        near = np.empty(len(pts), bool)
        mark_within(kernel_array(pts), kernel_array(pts[back]), 2.0 * RADIUS * spacing, near)
        test = cand[near[cand]]
    if cand.size < GROUP:
        return np.concatenate([cand, layer])
    pairs = cKDTree(pts[cand]).query_pairs(2.0 * RADIUS * spacing, output_type="ndarray")
    a, b = cand[pairs[:, 0]], cand[pairs[:, 1]]
    pairs = pairs[(np.sign(d[a]) == np.sign(d[b])) & (face[a] == face[b])]
    _, label = linked_components(cand.size, pairs)
    size = np.bincount(label)
    near = np.bincount(pairs.ravel(), minlength=cand.size)     # same-sided within 2 RADIUS
    most = np.zeros(size.size, np.int64)
    np.maximum.at(most, label, near)
    grouped = (size[label] >= GROUP) & _unlikely_by_chance(cand, most[label], pts, d, spacing)
    if not grouped.any():
        return np.concatenate([cand, layer])
    together = held.copy()
    together[cand[grouped]] = True
    ok = np.ones(cand.size, bool)
    ok[grouped] = _bracketed(cand[grouped], together, pts, d, face, spacing, thr)
    whole = np.bincount(label, weights=~ok, minlength=size.size) == 0
    return np.concatenate([cand[~(grouped & whole[label])], layer])


def _unlikely_by_chance(cand, most, pts, d, spacing) -> np.ndarray:
    """Per point of ``cand``: whether ``most`` same-sided left-out points within 2
    :data:`RADIUS` spacings of one point of its group are unlikely (:data:`ALPHA`) among this
    many scattered at random: ``n P(Poisson(lam) >= most) < ALPHA`` with ``lam`` the expected
    number there.  Among the scattered outliers of a poor scan (10 % of its points) groups form
    by chance and are not taken for a surface."""
    from ..measures._grid_kernels import count_within, kernel_array
    from scipy.stats import poisson

    around = np.empty(cand.size, np.int64)
    count_within(kernel_array(pts), kernel_array(pts[cand]), 2.0 * RADIUS * spacing, len(pts),
                 around)
    side = d[cand] > 0
    n_side = np.where(side, np.count_nonzero(side), np.count_nonzero(~side))
    lam = n_side / len(pts) * float(np.mean(around))
    return n_side * poisson.sf(most - 1, lam) < ALPHA


def _bracketed(idx, held, pts, d, face, spacing, thr) -> np.ndarray:
    """Whether the kept surface (``held``) around each point ``idx`` is smooth through it:
    within its kept neighbours' range or bracketed by one of them and a point beyond (module
    docstring), within ``thr``."""
    if len(idx) > CHUNK:
        return np.concatenate([_bracketed(idx[i:i + CHUNK], held, pts, d, face, spacing, thr)
                               for i in range(0, len(idx), CHUNK)])
    from ..measures._grid_kernels import kernel_array, mark_within
    from scipy.spatial import cKDTree

    radius = RADIUS * spacing
    near = np.empty(len(pts), bool)
    mark_within(kernel_array(pts), kernel_array(pts[idx]), 2.0 * radius * (1 + 1e-6), near)
    loc = np.flatnonzero(near)
    m = min(BRACKET_NEIGHBOURS + 1, loc.size)
    dist, nb = cKDTree(pts[loc]).query(pts[idx], k=m, distance_upper_bound=2.0 * radius)
    dist, nb = dist.reshape(len(idx), m), nb.reshape(len(idx), m)
    nb = loc[np.minimum(nb, loc.size - 1)]
    found = np.isfinite(dist) & (dist > 0) & held[nb] & (face[nb] == face[idx][:, None])
    u = pts[nb] - pts[idx][:, None, :]                      # i -> j, (n, m, 3)
    h = np.where(found, dist, np.nan)
    w = u[:, None, :, :] - u[:, :, None, :]                 # j -> k, (n, j, k, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        ahead = np.einsum("njkc,njc->njk", w, u) / h[:, :, None]
        side = np.linalg.norm(w, axis=3) ** 2 - ahead ** 2
        line = (found[:, :, None] & found[:, None, :]
                & (ahead >= AHEAD * h[:, :, None]) & (side <= ahead ** 2))
        dj = d[nb][:, :, None]
        p = dj - (d[nb][:, None, :] - dj) * h[:, :, None] / ahead
    di = d[idx][:, None, None]
    w = WIDEN * thr
    hit = line & (di >= np.minimum(dj, p) - w) & (di <= np.maximum(dj, p) + w)
    with np.errstate(invalid="ignore"):                    # within the kept neighbours' range
        between = ((np.count_nonzero(found, axis=1) >= 3)
                   & (d[idx] >= np.min(np.where(found, d[nb], np.inf), axis=1))
                   & (d[idx] <= np.max(np.where(found, d[nb], -np.inf), axis=1)))
    return between | hit.any(axis=(1, 2))
