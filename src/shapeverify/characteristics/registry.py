"""The characteristic registry: one row per characteristic type, from which the rest follows.

Adding a characteristic type = one schema model in :mod:`.schema`, one evaluator function
``f(c, ctx) -> CharacteristicResult`` (``ctx``: :class:`shapeverify.characteristics.evaluate.EvalContext`)
and one row of :data:`TYPES`.  From this table:

* the plan schema (:mod:`.plan`: the discriminated union of characteristics and the YAML tags
  that error messages leave out),
* the evaluator dispatch (:func:`.evaluate.evaluate_characteristics`),
* the zone sidedness (``one_sided``: a zone width with an upper limit only, ISO 14253-1
  decision against the upper limit; :func:`.zones.is_one_sided`),
* SPC's one-sided series (:mod:`.spc`: no lower limit, no Cp),
* the label a report prints for a type (:func:`label`; the PDF's table),
* the symbol of its feature control frame (``symbol``: the ISO 1101 / ASME Y14.5 symbol of a
  geometric tolerance, "Ø" for a diameter, "" for a linear size or a point;
  :mod:`shapeverify.report.fcf` draws the frame from it).

Evaluators are named as ``"module:function"`` (relative to this package) and imported on first
use, so that this table imports no evaluator module (no import cycle).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass

from . import schema

__all__ = ["CharacteristicType", "TYPES", "by_name", "schemas", "evaluator", "one_sided_types",
           "label", "symbol"]


@dataclass(frozen=True)
class CharacteristicType:
    """One characteristic type.

    Attributes
    ----------
    name : str           the plan's ``type:`` value
    schema : type        its pydantic model (:mod:`.schema`)
    evaluator : str      ``"module:function"`` of its evaluator in this package
    one_sided : bool     the measured value is a zone width (upper limit only)
    label : str          what a report prints (the five first types: their name, as before)
    symbol : str         the feature control frame's symbol (ISO 1101 / ASME Y14.5, Unicode),
                         "Ø" for a diameter, "" for a linear size or a point
                         (:mod:`shapeverify.report.fcf`)
    unit : str           the unit of its nominal and limits: "mm", or "deg" for an angle
    """

    name: str
    schema: type
    evaluator: str
    one_sided: bool
    label: str
    symbol: str = ""
    unit: str = "mm"


TYPES: tuple[CharacteristicType, ...] = (
    CharacteristicType("hole", schema.Hole, "evaluate:eval_hole", False, "hole", "⌖"),
    CharacteristicType("surface_profile", schema.SurfaceProfile, "gdt:eval_surface_profile", True,
                       "surface_profile", "⌓"),
    CharacteristicType("flatness", schema.Flatness, "evaluate:eval_flatness", True, "flatness",
                       "⏥"),
    CharacteristicType("cylinder", schema.Cylinder, "evaluate:eval_cylinder", False,
                       "cylinder", "Ø"),
    CharacteristicType("check_point", schema.CheckPoint, "evaluate:eval_check_point", False,
                       "check_point"),
    CharacteristicType("straightness", schema.Straightness, "each_feature:eval_straightness", True,
                       "straightness", "⏤"),
    CharacteristicType("circularity", schema.Circularity, "each_feature:eval_circularity", True,
                       "circularity (roundness)", "○"),
    CharacteristicType("cylindricity", schema.Cylindricity, "each_feature:eval_cylindricity", True,
                       "cylindricity", "⌭"),
    CharacteristicType("parallelism", schema.Parallelism, "each_feature:eval_orientation", True,
                       "parallelism", "∥"),
    CharacteristicType("perpendicularity", schema.Perpendicularity, "each_feature:eval_orientation",
                       True, "perpendicularity", "⊥"),
    CharacteristicType("angularity", schema.Angularity, "each_feature:eval_orientation", True,
                       "angularity", "∠"),
    CharacteristicType("position", schema.Position, "gdt:eval_position", True, "position", "⌖"),
    CharacteristicType("circular_runout", schema.CircularRunout, "gdt:eval_runout", True,
                       "circular runout", "↗"),
    CharacteristicType("total_runout", schema.TotalRunout, "gdt:eval_runout", True,
                       "total runout", "⌰"),
    CharacteristicType("concentricity", schema.Concentricity,
                       "concentricity:eval_concentricity", True, "concentricity", "◎"),
    CharacteristicType("symmetry", schema.Symmetry, "symmetry:eval_symmetry", True,
                       "symmetry", "⌯"),
    CharacteristicType("width", schema.Width, "gdt:eval_width", False, "size (width)"),
    CharacteristicType("distance", schema.Distance, "gdt_size:eval_distance", False,
                       "distance (planes)"),
    CharacteristicType("angle", schema.Angle, "gdt_size:eval_angle", False,
                       "angle (planes)", unit="deg"),
    CharacteristicType("line_profile", schema.LineProfile, "profile_line:eval_line_profile",
                       True, "profile of a line", "⌒"),
    CharacteristicType("position_zone", schema.PositionZone,
                       "position_zones:eval_position_zone", True, "position (planes, sphere)",
                       "⌖"),
    CharacteristicType("feature_size", schema.FeatureSize, "size_features:eval_feature_size",
                       False, "size (radius, sphere)"),
    CharacteristicType("cone_angle", schema.ConeAngle, "cone_sizes:eval_cone_angle", False,
                       "angle (cone)", unit="deg"),
    CharacteristicType("cone_diameter", schema.ConeDiameter, "countersink:eval_cone_diameter",
                       False, "diameter (countersink)", "Ø"),
)

_BY_NAME = {t.name: t for t in TYPES}
assert len(_BY_NAME) == len(TYPES), "a characteristic type is registered twice"


def by_name(name: str) -> CharacteristicType:
    """The registered type ``name``; KeyError naming the known types otherwise."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown characteristic type {name!r}; registered: "
                       f"{', '.join(_BY_NAME)}") from None


def schemas() -> tuple:
    """The schema models of every type, in table order (the plan's union)."""
    return tuple(t.schema for t in TYPES)


_EVALUATORS: dict = {}


def evaluator(name: str):
    """The evaluator function of type ``name`` (imported on first use)."""
    fn = _EVALUATORS.get(name)
    if fn is None:
        mod, func = by_name(name).evaluator.split(":")
        fn = getattr(importlib.import_module(f"{__package__}.{mod}"), func)
        _EVALUATORS[name] = fn
    return fn


def one_sided_types() -> tuple[str, ...]:
    """Names of the types whose value is a zone width (upper limit only)."""
    return tuple(t.name for t in TYPES if t.one_sided)


def label(name: str) -> str:
    """What a report prints for the type ``name`` (the name itself if unregistered)."""
    t = _BY_NAME.get(name)
    return t.label if t is not None else str(name)


def symbol(name: str) -> str:
    """The feature control frame symbol of the type ``name`` ("" if unregistered)."""
    t = _BY_NAME.get(name)
    return t.symbol if t is not None else ""
