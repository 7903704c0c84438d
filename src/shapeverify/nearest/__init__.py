"""Closest points on the model in microseconds: the Distance Varying Grid tree (Paper I).

>>> import numpy as np, shapeverify as sv
>>> from shapeverify.cad.examples import wavy_panel     # 120 x 90 mm, two trimmed faces
>>> prep = sv.prepare(wavy_panel(), spacing=2.0)
>>> points = np.array([[60.0, 45.0, 5.0], [10.0, 80.0, -3.0]])
>>> near = prep.closest(points)             # fast: tangent-patch projection
>>> near = prep.closest(points, exact=True) # refined on the NURBS faces
>>> near.points.shape, near.distances.shape, near.face.shape
((2, 3), (2,), (2,))
>>> bool(np.allclose(np.linalg.norm(points - near.points, axis=1), np.abs(near.distances)))
True

Modules: :mod:`.dvg` (the tree over plain arrays), :mod:`.exact` (refinement on the model),
:mod:`.prepared` (``prepare``, ``Prepared``, ``Closest``, the ``.svm`` file).
``set_workers(n)`` sets the threads the queries use (default: every core; 1: the calling
thread only; the answers are the same for any number).
"""

from ._threads import get_workers, set_workers
from .prepared import Closest, Prepared, load_prepared, prepare

__all__ = ["prepare", "Prepared", "Closest", "load_prepared", "set_workers", "get_workers"]
