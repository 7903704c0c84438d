"""Closest points on the model in microseconds: the Distance Varying Grid tree (Paper I).

>>> import shapeverify as sv                                  # doctest: +SKIP
>>> prep = sv.prepare(model)                                  # doctest: +SKIP
>>> near = prep.closest(points)             # fast: tangent-patch projection   # doctest: +SKIP
>>> near = prep.closest(points, exact=True) # refined on the NURBS faces       # doctest: +SKIP

Modules: :mod:`.dvg` (the tree over plain arrays), :mod:`.exact` (refinement on the model),
:mod:`.prepared` (``prepare``, ``Prepared``, ``Closest``, the ``.svm`` file).
``set_workers(n)`` sets the threads the queries use (default: every core; 1: the calling
thread only; the answers are the same for any number).
"""

from ._threads import get_workers, set_workers
from .prepared import Closest, Prepared, load_prepared, prepare

__all__ = ["prepare", "Prepared", "Closest", "load_prepared", "set_workers", "get_workers"]
