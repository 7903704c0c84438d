"""Closest points on the model in microseconds: the Distance Varying Grid tree (Paper I).

>>> import shapeverify as sv                                  # doctest: +SKIP
>>> prep = sv.prepare(model)                                  # doctest: +SKIP
>>> near = prep.closest(points)             # fast: tangent-patch projection   # doctest: +SKIP
>>> near = prep.closest(points, exact=True) # refined on the NURBS faces       # doctest: +SKIP

Modules: :mod:`.dvg` (the tree over plain arrays), :mod:`.exact` (refinement on the model),
:mod:`.prepared` (``prepare``, ``Prepared``, ``Closest``, the ``.svm`` file).
"""

from .prepared import Closest, Prepared, load_prepared, prepare

__all__ = ["prepare", "Prepared", "Closest", "load_prepared"]
