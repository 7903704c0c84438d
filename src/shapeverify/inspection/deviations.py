"""Signed deviations of scan points from the trimmed CAD surface (thesis Paper III).

A scan point ``p`` (scan coordinates) is first mapped into model coordinates,
``q = R @ p + t`` with ``T_model_scan = [[R, t], [0, 1]]``, then projected exactly onto the
trimmed CAD faces (``prep.closest(q, exact=True)``).  Its deviation is the signed distance
``±|q - foot|``, positive on the outward-normal side (material added), negative inside
(material missing).  On the interior of a face the closest-point condition makes ``q - foot``
parallel to the face normal, so this is exactly the deviation *along the CAD normal*; at an edge
shared by two faces it is the distance to the edge (the usual "closest distance" deviation).

A point is *not evaluated* (value NaN) when

* ``TOO_FAR``: it is farther than the evaluation distance from the model (background, fixture, gross
  outlier), or the closest-point search found no foot point at all;
* ``ON_BOUNDARY``: its foot point lies on a free edge of the model (the part's outer boundary),
  i.e. the scan extends past the CAD surface there and the distance says nothing about the shape;
* ``OUTSIDE_FACES``: its foot point lies on a face that is not inspected (``inspect(faces=...)``).

References
----------
Bergström (2011), thesis chapter 3 and Paper III (shape verification with projected fringes).
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np

from .._renamed import renamed_keywords
from .._arrays import check_points
from .._arrays import readonly as _readonly
from ..measures.codes import EVALUATED, ON_BOUNDARY, OUTSIDE_FACES, REASON_NAMES, TOO_FAR
from ..registration.rigid import apply_transform

logger = logging.getLogger(__name__)

__all__ = ["Deviations", "deviations", "EVALUATED", "TOO_FAR", "ON_BOUNDARY", "OUTSIDE_FACES",
           "REASON_NAMES"]

# The reason codes in :attr:`Deviations.reason` (EVALUATED, TOO_FAR, ON_BOUNDARY, OUTSIDE_FACES,
# REASON_NAMES) live in the leaf :mod:`shapeverify.measures.codes`; imported above.


@dataclass(frozen=True, repr=False, eq=False)
class Deviations:
    """Signed deviations of N scan points from the CAD model (mm).

    Attributes
    ----------
    values : (N,) float64
        Signed deviation, + outside the material (along the outward CAD normal); NaN where not
        evaluated.
    evaluated : (N,) bool
    reason : (N,) int8
        ``EVALUATED`` (0), ``TOO_FAR`` (1), ``ON_BOUNDARY`` (2) or ``OUTSIDE_FACES`` (3).
    face : (N,) int32
        Face of the foot point (triangle index for mesh models, -1 for point-cloud models or when
        no foot point was found).
    foot_points : (N, 3) float64
        Closest points on the CAD surface (model coordinates).
    normals : (N, 3) float64
        Outward unit normals at the foot points.
    points_model : (N, 3) float64
        The scan points mapped into model coordinates.
    evaluation_distance : float
        The limit used for ``TOO_FAR`` (``inf``: none), mm.
    """

    values: np.ndarray
    evaluated: np.ndarray
    reason: np.ndarray
    face: np.ndarray
    foot_points: np.ndarray
    normals: np.ndarray
    points_model: np.ndarray
    evaluation_distance: float

    @property
    def n(self) -> int:
        """Number of scan points."""
        return int(self.values.shape[0])

    @property
    def n_evaluated(self) -> int:
        return int(np.count_nonzero(self.evaluated))

    @property
    def n_too_far(self) -> int:
        return int(np.count_nonzero(self.reason == TOO_FAR))

    @property
    def n_on_boundary(self) -> int:
        return int(np.count_nonzero(self.reason == ON_BOUNDARY))

    @property
    def n_outside_faces(self) -> int:
        return int(np.count_nonzero(self.reason == OUTSIDE_FACES))

    @property
    def max_distance(self) -> float:
        """Deprecated old name of :attr:`evaluation_distance` (a :class:`DeprecationWarning`)."""
        warnings.warn("Deviations.max_distance is now called Deviations.evaluation_distance (the "
                      "old name will go)", DeprecationWarning, stacklevel=2)
        return self.evaluation_distance

    def counts(self) -> dict:
        """``{"evaluated": .., "too_far": .., "on_boundary": .., "outside_faces": ..}`` point counts."""
        return {"evaluated": self.n_evaluated, "too_far": self.n_too_far,
                "on_boundary": self.n_on_boundary, "outside_faces": self.n_outside_faces}

    def restricted_to(self, faces) -> "Deviations":
        """These deviations with the points whose foot lies on a face not in ``faces`` marked
        ``OUTSIDE_FACES`` (not evaluated)."""
        outside = self.evaluated & ~np.isin(self.face, np.asarray(list(faces), dtype=np.int32))
        if not outside.any():
            return self
        reason = self.reason.copy()
        reason[outside] = OUTSIDE_FACES
        evaluated = reason == EVALUATED
        return Deviations(_readonly(np.where(evaluated, self.values, np.nan)), _readonly(evaluated),
                          _readonly(reason), self.face, self.foot_points, self.normals,
                          self.points_model, self.evaluation_distance)

    def __repr__(self) -> str:
        v = self.values[self.evaluated]
        rng = f", range [{v.min():+.4f}, {v.max():+.4f}] mm" if v.size else ""
        return (f"Deviations(n={self.n}, evaluated={self.n_evaluated}, too_far={self.n_too_far}, "
                f"on_boundary={self.n_on_boundary}{rng})")


@renamed_keywords(max_distance="evaluation_distance")
def deviations(scan, prep, T_model_scan=None,
               evaluation_distance: float | None = None) -> Deviations:
    """Signed deviation of every scan point from the trimmed CAD surface.

    Parameters
    ----------
    scan : (N, 3) array_like
        Scan points in scan coordinates (mm).
    prep : shapeverify.nearest.Prepared
        Prepared model; only ``prep.closest(points, exact=True)`` is used.
    T_model_scan : (4, 4) array_like, optional
        Rigid transform from scan to model coordinates (``model = R @ scan + t``); identity if None.
    evaluation_distance : float, optional
        Points farther than this (mm) from the model are not evaluated (``TOO_FAR``).
        None: no limit. (:func:`shapeverify.inspect` uses
        :func:`shapeverify.inspection.default_evaluation_distance`.)
    max_distance : float, optional
        Old name of ``evaluation_distance`` (deprecated).

    Returns
    -------
    Deviations

    Raises
    ------
    ValueError
        If ``scan`` is not (N, 3) with finite values, ``T_model_scan`` is not a finite 4x4
        matrix, or ``evaluation_distance`` is not a positive number.

    Examples
    --------
    A simulated scan of the small example panel, with 0.02 mm noise, at its true pose:

    >>> import shapeverify as sv
    >>> from shapeverify.cad.examples import wavy_panel
    >>> from shapeverify.simulate import virtual_scan
    >>> prep = sv.prepare(wavy_panel(), spacing=2.0)
    >>> sim = virtual_scan(prep, pixel=2.0, noise=0.02, rng=1)
    >>> dev = deviations(sim.scan, prep, sim.T_model_scan, evaluation_distance=1.0)
    >>> round(float(dev.values[dev.evaluated].std()), 2)
    0.02
    """
    scan = check_points(scan, "scan", single=False)
    T = np.eye(4) if T_model_scan is None else np.asarray(T_model_scan, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"T_model_scan must be a finite 4x4 matrix, got shape {T.shape}")
    if evaluation_distance is None:
        evaluation_distance = np.inf
    else:
        evaluation_distance = float(evaluation_distance)
        if not evaluation_distance > 0:
            raise ValueError(f"evaluation_distance must be > 0 mm (or None for no limit), got "
                             f"{evaluation_distance}")
    return _deviations(scan, prep, T, evaluation_distance)


def _deviations(scan: np.ndarray, prep, T: np.ndarray, evaluation_distance: float) -> Deviations:
    """Kernel of :func:`deviations`: trusts its (validated) input."""
    q = apply_transform(T, scan)
    n = q.shape[0]
    if n == 0:
        empty3 = np.zeros((0, 3))
        return Deviations(_readonly(np.zeros(0)), _readonly(np.zeros(0, bool)),
                          _readonly(np.zeros(0, np.int8)), _readonly(np.zeros(0, np.int32)),
                          _readonly(empty3), _readonly(empty3), _readonly(empty3), evaluation_distance)
    near = prep.closest(q, exact=True)
    d = np.asarray(near.distances, dtype=np.float64)
    found = np.isfinite(d)
    reason = np.full(n, EVALUATED, dtype=np.int8)
    too_far = ~found | (np.abs(np.where(found, d, 0.0)) > evaluation_distance)
    reason[too_far] = TOO_FAR
    on_boundary = np.asarray(near.on_boundary, dtype=bool) & ~too_far
    reason[on_boundary] = ON_BOUNDARY
    evaluated = reason == EVALUATED
    values = np.where(evaluated, d, np.nan)
    logger.debug("deviations: %d points, %d evaluated, %d too far, %d on boundary",
                 n, int(evaluated.sum()), int(too_far.sum()), int(on_boundary.sum()))
    return Deviations(
        values=_readonly(values),
        evaluated=_readonly(evaluated),
        reason=_readonly(reason),
        face=_readonly(np.asarray(near.face, dtype=np.int32)),
        foot_points=_readonly(np.asarray(near.points, dtype=np.float64)),
        normals=_readonly(np.asarray(near.normals, dtype=np.float64)),
        points_model=_readonly(q),
        evaluation_distance=evaluation_distance,
    )
