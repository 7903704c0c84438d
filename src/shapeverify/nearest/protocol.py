"""What registration and inspection may ask of a prepared model: the :class:`ClosestPoints`
protocol.

A closest-point structure is anything with these attributes (a :class:`typing.Protocol`:
no base class to inherit).  Registration (:mod:`shapeverify.registration`) and inspection
(:mod:`shapeverify.inspection`) read nothing else of ``prep``:

``closest(points, exact=False) -> Closest``
    For (N, 3) float64 queries: ``points`` (feet), ``normals`` (outward unit), ``distances``
    (signed, + outside), ``face`` (int32), ``uv`` (N, 2), ``index`` (int64: the row of
    :attr:`points` nearest the query) and ``on_boundary`` (bool: the foot is on a free edge).
    ``exact=True`` asks for the answer refined on the model; a structure without refinement
    gives its best answer.  Raises ``ValueError`` for queries that are not finite (N, 3).
``points``
    The model points (:class:`~shapeverify.cad.model.ModelPoints`: ``points``, ``normals``,
    ``face``, ``uv``, ``tangent_u``, ``tangent_v``, ``half_extent``, ``boundary``,
    ``spacing``) in the order ``Closest.index`` refers to; the same object on every access
    (registration caches per structure).
``n_points``
    ``len(points.points)``, without assembling them.
``spacing``
    The model point spacing (mm).  (Also ``model_spacing`` on
    :class:`~shapeverify.nearest.Prepared`, the unambiguous name; a structure need only have
    ``spacing``.)
``reach``
    The structure's reach (mm): queries within it are answered by the fast path; registration
    reads it to choose its first correspondence distance.  (Its old name ``max_distance`` is a
    deprecated property of :class:`~shapeverify.nearest.Prepared`.)
``model``
    The :class:`~shapeverify.cad.model.Model`: registration reads ``model.size`` and
    ``model.kind``; inspection ``model.size``, ``model.faces`` (face count and names) and what
    coverage and the missing-faces note read of it.
``fixture``
    A (4, 4) start pose or None (``prepare --fixture``).

Implementations: :class:`~shapeverify.nearest.Prepared` (the DVG tree: fast answers, exact on
request), :class:`ExactSearch` (a Prepared model whose every answer is refined on the model)
and, in the tests, a kd-tree adapter (``tests/kdtree_closest.py``: scipy's cKDTree over the
same model points and the same tangent-patch projection).  ``tests/test_closest_points_contract.py``
runs the registration and deviation contract over all three.

>>> import shapeverify as sv
>>> from shapeverify.cad.examples import wavy_panel
>>> prep = sv.prepare(wavy_panel(), spacing=4.0)
>>> isinstance(prep, ClosestPoints), isinstance(ExactSearch(prep), ClosestPoints)
(True, True)
>>> missing_attributes(object())[:3]
['closest', 'points', 'n_points']
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

__all__ = ["ClosestPoints", "ExactSearch", "missing_attributes", "PROTOCOL_ATTRIBUTES"]

#: The attributes of :class:`ClosestPoints`, in the order the module docstring gives them.
PROTOCOL_ATTRIBUTES = ("closest", "points", "n_points", "spacing", "reach", "model",
                       "fixture")


@runtime_checkable
class ClosestPoints(Protocol):
    """A closest-point structure of a model (see the module docstring for each attribute)."""

    points: Any
    n_points: int
    spacing: float
    reach: float
    model: Any
    fixture: Any

    def closest(self, points, exact: bool = False):
        """Closest points on the model (a :class:`~shapeverify.nearest.Closest`)."""
        ...


def missing_attributes(obj) -> list[str]:
    """The :data:`PROTOCOL_ATTRIBUTES` that ``obj`` lacks (``closest`` also when not callable)."""
    out = [a for a in PROTOCOL_ATTRIBUTES if not hasattr(obj, a)]
    if "closest" not in out and not callable(getattr(obj, "closest", None)):
        out.insert(0, "closest")
    return out


class ExactSearch:
    """A prepared model whose every answer is refined on the model: ``closest(X)`` is
    ``prep.closest(X, exact=True)`` (the exact mode as a :class:`ClosestPoints` of its own:
    registration and inspection run on exact answers throughout).

    Parameters
    ----------
    prep : ClosestPoints
        Usually a :class:`~shapeverify.nearest.Prepared`.
    """

    def __init__(self, prep):
        missing = missing_attributes(prep)
        if missing:
            raise TypeError(f"ExactSearch needs a closest-point structure (ClosestPoints); "
                            f"{type(prep).__name__} lacks {', '.join(missing)}")
        self._prep = prep

    def closest(self, points, exact: bool = True):
        return self._prep.closest(points, exact=True)

    @property
    def points(self):
        return self._prep.points

    @property
    def n_points(self) -> int:
        return self._prep.n_points

    @property
    def spacing(self) -> float:
        return self._prep.spacing

    @property
    def model_spacing(self) -> float:
        return self._prep.spacing

    @property
    def reach(self) -> float:
        return self._prep.reach

    @property
    def model(self):
        return self._prep.model

    @property
    def fixture(self):
        return self._prep.fixture

    def __repr__(self) -> str:
        return f"ExactSearch({self._prep!r})"
