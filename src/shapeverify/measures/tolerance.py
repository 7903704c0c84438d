"""The tolerance zone ``lower <= deviation <= upper`` (mm), optionally different per face.

A leaf (numpy only): the inspection (:mod:`shapeverify.inspection.verdict`, which re-exports
:class:`Tolerance`) and the characteristics both read it.  Public name:
``shapeverify.inspection.Tolerance``.

References
----------
ISO 1101 (profile of a surface: a tolerance zone between two offset surfaces, here
``lower <= deviation <= upper`` along the CAD normal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

__all__ = ["Tolerance"]


def _limit(x, name: str) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number (mm), got {x!r}") from None
    if math.isnan(v):
        raise ValueError(f"{name} must not be NaN")
    if math.isinf(v):           # an infinite zone passes every part, however far it is off
        raise ValueError(f"{name} must be finite (mm), got {v:g}; a zone that accepts any "
                         "deviation decides nothing")
    return v


def _check_pair(lower: float, upper: float, what: str) -> tuple[float, float]:
    lower, upper = _limit(lower, f"{what} lower limit"), _limit(upper, f"{what} upper limit")
    if lower > 0:
        raise ValueError(f"{what} lower limit is a signed deviation and must be <= 0 mm, got "
                         f"{lower:g}; did you mean {-lower:g}?")
    if upper < 0:
        raise ValueError(f"{what} upper limit must be >= 0 mm, got {upper:g}; did you mean {-upper:g}?")
    if not lower < upper:
        raise ValueError(f"{what} tolerance zone [{lower:g}, {upper:g}] mm is empty")
    return lower, upper


@dataclass(frozen=True)
class Tolerance:
    """Tolerance zone ``lower <= deviation <= upper`` (mm), optionally different per face.

    Parameters
    ----------
    lower : float
        Lower limit, signed, <= 0 (material missing), e.g. -0.2.
    upper : float
        Upper limit, >= 0 (material added), e.g. 0.2.
    per_face : mapping {face index: (lower, upper)} or tuple of (face, lower, upper), optional
        Overrides for individual faces.

    Examples
    --------
    >>> Tolerance.symmetric(0.2)
    Tolerance(lower=-0.2, upper=0.2, per_face=())
    >>> Tolerance(-0.1, 0.3, per_face={4: (-0.05, 0.05)}).limits_for(4)
    (-0.05, 0.05)
    """

    lower: float
    upper: float
    per_face: tuple = ()

    def __post_init__(self):
        lo, hi = _check_pair(self.lower, self.upper, "tolerance")
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)
        items = self.per_face.items() if isinstance(self.per_face, Mapping) else self.per_face
        faces = []
        for item in items:
            if isinstance(self.per_face, Mapping):
                f, (flo, fhi) = item
            else:
                f, flo, fhi = item
            if isinstance(f, bool) or not isinstance(f, (int, np.integer)) or f < 0:
                raise ValueError(f"per-face tolerance keys must be face indices >= 0, got {f!r}")
            flo, fhi = _check_pair(flo, fhi, f"face {int(f)}")
            faces.append((int(f), flo, fhi))
        faces.sort()
        if len({f for f, _, _ in faces}) != len(faces):
            raise ValueError("per-face tolerance lists a face twice")
        object.__setattr__(self, "per_face", tuple(faces))

    @classmethod
    def symmetric(cls, tolerance: float, per_face: Mapping | None = None) -> "Tolerance":
        """``±tolerance``; ``per_face`` values may be numbers (symmetric) or (lower, upper)."""
        t = _limit(tolerance, "tolerance")
        if not t > 0:
            raise ValueError(f"tolerance must be > 0 mm, got {t:g}")
        pf = {}
        for f, v in (per_face or {}).items():
            pf[f] = (-abs(float(v)), abs(float(v))) if np.isscalar(v) else tuple(v)
        return cls(-t, t, pf)

    @classmethod
    def from_args(cls, tolerance=None, lower=None, upper=None, per_face=None) -> "Tolerance":
        """Build from the ``inspect`` arguments: ``lower``/``upper`` override ``±tolerance``.

        Raises
        ------
        ValueError
            If neither a tolerance nor both limits are given.
        """
        if isinstance(tolerance, Tolerance):
            if lower is None and upper is None and per_face is None:
                return tolerance
            base_lo, base_hi = tolerance.lower, tolerance.upper
        elif tolerance is not None:
            t = _limit(tolerance, "tolerance")
            if not t > 0:
                raise ValueError(f"tolerance must be > 0 mm, got {t:g}")
            base_lo, base_hi = -t, t
        else:
            base_lo = base_hi = None
        lo = base_lo if lower is None else lower
        hi = base_hi if upper is None else upper
        if lo is None or hi is None:
            raise ValueError("give a tolerance (±mm) or both lower and upper limits (mm)")
        pf = {}
        for f, v in (per_face or {}).items():
            pf[f] = (-abs(float(v)), abs(float(v))) if np.isscalar(v) else tuple(v)
        return cls(lo, hi, pf)

    @property
    def is_symmetric(self) -> bool:
        return self.lower == -self.upper and all(lo == -hi for _, lo, hi in self.per_face)

    @property
    def max_abs(self) -> float:
        """Largest |limit| over all faces (for colour scales)."""
        vals = [abs(self.lower), abs(self.upper)] + [max(abs(lo), abs(hi)) for _, lo, hi in self.per_face]
        return float(max(vals))

    def limits_for(self, face: int) -> tuple[float, float]:
        for f, lo, hi in self.per_face:
            if f == face:
                return lo, hi
        return self.lower, self.upper

    def limits(self, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-point limits ``(lower (N,), upper (N,))`` for points on faces ``face (N,)``."""
        face = np.asarray(face)
        lo = np.full(face.shape, self.lower)
        hi = np.full(face.shape, self.upper)
        for f, flo, fhi in self.per_face:
            m = face == f
            lo[m], hi[m] = flo, fhi
        return lo, hi

    def within(self, values: np.ndarray, face: np.ndarray) -> np.ndarray:
        """(N,) bool: ``lower <= value <= upper`` (False for NaN)."""
        lo, hi = self.limits(face)
        with np.errstate(invalid="ignore"):
            return (values >= lo) & (values <= hi)

    def to_dict(self) -> dict:
        d = {"lower": self.lower, "upper": self.upper, "symmetric": self.is_symmetric}
        if self.is_symmetric:
            d["tolerance"] = self.upper
        if self.per_face:
            d["per_face"] = {str(f): [lo, hi] for f, lo, hi in self.per_face}
        return d
