"""The inspection plan (``plan.yaml``): alignment, characteristics and tolerances, validated.

A plan says how the part is aligned (the way it is fixtured) and what is measured on it.  It is
read from YAML and validated with pydantic; an error names the file, the line and the key:
``plan.yaml, line 6, key 'characteristics[0].diameter.tol': Input should be a valid number``.

The minimum contract (scripts depend on it; everything else is optional)::

    units: mm
    alignment: {type: best_fit}          # best_fit [faces: [...]] | constrained {free: [tx, ty, rz]}
                                         # | rps {points: [{at: [x, y, z], lock: [z]}, ...]}
                                         # | datums {primary: face:0, secondary: hole:1, tertiary: hole:2}
    characteristics:
      - {name: H1, type: hole, near: [70, 55, 0], diameter: {tol: 0.2}, position: {tol: 0.3}}
      - {name: SKIN, type: surface_profile, faces: all, tol: 0.2}

Further characteristic types: ``flatness`` (``feature: face:3`` or ``near``, ``tol``),
``cylinder`` (``feature``/``near``, ``diameter: {tol}``), ``check_point`` (``at``, ``tol`` or
``lower``/``upper``, ``radius``).  Wherever a plan names a face (``faces: [...]``,
``feature``, the datums) it may use the face's name from the STEP file instead of its id
(``faces: [datum_A]``; see ``shapeverify info --features``); in ``faces`` a name stands for
every face that carries it.  A plan written by ``shapeverify plan`` from the CAD file's semantic PMI marks each entry
with its source (``pmi: {kind: geometric_tolerance | dimension | datum, type: Position}``) and
lists the PMI it does not check in ``unsupported: [{pmi: {...}, reason: "..."}]``, and the
tolerances and dimensions the file declares that OpenCASCADE does not read at all in ``unread``
(the same form; ``pmi`` has the item's ``name`` and STEP ``entity``).
GD&T types (issue 28; docs/characteristics.md): ``straightness``, ``circularity``,
``cylindricity`` (``faces``, ``tol``); ``parallelism``, ``perpendicularity``, ``angularity``
(``faces``, ``tol``, ``datums: [A, ...]``, ``zone: planes | diameter``); ``position``
(``features: [hole:N | face:N | [face:N, ...]]``, ``tol``, ``datums``, ``material: M | L`` with
``size: {lower, upper}``); ``circular_runout``, ``total_runout`` (``faces``, ``tol``,
``datums``); ``width``, ``distance``, ``angle`` (two ``faces``, ``lower``, ``upper``, the last two an optional
``nominal``; a ``distance``'s second side may be ``{cylinder: face:N, cone: face:M}``, the
circle where a hole's wall meets its drill point); ``surface_profile`` takes
``datums`` too.  The datum letters come from the plan's table
``datums: {A: {faces: [face:0]}, B: {faces: [face:3, face:4]}, ...}`` (fitted by
:mod:`.drf`).  Every type is one row of :mod:`.registry`.
``section`` (optional): a cross-section plane
``{point: [x, y, z], normal: [nx, ny, nz], width: 1.0}`` for the PDF report.
``evaluation_distance`` (optional, mm): scan points farther than this from the CAD are not
evaluated (default: that of :func:`shapeverify.inspect`).  Its old key ``max_distance`` is
still read, with a :class:`DeprecationWarning` and a warning in the log naming the file and
line (issue 31: one name per concept).

Tolerance conventions (ISO 1101)
--------------------------------
* ``surface_profile`` and ``flatness``: ``tol`` is the *width* t of the tolerance zone; the
  measured value is a zone width too (see :mod:`shapeverify.characteristics.evaluate`).
* ``position``: ``tol`` is the diameter of the cylindrical tolerance zone of the axis.
* ``diameter`` and ``check_point``: ``tol`` is symmetric (±tol); ``lower``/``upper`` give
  asymmetric limits (deviations, mm).

Lengths in millimetres.
"""
from __future__ import annotations

import logging
import os
import warnings
from pathlib import Path
from typing import Annotated, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ..errors import ShapeVerifyError
from . import registry
from .schema import (  # noqa: F401 - re-exported: the plan's schema lives in .schema
    CheckPoint, Cylinder, DatumSpec, FeatureId, FeatureRef, Flatness, Hole, PmiSource,
    SurfaceProfile, Tol, Unsupported, Vec3, _Char, _Located, _Strict)

__all__ = ["Plan", "PlanError", "load_plan", "parse_plan", "Tol", "DOF_NAMES", "PmiSource",
           "Unsupported"]

logger = logging.getLogger(__name__)

#: the six rigid degrees of freedom, in the order of the alignment's parameter vector
DOF_NAMES = ("rx", "ry", "rz", "tx", "ty", "tz")
_AXES = ("x", "y", "z")


class PlanError(ShapeVerifyError, ValueError):
    """An inspection plan that cannot be read or does not follow the schema.

    The message names the file, line and key (``where``); ``line`` is 1-based or None.
    """

    def __init__(self, message: str, line: int | None = None, key: str | None = None):
        super().__init__(message)
        self.line = line
        self.key = key


# ------------------------------------------------------------------------------ alignments
class BestFit(_Strict):
    """Free 6-DOF best fit on all faces or on named faces (a local best fit)."""

    type: Literal["best_fit"]
    faces: Union[Literal["all"], list[Union[FeatureId, int, str]]] = "all"
    loss: Literal["tukey", "huber", "cauchy", "welsch", "l2"] = "tukey"


class Constrained(_Strict):
    """Best fit in the free degrees of freedom only; the others stay at the start pose.

    ``free``: names from ``rx ry rz tx ty tz`` (rotations about the model axes through
    ``center``, translations along them).
    """

    type: Literal["constrained"]
    free: list[Literal["rx", "ry", "rz", "tx", "ty", "tz"]] = Field(min_length=1)
    faces: Union[Literal["all"], list[Union[FeatureId, int, str]]] = "all"
    center: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    loss: Literal["tukey", "huber", "cauchy", "welsch", "l2"] = "tukey"

    @field_validator("free")
    @classmethod
    def _unique(cls, v):
        if len(set(v)) != len(v):
            raise ValueError(f"free lists a degree of freedom twice: {v}")
        return v


class RpsPoint(_Strict):
    """A reference point: nominal position ``at`` (model frame) and the axes it locks.

    A point at a hole (``feature: hole:N``, or ``at`` within a radius of a hole's centre) is
    measured as the hole's centre; any other point as the scan's surface at ``at``.
    """

    at: Vec3
    lock: list[Literal["x", "y", "z"]] = Field(min_length=1, max_length=3)
    name: Optional[str] = None
    feature: Optional[FeatureRef] = None
    radius: Optional[float] = Field(default=None, gt=0)


class Rps(_Strict):
    """RPS alignment: reference points with the axes each one locks (3-2-1 is six locks)."""

    type: Literal["rps"]
    points: list[RpsPoint] = Field(min_length=1)

    @model_validator(mode="after")
    def _six(self):
        n = sum(len(p.lock) for p in self.points)
        if n < 6:
            raise ValueError(f"the RPS points lock {n} coordinates; a rigid pose needs at least 6 "
                             "(3-2-1: lock [z] at three points, [x, y] at one, [y] at another)")
        return self


class Datums(_Strict):
    """Datum-feature alignment: primary plane, secondary axis/plane, tertiary axis/plane."""

    type: Literal["datums"]
    primary: FeatureRef
    secondary: FeatureRef
    tertiary: Optional[FeatureRef] = None
    pmi: Optional[list[PmiSource]] = None


Alignment = Annotated[Union[BestFit, Constrained, Rps, Datums], Field(discriminator="type")]


#: every registered characteristic type (:mod:`.registry`)
Characteristic = Annotated[Union[registry.schemas()], Field(discriminator="type")]


class Section(_Strict):
    """A cross-section plane for the report: points within ``width``/2 of the plane."""

    point: Vec3
    normal: Vec3
    width: float = Field(default=1.0, gt=0)
    name: str = "section"


class Plan(_Strict):
    """A validated inspection plan (see the module docstring for the YAML form)."""

    units: Literal["mm"] = "mm"
    part: Optional[str] = None
    alignment: Alignment = Field(default_factory=lambda: BestFit(type="best_fit"))
    characteristics: list[Characteristic] = Field(default_factory=list)
    section: Optional[Section] = None
    evaluation_distance: Optional[float] = Field(default=None, gt=0)
    coverage_factor: float = Field(default=2.0, gt=0)
    unsupported: list[Unsupported] = Field(default_factory=list)
    #: PMI the file declares that OpenCASCADE's reader does not return (not checked either)
    unread: list[Unsupported] = Field(default_factory=list)
    #: datum features by letter, for the characteristics' own datum reference frames
    #: (``datums: [A, B, C]`` on a characteristic; fitted by :mod:`.drf`)
    datums: dict[str, DatumSpec] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _old_key(cls, data):
        """The plan key ``max_distance`` (deprecated) read as ``evaluation_distance``."""
        return _renamed_key(data, "<plan>", None)

    @model_validator(mode="after")
    def _unique_names(self):
        seen = set()
        for c in self.characteristics:
            if c.name in seen:
                raise ValueError(f"characteristic name {c.name!r} is used twice; names must be "
                                 "unique")
            seen.add(c.name)
            drf = getattr(c, "datums", None) or []
            missing = [d for d in drf if d not in self.datums]
            if missing:
                raise ValueError(f"characteristic {c.name!r} names datum {missing[0]!r}, which "
                                 f"the plan's datums table does not define (have: "
                                 f"{sorted(self.datums) or 'none'}); add datums: "
                                 f"{{{missing[0]}: {{faces: [face:N]}}}}")
            if len(set(drf)) != len(drf):
                raise ValueError(f"characteristic {c.name!r} names a datum twice: {drf}")
        return self

    @classmethod
    def default(cls) -> "Plan":
        """Today's behaviour without a plan: free best fit, nothing else."""
        return cls()


# ------------------------------------------------------------------------------ YAML with lines
# (read by shapeverify.io.yaml_safe.load_yaml: bounded aliases, every key's line)
def _where(loc: tuple, data, lines: dict) -> tuple[tuple, int | None]:
    """The data path of a pydantic error location (union tags dropped) and its line."""
    path, cur = [], data
    for part in loc:
        if isinstance(cur, dict) and part in cur:
            path.append(part)
            cur = cur[part]
        elif isinstance(cur, list) and isinstance(part, int) and part < len(cur):
            path.append(part)
            cur = cur[part]
        elif isinstance(cur, dict) and isinstance(part, str) and part not in cur:
            # a discriminator tag ('hole'), or a missing/extra key: keep it only if it is last
            if part == loc[-1] and part not in _TAGS:
                path.append(part)
            continue
    for k in range(len(path), -1, -1):
        if tuple(path[:k]) in lines:
            return tuple(path), lines[tuple(path[:k])]
    return tuple(path), None


_TAGS = {"best_fit", "constrained", "rps", "datums"} | {t.name for t in registry.TYPES}


def _key_text(path: tuple) -> str:
    s = ""
    for p in path:
        s += f"[{p}]" if isinstance(p, int) else (f".{p}" if s else str(p))
    return s or "(top level)"


def parse_plan(text: str, source: str = "<plan>") -> Plan:
    """Validate a plan given as YAML text.

    Parameters
    ----------
    text : str
        The YAML document.
    source : str
        Name used in error messages (the file name).

    Returns
    -------
    Plan

    Raises
    ------
    PlanError
        YAML syntax errors and schema violations; the message names ``source``, the line and
        the key, and what was expected.

    Examples
    --------
    >>> p = parse_plan("units: mm\\nalignment: {type: best_fit}\\ncharacteristics: []")
    >>> p.alignment.type
    'best_fit'
    """
    from ..io.yaml_safe import YamlInputError, load_yaml

    try:   # aliases expanded within a budget, nesting bounded, repeated keys refused
        data, lines = load_yaml(text, source, with_lines=True)
    except YamlInputError as exc:
        raise PlanError(str(exc), line=exc.line) from None
    if data is None:
        raise PlanError(f"{source}: the plan is empty; it needs at least 'units: mm' and "
                        "'characteristics: [...]'", line=1)
    return _validate(data, lines, source)


#: old plan keys still read: {old: new} (issue 31); each use is a DeprecationWarning and a log
#: warning naming the file and line
OLD_KEYS = {"max_distance": "evaluation_distance"}


def _renamed_key(data, source: str, lines: dict | None):
    if not isinstance(data, dict):
        return data
    for old, new in OLD_KEYS.items():
        if old not in data:
            continue
        line = (lines or {}).get((old,))
        where = f"{source}, line {line}" if line is not None else source
        if new in data:
            raise PlanError(f"{where}: give '{new}' only ('{old}' is its old name)", line=line,
                            key=old)
        data = {(new if k == old else k): v for k, v in data.items()}
        msg = (f"{where}: the plan key '{old}' is now called '{new}' (read as '{new}'; the old "
               "name will go)")
        logger.warning("%s", msg)
        warnings.warn(msg, DeprecationWarning, stacklevel=5)
    return data


def _validate(data, lines: dict, source: str) -> Plan:
    if not isinstance(data, dict):
        raise PlanError(f"{source}, line 1: the plan must be a mapping (key: value lines), got "
                        f"{type(data).__name__}", line=1)
    data = _renamed_key(data, source, lines)
    try:
        return Plan.model_validate(data)
    except ValidationError as exc:
        msgs, first_line, first_key = [], None, None
        for err in exc.errors():
            path, line = _where(tuple(err["loc"]), data, lines)
            key = _key_text(path)
            text = err["msg"]
            if err["type"] == "extra_forbidden":
                text = "unknown key (check its spelling; see shapeverify.characteristics.plan)"
            elif err["type"] == "missing":
                text = "required key is missing"
            elif err["type"] == "union_tag_invalid":
                text = f"unknown type {err.get('input', {}).get('type')!r}: " \
                       f"expected one of {err.get('ctx', {}).get('expected_tags')}" \
                    if isinstance(err.get("input"), dict) else text
            msgs.append(f"{source}, line {line}, key '{key}': {text}")
            if first_line is None:
                first_line, first_key = line, key
        raise PlanError("invalid inspection plan:\n  " + "\n  ".join(msgs), line=first_line,
                        key=first_key) from None


def load_plan(plan) -> Plan:
    """A :class:`Plan` from a Plan, a dict, a YAML file path or YAML text.

    Raises
    ------
    PlanError
        Unreadable or invalid plan (line and key named).
    FileNotFoundError
        A path that does not exist.
    """
    if isinstance(plan, Plan):
        return plan
    if isinstance(plan, dict):
        return _validate(plan, {(): 1}, "<plan dict>")
    if isinstance(plan, (str, os.PathLike)):
        s = os.fspath(plan)
        if "\n" not in s and (s.endswith((".yaml", ".yml")) or Path(s).exists()):
            p = Path(s)
            if not p.exists():
                raise FileNotFoundError(2, "no such plan file", s)
            if p.is_dir():
                raise PlanError(f"{s}: is a directory; give the plan file (plan.yaml)")
            data = p.read_bytes()
            try:
                text = data.decode("utf-8-sig")
            except UnicodeDecodeError as exc:
                line = data[:exc.start].count(b"\n") + 1
                raise PlanError(f"{p.name}, line {line}: not UTF-8 text (byte 0x{data[exc.start]:02x}); "
                                "a plan is a YAML text file: save it as UTF-8", line=line) from None
            return parse_plan(text, source=p.name)
        return parse_plan(s)
    raise PlanError(f"plan must be a Plan, a dict, a YAML file or YAML text, got "
                    f"{type(plan).__name__}")
