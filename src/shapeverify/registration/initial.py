"""Coarse global alignment by principal axes, for starts too far off for ICP.

The scan's centroid and principal axes (eigenvectors of its covariance) are matched with those of
candidate sets of model points: all model points and, because a single-shot scan sees only one
side of a part, the "visible" halves ``{normal . a > 0}`` for each of the six directions ``±a``
along the model's principal axes.  The axes of two point sets agree only up to order and sign,
so all 24 proper rotations that map one orthonormal frame onto the other are tried.  Every
candidate is scored by a robust residual (the median distance of a random subset of scan points
to the model); the best few are refined by a short Huber ICP on that subset and the best refined
one wins.

What it can handle: any rotation (including upside down) and any translation, for scans that
cover most of the part or most of one side of it, when the part (or that side) has a clearly
elongated or flattened shape.  What it cannot: parts with rotational symmetry or nearly equal
principal moments (the axes are then arbitrary -- the result may be a symmetric copy of the true
pose), scans that cover a small piece of the model (their centroid and axes say little about
where they belong), or heavily cluttered scans (outliers bias the axes).  The result is coarse
(typically a few degrees and a few percent of the size); always follow it with :func:`register`.
"""
from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass

import numpy as np
from shapeverify._lazy import cKDTree

from .._random import generator
from .rigid import make_transform

__all__ = ["principal_axes_alignment", "InitialAlignment", "candidate_poses", "read_init"]

_MAX_MODEL = 20000  # model points used for the axes and the scoring


@dataclass(frozen=True, eq=False, repr=False)
class InitialAlignment:
    """Result of :func:`principal_axes_alignment`.

    T_model_scan : (4, 4) coarse pose; score : median |distance| (mm) of the scored subset after
    the short refinement; n_candidates : poses tried.
    """

    T_model_scan: np.ndarray
    score: float
    n_candidates: int

    def __repr__(self) -> str:
        return f"InitialAlignment(score={self.score:.4g} mm, n_candidates={self.n_candidates})"


def _frame(X: np.ndarray):
    c = X.mean(axis=0)
    lam, V = np.linalg.eigh(np.cov((X - c).T))
    V = V[:, ::-1]
    if np.linalg.det(V) < 0:
        V[:, 2] *= -1
    return c, V


def _proper_maps() -> list[np.ndarray]:
    """The 24 signed permutation matrices with determinant +1."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            M = np.zeros((3, 3))
            M[np.arange(3), perm] = signs
            if np.linalg.det(M) > 0:
                out.append(M)
    return out


def _score(tree, S, T) -> float:
    """Median distance from the moved scan subset to the nearest model point (robust)."""
    d, _ = tree.query(S @ T[:3, :3].T + T[:3, 3])
    return float(np.median(d))


def candidate_poses(scan: np.ndarray, M: np.ndarray, Nm: np.ndarray) -> list[np.ndarray]:
    """The principal-axes poses (4, 4): the scan's centroid and axes onto those of the model
    points M (m, 3) and of their visible halves (outward normals Nm along +-each axis), under
    all 24 proper signed axis permutations (module docstring)."""
    cs, Vs = _frame(scan)
    _, Vm_all = _frame(M)
    subsets = [M]
    for k in range(3):
        for sgn in (1.0, -1.0):
            sel = (Nm @ (sgn * Vm_all[:, k])) > 0.0
            if sel.sum() >= 10:
                subsets.append(M[sel])
    cands = []
    for sub in subsets:
        cm, Vm = _frame(sub)
        for Q in _proper_maps():
            R = Vm @ Q @ Vs.T
            cands.append(make_transform(R, cm - R @ cs))
    return cands


def principal_axes_alignment(scan, prep, rng=0, n_sample: int = 600,
                             n_refine: int = 6) -> InitialAlignment:
    """Coarse T_model_scan from principal axes of the scan and of (visible) model points.

    Parameters
    ----------
    scan : (N, 3) float64
    prep : Prepared
        Uses ``prep.points`` (ModelPoints: points and outward normals) and ``prep.closest``.
    rng : None, int or Generator
        Seeds the scoring subset.
    n_sample : int
        Scan points used for scoring and refinement.
    n_refine : int
        Best-scoring candidates refined by a short Huber ICP.

    Returns
    -------
    InitialAlignment
        ``score`` is the median distance (mm) from the scan subset to the nearest of up to
        20,000 model points.

    Raises
    ------
    RegistrationError
        When no candidate has a finite score (every candidate leaves most points far away).
    """
    from .icp import RegistrationError, _check_scan, register

    S_all = _check_scan(scan)
    rng = generator(rng)
    S = S_all[rng.choice(S_all.shape[0], min(n_sample, S_all.shape[0]), replace=False)]
    mp = prep.points
    M, Nm = np.asarray(mp.points, np.float64), np.asarray(mp.normals, np.float64)
    if M.shape[0] > _MAX_MODEL:
        keep = rng.choice(M.shape[0], _MAX_MODEL, replace=False)
        M, Nm = M[keep], Nm[keep]
    tree = cKDTree(M)
    cands = candidate_poses(S_all, M, Nm)
    scores = np.array([_score(tree, S, T) for T in cands])
    order = np.argsort(scores)[:n_refine]
    best_T, best = None, np.inf
    for i in order:
        if not np.isfinite(scores[i]):
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                reg = register(S, prep, init=cands[i], loss="huber", max_iterations=15,
                               rtol=1e-4, rng=rng)
            T = reg.T_model_scan
        except RegistrationError:
            T = cands[i]
        s = _score(tree, S, T)
        if s < best:
            best_T, best = T, s
    if best_T is None:
        raise RegistrationError("principal-axes alignment found no candidate pose that brings "
                                "the scan near the model")
    return InitialAlignment(best_T, best, len(cands))


def read_init(path) -> np.ndarray:
    """Read a start pose T_model_scan (4, 4) from ``T.json`` or ``T.npy``.

    JSON: a 4x4 nested list, or an object ``{"T_model_scan": [[...], ...]}``; ``.npy``: a
    (4, 4) array.  The matrix must be rigid (orthonormal rotation with det +1, last row
    ``[0, 0, 0, 1]``, mm); it maps scan coordinates into model coordinates.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Unknown suffix, unreadable content, or not a rigid 4x4 transform (the message says
        which).
    """
    import json
    from pathlib import Path

    from .icp import validate_pose

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"init file {str(p)!r} does not exist")
    suf = p.suffix.lower()
    if suf == ".json":
        try:
            obj = json.loads(p.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"init file {str(p)!r} is not valid JSON: {exc}") from None
        if isinstance(obj, dict):
            if "T_model_scan" not in obj:
                raise ValueError(f"init file {str(p)!r}: a JSON object must hold the key "
                                 f"'T_model_scan' (found {sorted(obj)[:5]})")
            obj = obj["T_model_scan"]
        try:
            T = np.asarray(obj, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"init file {str(p)!r}: T_model_scan must be a 4x4 nested list "
                             "of numbers") from None
    elif suf == ".npy":
        try:
            from shapeverify.io.npy import load_npy

            T = load_npy(p, error=ValueError)   # header checked against the file size
        except (ValueError, OSError) as exc:
            raise ValueError(f"init file {str(p)!r} is not a readable .npy array: {exc}") from None
        T = np.asarray(T, dtype=np.float64)
    else:
        raise ValueError(f"init file {str(p)!r}: use a .json (4x4 nested list or "
                         "{'T_model_scan': ...}) or a .npy (4, 4) file")
    return validate_pose(T, f"init file {str(p)!r}")
