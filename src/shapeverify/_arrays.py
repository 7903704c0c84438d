"""Small array helpers shared by the packages (private): the one check of (N, 3) point arrays at
the public boundary (:func:`check_points`), fast one-pass checks behind it, and write-protected
result arrays.

numpy's ``np.isfinite(a).all(axis=1)`` and ``a.min(axis=0)`` on a narrow (N, 3) array cost
0.4-0.8 ms per 30,000 points (axis reductions over 3 columns); the inspection path ran about
twenty of them per scan.  One numba pass does each in a few microseconds.
"""

from __future__ import annotations

import numpy as np

# the numba passes live in ``_array_kernels``, imported on first use: importing this module (as
# building a model does, e.g. for ``shapeverify info``) needs no numba.


def count_nonfinite_rows(a: np.ndarray) -> int:
    """Rows of the 2-D float array ``a`` holding a NaN or an infinity."""
    if a.size == 0:
        return 0
    with np.errstate(invalid="ignore", over="ignore"):   # inf - inf, huge + huge
        if np.isfinite(a.sum()):                # a sum is finite only if every value is
            return 0
    from ._array_kernels import _count_nonfinite_rows

    return int(_count_nonfinite_rows(np.ascontiguousarray(a, dtype=np.float64)))


def bounds(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Column-wise (min, max) of a finite, non-empty 2-D float array."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    lo = np.empty(a.shape[1])
    hi = np.empty(a.shape[1])
    from ._array_kernels import _bounds

    _bounds(a, lo, hi)
    return lo, hi


def readonly(a) -> np.ndarray:
    """A C-contiguous, write-protected array (a copy only when ``a`` is not C-contiguous)."""
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def check_points(points, name: str = "points", allow_empty: bool = True, *, min_points: int = 0,
                 single: bool = True, error: type[Exception] = ValueError) -> np.ndarray:
    """Validate an (N, 3) array of finite coordinates; return it as C-contiguous float64.

    The one check of point arrays at the public boundary (queries, scans, rays, camera points).

    Parameters
    ----------
    points : (N, 3) array_like
        One row of x, y, z per point (mm).
    name : str
        What the array is called in the messages ("scan", "queries", ...).
    allow_empty : bool
        Whether N = 0 is accepted.
    min_points : int
        Smallest accepted N (0: no limit beyond ``allow_empty``).
    single : bool
        Accept a single (3,) point (it becomes (1, 3)).
    error : Exception class
        Raised on bad input (``ValueError`` or a subclass such as ``ScanError``).

    Raises
    ------
    error
        The shape is not (N, 3) (or not numbers), N is 0 and ``allow_empty`` is False, N is
        below ``min_points``, or a value is NaN or infinite; the message names the fix.
    """
    try:
        a = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be an (N, 3) array of numbers: {exc}") from None
    if single and a.ndim == 1 and a.shape[0] == 3:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 3:
        raise error(f"{name} must have shape (N, 3), got {a.shape}; pass one row of x, y, z per point")
    if a.shape[0] == 0 and not allow_empty:
        raise error(f"{name} is empty; at least one point is needed")
    if a.shape[0] < min_points:
        raise error(f"{name} has {a.shape[0]} points; at least {min_points} are needed")
    if count_nonfinite_rows(a):
        bad = ~np.isfinite(a).all(axis=1)
        raise error(f"{name} has {int(bad.sum())} row(s) with NaN or inf (first: row "
                    f"{int(np.flatnonzero(bad)[0])}); remove them first, e.g. "
                    f"{name} = {name}[np.isfinite({name}).all(axis=1)]")
    return np.ascontiguousarray(a)
