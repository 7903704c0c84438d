"""Pose hypotheses for a near-axisymmetric part (an impeller, a fan, a wheel): the scan's axis
direction onto the model's, then one point pair.

Why: an impeller seen from a sensor's frame (a third to a half of it) shows its hub, whose
normals fix the axis' direction but not its position (a flat top), and blades that are not
turned.  Its principal axes say little, its FPFH triples did not hold the true pose
(also at 2-3 x finer voxels or 3 x more RANSAC), and the solid-of-revolution hypotheses do
not apply (a third of its normal lines meet its axis): 2 of 8 such views ended right.

How: with the scan's axis direction ``a`` known (:func:`._revolution.axis_directions`, the
best two) and put on the model's (:func:`._restart.symmetry_axis`) both ways up, a pose has
one free spin and a translation, so one scan point paired with one model point fixes it: the
spin takes the scan normal's part across the axis onto the model normal's, the translation
the point onto the point.  The pairs are each scan feature point's :data:`MATCHES` nearest
model points in FPFH space whose normals make the same angle with the axis (within
:data:`SLOPE`; the angle does not change under the spin).  All poses are screened by the fit of
:data:`SCREEN` scan points, the best :data:`REFINED` refined by the global search's short ICP
and scored at its sharp fit distance; the best :data:`KEEP` join the global search's other
hypotheses under its objective.  On the bundled impeller's 8 views in a sensor frame the
global search then ended right on 7 (on the nearest blade copy), against 2; about 0.2 s
more (global search 0.4 -> 0.6 s, median).
"""
from __future__ import annotations

import numpy as np

from .rigid import make_transform

#: nearest model descriptors tried per scan feature point
MATCHES = 8
#: |cos| of the angles of the paired normals with the axis may differ by this much
SLOPE = 0.1
#: scan normals closer to the axis than this |cos| do not fix the spin and are not paired
ALONG = 0.9
#: scan points of the screening fit, poses refined, poses returned
SCREEN, REFINED, KEEP = 100, 20, 4


def _spins(axis: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rotations (k, 3, 3) by the angles theta (k,) about the unit axis (Rodrigues)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def _pair_poses(X, Nrm, F, side, a, am):
    """Poses (k, 4, 4) pairing the scan points X (normals Nrm, descriptors F) with model points,
    for the scan axis direction a put on the model's am both ways up."""
    from ._revolution import _onto

    k = min(MATCHES, side.features.shape[0])
    _, J = side.ftree.query(F, k=k)
    i = np.repeat(np.arange(X.shape[0]), k)
    j = np.asarray(J).reshape(-1)
    out = []
    for up in (1.0, -1.0):
        R0 = _onto(up * a, am)
        n0 = Nrm @ R0.T
        h = n0 @ am
        mh = side.normals[j] @ am
        ok = (np.abs(h[i]) <= ALONG) & (np.abs(mh - h[i]) <= SLOPE)
        ii, jj = i[ok], j[ok]
        u = n0[ii] - h[ii, None] * am
        v = side.normals[jj] - mh[ok, None] * am
        theta = np.arctan2(np.cross(u, v) @ am, np.einsum("ij,ij->i", u, v))
        R = _spins(am, theta) @ R0
        T = np.zeros((ii.shape[0], 4, 4))
        T[:, :3, :3] = R
        T[:, :3, 3] = side.points[jj] - np.einsum("kij,kj->ki", R, X[ii])
        T[:, 3, 3] = 1.0
        out.append(T)
    return np.concatenate(out)


def hypotheses(P: np.ndarray, side, S: np.ndarray, radius: float, features) -> list[np.ndarray]:
    """Up to :data:`KEEP` poses (4, 4), best first (module docstring); [] when the model has no
    near-symmetry axis or is a solid of revolution (:mod:`._revolution` poses it).

    P (n, 3) the scan, S the global search's scored subset of it, radius the scan's RMS
    radius, features (X, normals towards the sensor, FPFH) of its voxel subsample."""
    from . import _restart, _revolution
    from .global_search import _quick_fits, _sharp_fits, refine

    ax = _restart.symmetry_axis(side)
    X, Nrm, F = features
    if ax is None or X.shape[0] < 10 or _revolution.model_axis(side) is not None:
        return []
    am = ax[0]
    dense = _revolution.scan_normals(P, side)
    if dense is None:
        return []
    dirs = _revolution.axis_directions(*dense, _revolution.NEAR * side.size)
    T = np.concatenate([_pair_poses(X, Nrm, F, side, a, am) for a in dirs])
    if T.shape[0] == 0:
        return []
    fit = _quick_fits(side.tree, S[:SCREEN], T, 2.0 * side.voxel)
    best = np.argsort(-fit, kind="stable")[:REFINED]
    poses = [refine(S, side, T[k], radius, 8) for k in best]
    fits, _ = _sharp_fits(side, S, poses)
    order = np.argsort(-np.asarray(fits), kind="stable")[:KEEP]
    return [make_transform(poses[k][:3, :3], poses[k][:3, 3]) for k in order]
