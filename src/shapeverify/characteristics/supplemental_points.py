"""Scan points that lie on a file's supplemental geometry, not on the part.

A STEP file may hold, beside its solid, open shells and free faces a designer adds for
construction or annotation (:attr:`shapeverify.cad.model.Model.supplemental`; NIST FTC 10: 18
faces 1.25-1.69 mm off the solid).  No real part has material there, but a "scan" made by
tessellating the whole file (every face OpenCASCADE reads, as an independent sampler does)
has points on them: on a perfect FTC 10, 30-135 points 0.3-2.3 mm outside faces 177 and 179,
a dense surface the outlier tests keep, and the profile GT10 (1.5 mm, A|B|C) read 2.88 mm:
**fail** on every perfect scan.

A point is on supplemental geometry when it lies on it -- its exact distance to those faces
(NURBS point inversion with trims on a model of them alone, :func:`shapeverify.nearest.prepare`)
at most ``NEAR`` x the scan's noise -- and far from the part (``|d|`` at least ``FAR`` x the
noise and ``RATIO`` x its distance to the supplemental face).  Such points are left out of
every characteristic and counted (``excluded: on_supplemental_geometry``).  A point on the
part where a supplemental face touches it (CTC 04's fill over a pocket) is nearer the part
than ``FAR`` noise: it stays.

Exact, not the tangent plane of the nearest sample of those faces (the rule before): on a
curved supplemental face that plane is off by up to spacing^2 x curvature / 8, so points
there were missed.  On the perfect FTC 10 scan (``benchmarks/check_supplemental_points.py``)
the samples found 133 of the 140 supplemental points 0.3-3 mm off the part, the exact distance
all 140 (185 points left out of GT10, 178 before; none of the part's either way); with a
1.5 mm bump on face 177 a missed point 2.06 mm off stayed (the outlier rescue keeps it: within
the bump's range) and GT10 read 4.12 mm, now 3.02 (2 x 1.5).  Only the ``far`` candidates are
projected (190 there): about 0.5 ms of CPU; the first call for a model prepares its
supplemental faces (FTC 10: 1,536 model points, 0.15-0.3 s of CPU; the samples took 0.03 s).
"""
from __future__ import annotations

import numpy as np

__all__ = ["on_supplemental"]

NEAR = 4.0
FAR = 6.0
RATIO = 4.0

#: the last model's closest-point structure of its supplemental faces: (model, spacing,
#: Prepared) -- one entry, so a service or a batch going through many models keeps none alive
_LAST: list = []


def _prepared(model, spacing: float):
    """:class:`~shapeverify.nearest.Prepared` of ``model``'s supplemental faces alone at
    ``spacing`` (the last model's kept)."""
    if _LAST and _LAST[0] is model and _LAST[1] == float(spacing):
        return _LAST[2]
    from ..cad.model import Model
    from ..nearest.prepared import prepare

    sub = Model(faces=tuple(model.faces[i] for i in model.supplemental), unit=model.unit,
                scale_to_mm=model.scale_to_mm, source=model.source)
    prep = prepare(sub, spacing=float(spacing), allow_incomplete=True)
    _LAST[:] = [model, float(spacing), prep]
    return prep


def on_supplemental(model, X, d, candidates, spacing: float, noise: float) -> np.ndarray:
    """(n,) bool: which points ``X`` (model frame; ``d`` their signed distances to the part,
    only ``candidates`` looked at) lie on ``model``'s supplemental geometry (module
    docstring); ``spacing``: of the model points of those faces, ``noise``: the scan's
    sigma."""
    out = np.zeros(X.shape[0], bool)
    if not getattr(model, "supplemental", ()) or not np.isfinite(noise) or noise <= 0:
        return out
    far = candidates & np.isfinite(d) & (np.abs(d) >= FAR * noise)
    if not far.any():
        return out
    idx = np.flatnonzero(far)
    gap = np.abs(np.asarray(_prepared(model, spacing).closest(X[idx], exact=True).distances,
                            np.float64))
    hit = np.isfinite(gap) & (gap <= NEAR * noise) & (np.abs(d[idx]) >= RATIO * gap)
    out[idx[hit]] = True
    return out
