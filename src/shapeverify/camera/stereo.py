"""Stereo phase matching and triangulation of one fringe image per camera (thesis §3.1, Paper III).

The chain, for a rig of two cameras and a projector (:mod:`shapeverify.camera.rig`):

1. wrapped phase and modulation of each image (:func:`shapeverify.camera.fringe_analysis.ftp` or
   ``wff``), with the lobe chosen so that both phases increase with the projector column;
2. relative fringe orders in the left image by a quality-guided flood fill: each connected region
   of usable pixels gets ``psi + 2 pi m`` continuous, with one unknown integer offset ``K``;
3. the offset of each region is voted: for a sample of its pixels and every candidate ``K``, the
   projector's ray surface of the absolute phase ``psi + 2 pi (m + K)`` cuts the pixel's ray in a
   3-D point, which the right camera must see with the same wrapped phase.  Only the right order
   is consistent in both views.  With a CAD model at a nominal pose, the candidates are limited to
   the order the model predicts (+- ``cad_window``) -- the idea of Paper V;
4. every pixel: the sub-pixel point on its epipolar line in the right image whose phase equals the
   left phase (Newton along the left ray, from the projector's estimate), which *is* the
   triangulation of the left ray with the right point's ray (lens distortion included); points
   whose projector phase disagrees with the stereo point by more than ``tol_projector`` are
   dropped, and failed patches are voted again as regions of their own;
5. per-point quality = sqrt(quality_left * quality_right) * (1 - |projector residual| / tol).

A rig with equal baselines on both sides of the projector cannot tell a wrong order from the right
one on a plane parallel to the baseline (the wrong surface is consistent in both views); there,
pass the model and nominal pose, or a tight ``depth_range``.

The projected pattern must follow the rig file's convention (intensity ``(1 + cos phase) / 2``).
A pattern with another phase origin shows as projector residuals on the largest region; an offset
search then finds and compensates it (``info["pattern_offset"]``, logged).  That works for a sine
or an inverted pattern; an offset close to the residual of a wrong fringe order (about +-1 rad for
typical rigs) cannot be told from that order.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from shapeverify.camera import _optics_kernels as _k
from shapeverify._renamed import grouped_keywords

__all__ = ["StereoMatching", "StereoScan", "measure", "phase_direction"]

log = logging.getLogger(__name__)
TWO_PI = 2.0 * np.pi


@dataclass(frozen=True, repr=False)
class StereoScan:
    """Points measured from one pair of fringe images.

    Attributes
    ----------
    points : (N, 3) float64
        Points in the rig (left camera) frame, mm.
    quality : (N,) float64
        Per-point quality in [0, 1] (fringe contrast in both views times order consistency).
    pixels : (N, 2) int64
        Left-camera pixel (u, v) of each point.
    residual : (N,) float64
        Projector-phase residual (rad) of each stereo point.
    usable : (H, W) bool
        Left pixels with a usable phase (before matching).
    timings : dict
        Seconds per stage.
    info : dict
        Regions voted, candidate orders, pixels rejected.
    """

    points: np.ndarray
    quality: np.ndarray
    pixels: np.ndarray
    residual: np.ndarray
    usable: np.ndarray
    timings: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.points)

    def __repr__(self):
        return (f"StereoScan(points={len(self.points):,}, median quality={float(np.median(self.quality)) if len(self.quality) else 0:.3g}, "
                f"{sum(self.timings.values()):.3g} s)")


def _kargs(dev):
    return dev.K, dev.dist, dev.R, dev.T


def _working_distance(rig) -> float:
    """Left-ray parameter where the left and projector optical axes pass closest."""
    c0, d0 = np.zeros(3), np.array([0.0, 0.0, 1.0])
    c1, d1 = rig.projector.center, rig.projector.R[2]
    w = c0 - c1
    a, b, c, d, e = d0 @ d0, d0 @ d1, d1 @ d1, d0 @ w, d1 @ w
    den = a * c - b * b
    t = (b * e - c * d) / den if abs(den) > 1e-12 else 300.0
    return float(t) if t > 0 else float(np.linalg.norm(c1)) * 3


def phase_direction(rig, camera: str, t_mid: float | None = None) -> np.ndarray:
    """Image direction (2,) in ``camera`` along which the projector column (pattern phase) increases."""
    t_mid = _working_distance(rig) if t_mid is None else t_mid
    dev = getattr(rig, camera)
    X = np.array([0.0, 0.0, t_mid])
    axis = rig.projector.R[1 if rig.pattern.direction == "rows" else 0]
    uv, _ = dev.project(np.vstack([X, X + 0.5 * axis]))
    d = uv[1] - uv[0]
    if not np.all(np.isfinite(d)):
        raise ValueError(f"the {camera} camera does not see the projector's working volume: check the rig's R, T")
    return d / np.linalg.norm(d)


_RAYS: dict = {}


def _left_rays(rig) -> np.ndarray:
    key = (rig.left.K.tobytes(), rig.left.dist.tobytes(), rig.left.size)  # the left camera is the frame
    r = _RAYS.get(key)
    if r is None:
        _RAYS.clear()
        r = np.ascontiguousarray(rig.left.rays(rig.left.pixel_grid())[1])
        _RAYS[key] = r
    return r


def _depth_bracket(rig, depth_range, t_mid):
    if depth_range is not None:
        z0, z1 = (float(x) for x in depth_range)
        if not 0 < z0 < z1:
            raise ValueError(f"depth_range must be (z_near, z_far) with 0 < z_near < z_far (mm), got {depth_range}")
        return z0, z1 * 1.5  # ray parameter >= z; the far end covers oblique rays
    # where the left optical axis is seen by the right camera and the projector
    ts = t_mid * np.geomspace(0.2, 5.0, 400)
    X = np.column_stack([np.zeros_like(ts), np.zeros_like(ts), ts])
    ok = np.ones(len(ts), bool)
    for dev in (rig.right, rig.projector):
        uv, z = dev.project(X)
        ok &= (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= dev.width - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= dev.height - 1)
    if not ok.any():
        raise ValueError("the left camera's optical axis is not seen by both the right camera and the projector; "
                         "pass depth_range=(z_near, z_far)")
    return float(ts[ok].min()) * 0.7, float(ts[ok].max()) * 1.4


def _sample(idx, n):
    if len(idx) <= n:
        return idx
    return idx[np.linspace(0, len(idx) - 1, n).round().astype(np.int64)]


def _candidate_range(rig, dirs, psi, m, t_lo, t_hi, delta=0.0):
    """Integer offsets K such that psi + 2 pi (m + K) is a projector phase seen along the rays."""
    rows = rig.pattern.direction == "rows"
    P = rig.pattern.period_px
    lo, hi = np.inf, -np.inf
    for t in np.geomspace(t_lo, t_hi, 64):
        uv, z = rig.projector.project(dirs * t)
        c = uv[:, 1 if rows else 0]
        k = c / P - (psi + delta) / TWO_PI - m
        ok = np.isfinite(k) & (z > 0)
        if ok.any():
            lo, hi = min(lo, k[ok].min()), max(hi, k[ok].max())
    if not np.isfinite(lo):
        return np.zeros(0, np.int64)
    return np.arange(int(np.floor(lo)), int(np.ceil(hi)) + 1, dtype=np.int64)


def _vote(rig, dirs, psi, m, cands, psi_r, valid_r, t_mid, t_lo, t_hi, tol, prior=None, delta=0.0):
    """Best offset of a region and its score (fraction of samples consistent), second-best score.

    With a ``prior`` (the CAD-predicted offset, fractional), the offset nearest to it among those
    scoring at least 0.9 x the best wins: the stereo check alone cannot split near-ties.
    """
    err = np.empty((len(dirs), len(cands)))
    P = rig.pattern.period_px
    rows = rig.pattern.direction == "rows"
    _k.candidate_errors(np.ascontiguousarray(dirs), psi, m.astype(np.int64), cands, *_kargs(rig.projector), rows, P,
                        *_kargs(rig.right), psi_r, valid_r, t_mid, t_lo, t_hi, delta, err)
    good = np.abs(np.nan_to_num(err, nan=np.pi)) < tol
    score = good.mean(axis=0)
    mean_err = np.array([np.abs(err[good[:, c], c]).mean() if good[:, c].any() else np.pi for c in range(len(cands))])
    order = np.lexsort((mean_err, -score))
    best = order[0]
    if prior is not None:
        near = np.flatnonzero(score >= 0.9 * score[best])
        best = int(near[np.argmin(np.abs(cands[near] - prior))])
        order = np.concatenate([[best], order[order != best]])
    second = score[order[1]] if len(order) > 1 else 0.0
    return int(cands[best]), float(score[best]), float(second)


def _cad_orders(rig, model, T_left_model, dirs, psi, m, delta=0.0):
    """Offsets K predicted by the CAD model at the nominal pose for sample rays (NaN where it misses)."""
    from shapeverify.camera.intersect import intersect_rays

    T = np.asarray(T_left_model, dtype=np.float64)
    R, t = T[:3, :3], T[:3, 3]
    o = np.broadcast_to(-R.T @ t, dirs.shape)
    hits = intersect_rays(model, np.ascontiguousarray(o), np.ascontiguousarray(dirs @ R))
    X = hits.points @ R.T + t
    uv, z = rig.projector.project(np.where(hits.hit[:, None], X, 0.0))
    c = uv[:, 1 if rig.pattern.direction == "rows" else 0]
    k = np.where(hits.hit & (z > 0), c / rig.pattern.period_px - (psi + delta) / TWO_PI - m, np.nan)
    return k


@dataclass(frozen=True)
class StereoMatching:
    """How :func:`measure` matches the two cameras' pixels (its ``matching=``; the loose
    keywords of these names still work, with a DeprecationWarning); the fields are described in
    its Parameters."""

    depth_range: tuple | None = None
    tol_vote: float = 0.5
    tol_projector: float = 0.5
    cad_window: int = 1
    min_region: int = 64
    samples: int = 300
    min_score: float = 0.5


@grouped_keywords("matching", StereoMatching)
def measure(rig, left, right, model=None, T_left_model=None, method="ftp", analysis_options=None,
            phases=None, matching: StereoMatching = StereoMatching()) -> StereoScan:
    """3-D points from one fringe image per camera.

    Parameters
    ----------
    rig : Rig
        Calibrated rig with a projector (:mod:`shapeverify.camera.rig`).
    left, right : (H, W) array_like
        Fringe images of the left and right camera (uint8, uint16 or float), sizes as in the rig.
    model : Model, Prepared or None
        CAD model used to predict the fringe order (optional).
    T_left_model : (4, 4) or None
        Nominal pose of the model in the left camera frame (identity when a model is given without it).
    method : "ftp" or "wff"
        Single-image phase analysis (:func:`~shapeverify.camera.fringe_analysis.ftp`, ``wff``).
    matching : StereoMatching
        Groups ``depth_range``, ``tol_vote``, ``tol_projector``, ``cad_window``,
        ``min_region``, ``samples``, ``min_score`` (described below); the loose keywords
        still work, with a DeprecationWarning.
    depth_range : (z_near, z_far) or None
        Depth interval (mm, left camera z) that holds the part; default: where the left optical
        axis is seen by the right camera and the projector.
    tol_vote : float
        Right-phase error (rad) under which a sample counts as consistent in the order vote.
    tol_projector : float
        Largest projector-phase residual (rad) of a kept stereo point.
    cad_window : int
        With a model: orders within +- this of the predicted one are candidates.
    min_region : int
        Regions with fewer pixels are dropped.
    samples : int
        Pixels per region used in the vote.
    min_score : float
        A region whose best order explains fewer than this fraction of samples is dropped.
    analysis_options : dict or None
        Extra keyword arguments for the phase analysis.
    phases : (FringeAnalysis, FringeAnalysis) or None
        Phase analyses of the left and right image computed elsewhere (``method`` is then unused);
        their phases must increase with the projector column (:func:`phase_direction`).

    Returns
    -------
    StereoScan

    Raises
    ------
    ValueError
        Rig without projector, image sizes that differ from the rig, unknown method, bad ranges.
    """
    depth_range = matching.depth_range
    tol_vote = matching.tol_vote
    tol_projector = matching.tol_projector
    cad_window = matching.cad_window
    min_region = matching.min_region
    samples = matching.samples
    min_score = matching.min_score
    from shapeverify.camera.fringe_analysis import ftp, wff

    if rig.projector is None:
        raise ValueError("the rig has no projector; measuring needs its pattern (projector key of rig.json)")
    if method not in ("ftp", "wff"):
        raise ValueError(f"method must be 'ftp' or 'wff', got {method!r}")
    if T_left_model is not None:
        T_left_model = np.asarray(T_left_model, dtype=np.float64)
        if T_left_model.shape != (4, 4) or not np.all(np.isfinite(T_left_model)):
            raise ValueError(f"T_left_model must be a finite (4, 4) pose (model -> left camera), got shape "
                             f"{T_left_model.shape}")
        if model is None:
            raise ValueError("T_left_model is the pose of a model: pass model= too")
    L, Rr = np.asarray(left), np.asarray(right)
    for name, img, dev in (("left", L, rig.left), ("right", Rr, rig.right)):
        if img.ndim != 2 or img.shape != (dev.height, dev.width):
            raise ValueError(f"the {name} image has shape {img.shape}, the rig's {name} camera is "
                             f"{dev.width} x {dev.height} (W x H): pass a single-channel image of that size")
    timings = {}
    t0 = time.perf_counter()
    t_mid = _working_distance(rig)
    analyse = ftp if method == "ftp" else wff
    opts = dict(analysis_options or {})
    if phases is None:
        fa_l = analyse(L, direction=phase_direction(rig, "left", t_mid), **opts)
        fa_r = analyse(Rr, direction=phase_direction(rig, "right", t_mid), **opts)
    else:
        fa_l, fa_r = phases
    timings["phase"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    H, W = L.shape
    psi_l = np.ascontiguousarray(np.where(fa_l.mask, fa_l.phase, 0.0))
    psi_r = np.ascontiguousarray(np.where(fa_r.mask, fa_r.phase, 0.0))
    valid_r = np.ascontiguousarray(fa_r.mask)
    labels = np.empty((H, W), np.int32)
    order = np.zeros((H, W), np.int32)
    n_reg = _k.flood_unwrap(psi_l, np.ascontiguousarray(fa_l.quality), np.ascontiguousarray(fa_l.mask), 0.8 * np.pi,
                            labels, order)
    timings["unwrap"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    dirs_all = _left_rays(rig)
    t_lo, t_hi = _depth_bracket(rig, depth_range, t_mid)
    lab = labels.ravel()
    psi_flat, m_flat = psi_l.ravel(), order.ravel().astype(np.int64)
    sizes = np.bincount(lab[lab >= 0], minlength=n_reg)
    flat_idx = np.flatnonzero(lab >= 0)
    if n_reg == 1:
        by_label = [flat_idx]
    else:
        by_label = np.split(flat_idx[np.argsort(lab[flat_idx], kind="stable")], np.cumsum(sizes)[:-1]) if n_reg else []
    rows = rig.pattern.direction == "rows"
    P = rig.pattern.period_px

    delta = 0.0  # pattern phase - measured phase; 0 for the documented (1 + cos) / 2 pattern

    def resolve(region_idx, prior=None):
        """Vote the offset of a set of pixels; None when not decided."""
        s = _sample(region_idx, samples)
        d, p, mm = dirs_all[s], psi_flat[s], m_flat[s]
        cands = _candidate_range(rig, d, p, mm, t_lo, t_hi, delta)
        if model is not None and prior is None:
            kc = _cad_orders(rig, model, np.eye(4) if T_left_model is None else T_left_model, d, p, mm, delta)
            if np.isfinite(kc).sum() >= max(3, len(s) // 10):
                prior = float(np.nanmedian(kc))
                kp = int(np.round(prior))
                cands = np.arange(kp - cad_window, kp + cad_window + 1, dtype=np.int64)
        if len(cands) == 0:
            return None, 0.0, 0.0
        K, score, second = _vote(rig, d, p, mm, cands, psi_r, valid_r, t_mid, t_lo, t_hi, tol_vote, prior, delta)
        return (K if score >= min_score else None), score, second

    def match(idx):
        out_t, out_e = np.empty(len(idx)), np.empty(len(idx))
        _k.match_pixels(idx, dirs_all, psi_flat, korder[idx], *_kargs(rig.projector), rows, P, *_kargs(rig.right),
                        psi_r, valid_r, t_mid, t_lo, t_hi, tol_projector, delta, out_t, out_e)
        return out_t, out_e

    korder = np.full(H * W, np.iinfo(np.int64).min, np.int64)
    info = {"regions": int(n_reg), "voted": 0, "ambiguous": 0, "revoted": 0, "pattern_offset": 0.0}
    if n_reg and sizes.max() >= min_region:
        # a pattern rendered with another phase origin (sin, 1 - cos, ...) shifts every projector
        # ray surface: check the residuals of the largest region, search the offset if they are off
        big = by_label[int(np.argmax(sizes))]

        def residual_offset(K):
            s_idx = _sample(big, 4 * samples)
            korder[s_idx] = m_flat[s_idx] + K
            nonlocal tol_projector
            tol_save, tol_projector = tol_projector, np.pi
            tt, ee = match(s_idx)
            tol_projector = tol_save
            korder[s_idx] = np.iinfo(np.int64).min
            ok_ = np.isfinite(tt)
            return float(np.angle(np.mean(np.exp(1j * ee[ok_])))) if ok_.sum() > 10 else np.nan

        K0, sc0, _ = resolve(big)
        off = residual_offset(K0) if K0 is not None else np.nan
        if not (sc0 >= 0.8 and abs(off) <= 0.2):
            best = (sc0 if abs(off) <= 0.2 else -1.0, 0.0)
            for dlt in np.arange(0, 16) * (np.pi / 8):
                delta = float(dlt)
                K, sc, _ = resolve(big)
                if K is not None and sc > best[0]:
                    best = (sc, delta)
            delta = best[1]
            K = resolve(big)[0]
            if K is not None:
                off = residual_offset(K)
                if np.isfinite(off):
                    delta += off
            info["pattern_offset"] = float(np.angle(np.exp(1j * delta)))
            if abs(info["pattern_offset"]) > 0.2:
                log.warning("measure: the pattern's phase origin differs from the rig's by %.3f rad; "
                            "compensated", info["pattern_offset"])
    for r in range(n_reg):
        if sizes[r] < min_region:
            continue
        K, score, second = resolve(by_label[r])
        info["voted"] += 1
        if K is None:
            continue
        if second > 0.8 * score:
            info["ambiguous"] += 1
        korder[by_label[r]] = m_flat[by_label[r]] + K
    timings["orders"] = time.perf_counter() - t0

    t0 = time.perf_counter()

    idx = np.flatnonzero(korder != np.iinfo(np.int64).min)
    t_ray, resid = match(idx)
    # patches that failed (a wrong relative order inside a region) are voted again on their own
    failed = np.zeros(H * W, bool)
    failed[idx[~np.isfinite(t_ray)]] = True
    failed[(lab >= 0) & (korder == np.iinfo(np.int64).min)] = True
    comp, n_comp = ndimage.label(failed.reshape(H, W))
    if n_comp:
        cs = np.bincount(comp.ravel(), minlength=n_comp + 1)
        big = np.flatnonzero(cs >= min_region)
        big = big[big > 0]
        good = np.zeros(H * W, bool)
        good[idx[np.isfinite(t_ray)]] = True
        for c in big:
            ci = np.flatnonzero(comp.ravel() == c)
            prior = _continuity_prior(comp == c, good.reshape(H, W), korder, m_flat, psi_flat)
            K, score, second = resolve(ci, prior)
            # a patch touching resolved pixels is re-ordered only to the continuation of its
            # neighbours (that repairs a flood-fill slip; a patch the right camera does not see at
            # its true order can look consistent at a wrong one); an isolated patch needs a clear vote
            if K is None or (K != round(prior) if prior is not None else second >= 0.8 * score):
                continue
            info["revoted"] += 1
            korder[ci] = m_flat[ci] + K
            tt, ee = match(ci)
            pos = np.searchsorted(idx, ci)
            inside = (pos < len(idx)) & (idx[np.minimum(pos, len(idx) - 1)] == ci)
            new = ci[~inside]
            t_ray[pos[inside]] = np.where(np.isfinite(tt[inside]), tt[inside], t_ray[pos[inside]])
            resid[pos[inside]] = np.where(np.isfinite(tt[inside]), ee[inside], resid[pos[inside]])
            if len(new):
                idx = np.concatenate([idx, new])
                t_ray = np.concatenate([t_ray, tt[~inside]])
                resid = np.concatenate([resid, ee[~inside]])
                o = np.argsort(idx, kind="stable")
                idx, t_ray, resid = idx[o], t_ray[o], resid[o]
    ok = np.isfinite(t_ray)
    idx, t_ray, resid = idx[ok], t_ray[ok], resid[ok]
    points = dirs_all[idx] * t_ray[:, None]
    uv_r, _ = rig.right.project(points)
    qr = ndimage.map_coordinates(fa_r.quality, [uv_r[:, 1], uv_r[:, 0]], order=1, mode="nearest")
    ql = fa_l.quality.ravel()[idx]
    quality = np.sqrt(np.clip(ql * qr, 0, None)) * np.clip(1.0 - np.abs(resid) / tol_projector, 0.0, 1.0)
    timings["match"] = time.perf_counter() - t0
    info["usable_left"] = int(fa_l.mask.sum())
    info["points"] = int(len(idx))
    log.info("measure: %d points from %d usable left pixels (%d regions)", len(idx), info["usable_left"], n_reg)
    pixels = np.column_stack([idx % W, idx // W]).astype(np.int64)
    return StereoScan(points, quality, pixels, resid, fa_l.mask, timings, info)


def _continuity_prior(patch, good, korder, m_flat, psi_flat):
    """Offset K of a patch that makes its absolute phase continuous with resolved 4-neighbours (None if none)."""
    H, W = patch.shape
    ks = []
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        p = np.zeros((H, W), bool)
        q = np.zeros((H, W), bool)
        ys, yd = (slice(0, H - dy), slice(dy, H)) if dy >= 0 else (slice(-dy, H), slice(0, H + dy))
        xs, xd = (slice(0, W - dx), slice(dx, W)) if dx >= 0 else (slice(-dx, W), slice(0, W + dx))
        pair = patch[ys, xs] & good[yd, xd]
        if not pair.any():
            continue
        p[ys, xs] = pair
        q[yd, xd] = pair
        ip, iq = np.flatnonzero(p), np.flatnonzero(q)  # row-major order keeps the pairs aligned
        step = np.angle(np.exp(1j * (psi_flat[ip] - psi_flat[iq])))
        k_p = korder[iq] + np.round((psi_flat[iq] - psi_flat[ip] + step) / TWO_PI)
        ks.append(k_p - m_flat[ip])
    if not ks:
        return None
    return float(np.median(np.concatenate(ks)))
