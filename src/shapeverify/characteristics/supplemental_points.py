"""Scan points that lie on a file's supplemental geometry, not on the part.

A STEP file may hold, beside its solid, open shells and free faces a designer adds for
construction or annotation (:attr:`shapeverify.cad.model.Model.supplemental`; NIST FTC 10: 18
faces 1.25-1.69 mm off the solid).  No real part has material there, but a "scan" made by
tessellating the whole file (every face OpenCASCADE reads, as an independent sampler does)
has points on them: on a perfect FTC 10, 30-135 points 0.3-2.3 mm outside faces 177 and 179,
a dense surface the outlier tests keep, and the profile GT10 (1.5 mm, A|B|C) read 2.88 mm:
**fail** on every perfect scan.

A point is on supplemental geometry when it lies on it -- its distance to the nearest sample
of the supplemental faces, along that sample's normal, at most ``NEAR`` x the scan's noise,
and across it within ``ACROSS`` x the samples' spacing -- and far from the part (``|d|`` at
least ``FAR`` x the noise and ``RATIO`` x its distance to the supplemental face).  Such points
are left out of every characteristic and counted (``excluded: on_supplemental_geometry``).
A point on the part where a supplemental face touches it (CTC 04's fill over a pocket) is
nearer the part than ``FAR`` noise: it stays.
"""
from __future__ import annotations

import numpy as np

__all__ = ["on_supplemental"]

NEAR = 4.0
ACROSS = 1.5
FAR = 6.0
RATIO = 4.0

#: the last model's samples: (model, spacing, samples) -- one entry, so a service or a batch
#: going through many models keeps none of them alive
_LAST: list = []


def _samples(model, spacing: float):
    """(points, normals, spacing) sampled on ``model``'s supplemental faces (the last model's
    kept)."""
    if _LAST and _LAST[0] is model and _LAST[1] == float(spacing):
        return _LAST[2]
    from ..cad.model import Model
    from ..cad.sampling import sample_model

    sub = Model(faces=tuple(model.faces[i] for i in model.supplemental), unit=model.unit,
                scale_to_mm=model.scale_to_mm, source=model.source)
    mp = sample_model(sub, spacing)
    out = (np.asarray(mp.points, np.float64), np.asarray(mp.normals, np.float64),
           float(mp.spacing))
    _LAST[:] = [model, float(spacing), out]
    return out


def on_supplemental(model, X, d, candidates, spacing: float, noise: float) -> np.ndarray:
    """(n,) bool: which points ``X`` (model frame; ``d`` their signed distances to the part,
    only ``candidates`` looked at) lie on ``model``'s supplemental geometry (module
    docstring); ``spacing``: of the samples of those faces, ``noise``: the scan's sigma."""
    out = np.zeros(X.shape[0], bool)
    if not getattr(model, "supplemental", ()) or not np.isfinite(noise) or noise <= 0:
        return out
    far = candidates & np.isfinite(d) & (np.abs(d) >= FAR * noise)
    if not far.any():
        return out
    P, N, s = _samples(model, spacing)
    if not len(P):
        return out
    from shapeverify._lazy import cKDTree

    idx = np.flatnonzero(far)
    _, j = cKDTree(P).query(X[idx], k=1)
    gap = X[idx] - P[j]
    along = np.abs(np.einsum("ij,ij->i", gap, N[j]))
    across = np.sqrt(np.maximum(np.einsum("ij,ij->i", gap, gap) - along ** 2, 0.0))
    hit = (along <= NEAR * noise) & (across <= ACROSS * s) & \
        (np.abs(d[idx]) >= RATIO * along)
    out[idx[hit]] = True
    return out
