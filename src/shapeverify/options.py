"""What to inspect with (:class:`InspectionOptions`) and what to write (:class:`OutputRequest`).

Every front end builds one :class:`InspectionOptions` at its boundary and passes it whole: the
command line with :meth:`InspectionOptions.from_cli` (``shapeverify inspect`` and ``batch``),
the service with :meth:`InspectionOptions.from_query` (``POST /inspect``), a plan with
:meth:`InspectionOptions.from_plan`, and :func:`shapeverify.inspect`'s keywords with
:meth:`InspectionOptions.from_kwargs`.  The object is frozen, validated when it is built (a bad
value raises :class:`OptionError`, a :class:`ValueError` that names the option the way the
front end spells it: ``--faces``, ``faces=``, the query parameter ``faces``), and picklable (batch
ships it to its workers).  What depends on the model (the default evaluation distance, whether
a face number exists) is checked by the inspection itself.

This module is a leaf: it imports numpy only (the registration's names are checked lazily).

>>> opts = InspectionOptions(tolerance=0.2, faces="0, 3,3")
>>> opts.faces, opts.evaluation_distance
((0, 3), None)
>>> InspectionOptions.from_query({"tolerance": "0.2", "faces": "0,3"}) == opts
True
>>> InspectionOptions(tolerance=-1)
Traceback (most recent call last):
...
shapeverify.options.OptionError: tolerance must be > 0 mm, got -1
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

__all__ = ["InspectionOptions", "OutputRequest", "OptionError"]


class OptionError(ValueError):
    """A bad inspection option.  ``option`` is its Python name (``"evaluation_distance"``);
    the message names it as the front end spells it (:meth:`spelled`)."""

    def __init__(self, option: str, template: str, spelling: str | None = None):
        self.option, self.template = option, template
        self.spelling = spelling or option
        super().__init__(template.replace("{name}", self.spelling))

    def spelled(self, spelling: str) -> "OptionError":
        """The same error naming the option ``spelling`` (``--evaluation-distance``)."""
        return OptionError(self.option, self.template, spelling)


def _number(name: str, value, *, positive: bool = False, unit: str = " mm") -> float | None:
    if value is None:
        return None
    of = f" of{unit}" if unit else ""
    try:
        if isinstance(value, bool):
            raise TypeError
        x = float(value)
    except (TypeError, ValueError):
        raise OptionError(name, "{name} must be a number" + of + f", got {value!r}") from None
    if not math.isfinite(x):
        raise OptionError(name, "{name} must be a finite number" + of + f", got {value!r}")
    if positive and not x > 0:
        raise OptionError(name, "{name} must be > 0" + unit + f", got {x:g}")
    return x


def _faces(value) -> tuple | str | None:
    """``"0,3,7"``, ``"all"``, ``"seen"``, a sequence of face numbers or None -> sorted tuple,
    ``"seen"`` or None."""
    if value is None or (isinstance(value, str) and value.strip().lower() == "all"):
        return None
    if isinstance(value, str) and value.strip().lower() == "seen":
        return "seen"
    items = [f for f in value.replace(",", " ").split() if f] if isinstance(value, str) \
        else list(np.atleast_1d(np.asarray(value, dtype=object)))
    out = []
    for f in items:
        try:
            i = int(f)
        except (TypeError, ValueError):
            i = None
        if i is None or i < 0 or (not isinstance(f, str) and i != f):
            raise OptionError("faces", "{name} must be CAD face numbers (0, 1, ...; see "
                              f"`shapeverify info`), e.g. '0,3,7'; got {f!r}")
        out.append(i)
    if not out:
        raise OptionError("faces", "{name} is empty; name at least one face, or leave it out "
                          "to inspect all")
    return tuple(sorted(set(out)))


def _pose(name: str, value) -> tuple:
    T = np.asarray(value, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise OptionError(name, "{name} must be a start strategy ('auto', 'identity', "
                          "'principal-axes', 'global') or a finite 4x4 T_model_scan; got an array "
                          f"of shape {T.shape}")
    return tuple(tuple(float(v) for v in row) for row in T)


def _init(value):
    """None, a canonical strategy name, a 4x4 pose (nested tuple) or a tuple of per-view poses."""
    if value is None:
        return None
    if isinstance(value, str):
        from shapeverify.registration.options import InitMode

        try:
            mode, _ = InitMode.parse(value)
        except ValueError:
            raise OptionError("init", "{name} must be 'auto', 'identity', 'principal-axes', "
                              f"'global' or a 4x4 T_model_scan, got {value!r}") from None
        return str(mode)      # 'auto' stays: unlike None it does not start at a fixture pose
    if isinstance(value, (list, tuple)) and value and (
            value[0] is None or np.shape(value[0]) == (4, 4)):
        return tuple(None if p is None else _pose("init", p) for p in value)   # one per view
    return _pose("init", value)


def _is_one_pose(init) -> bool:
    """Whether a stored ``init`` is one 4x4 pose (not a tuple of per-view poses)."""
    return isinstance(init[0], tuple) and isinstance(init[0][0], float)


def _unit(name: str, value) -> str | None:
    if value is None:
        return None
    from shapeverify.units import unit_factor

    try:
        unit_factor(value)
    except ValueError as exc:
        raise OptionError(name, "{name}: " + str(exc)) from None
    return str(value)


def _plan(value):
    """A loaded plan (a :class:`~shapeverify.characteristics.Plan`): loaded once, here."""
    if value is None:
        return None
    from shapeverify.characteristics import load_plan

    return load_plan(value)


def _pairs(value, key=str) -> tuple:
    """A mapping (or pairs) as a sorted tuple of ``(key(k), v)`` pairs: frozen, comparable."""
    if value is None:
        return ()
    items = value.items() if isinstance(value, Mapping) else value
    return tuple(sorted(((key(k), v) for k, v in items), key=lambda kv: repr(kv[0])))


@dataclass(frozen=True)
class InspectionOptions:
    """Every setting of one inspection, checked once, passed whole (module docstring).

    Attributes
    ----------
    tolerance : float or Tolerance, optional
        Symmetric tolerance ±mm, or a :class:`~shapeverify.inspection.Tolerance`.
    lower, upper : float, optional
        Signed limits (mm) overriding ``tolerance`` (``lower=-0.1, upper=0.3``).  A tolerance or
        both limits are required.
    evaluation_distance : float, optional
        Scan points farther than this from the CAD surface are not evaluated (mm); None: the
        default of :func:`shapeverify.inspection.default_evaluation_distance`.
    faces : tuple of int or "seen", optional
        The inspected CAD faces (``"0,3,7"`` is accepted); None: all; ``"seen"``: the faces the
        scan saw (:func:`shapeverify.inspection.coverage.seen_faces`).
    min_coverage : float, optional
        Least covered share of the inspected area, 0..1 (None: 0.2).
    init : str, 4x4 or tuple of 4x4, optional
        Start pose: None (the prepared model's fixture pose if it has one, else ``'auto'``), a
        strategy (``'auto'``, ``'identity'``, ``'principal-axes'``, ``'global'``; aliases are
        stored by these names), a ``T_model_scan`` (stored as a nested tuple, see
        :attr:`init_pose`), or for several views one pose (or None) per view.
    plan : Plan, optional
        An inspection plan (a path, dict or YAML text is loaded when the object is built).
    scan_unit, model_unit : str, optional
        Units of files that carry none (:mod:`shapeverify.units`; default mm).
    per_face : tuple of (face, tolerance or (lower, upper)), optional
        Per-face tolerances (a dict is accepted).
    min_region_points : int, optional
        Fewest core points of a defect region (None: 5).
    min_inlier_fraction : float, optional
        Below this registration inlier fraction the verdict is 'error' (None: 0.25).
    missing : bool
        Look for CAD surface the scan sees through (default True; :func:`shapeverify.inspect`).
    rng : int or numpy Generator
        Seed of the registration's random choices (default 0: the same result every run).
    registration : tuple of (name, value)
        More keywords of :func:`shapeverify.register` (a dict is accepted; see
        :attr:`register_kwargs`): ``{"method": "point-to-point", "options":
        RegistrationOptions(restart=False)}``.
    """

    tolerance: Any = None
    lower: float | None = None
    upper: float | None = None
    evaluation_distance: float | None = None
    faces: tuple | None = None
    min_coverage: float | None = None
    init: Any = None
    plan: Any = None
    scan_unit: str | None = None
    model_unit: str | None = None
    per_face: tuple = ()
    min_region_points: int | None = None
    min_inlier_fraction: float | None = None
    missing: bool = True
    rng: Any = 0
    registration: tuple = ()

    def __post_init__(self):
        put = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 - frozen
        if not _is_tolerance(self.tolerance):
            put("tolerance", _number("tolerance", self.tolerance, positive=True))
        put("lower", _number("lower", self.lower))
        put("upper", _number("upper", self.upper))
        if self.tolerance is None and (self.lower is None or self.upper is None):
            raise OptionError("tolerance", "give {name} (±mm) or both lower and upper limits (mm)")
        if self.lower is not None and self.lower > 0:
            raise OptionError("lower", "{name} limit is a signed deviation and must be <= 0 mm, "
                              f"got {self.lower:g}; did you mean {-self.lower:g}?")
        if self.upper is not None and self.upper < 0:
            raise OptionError("upper", "{name} limit must be >= 0 mm, got "
                              f"{self.upper:g}; did you mean {-self.upper:g}?")
        if self.lower is not None and self.lower == self.upper:
            raise OptionError("lower", f"the tolerance zone [{self.lower:g}, {self.upper:g}] mm "
                              "is empty: give {name} < upper")
        put("evaluation_distance", _number("evaluation_distance", self.evaluation_distance,
                                           positive=True))
        put("faces", _faces(self.faces))
        cov = _number("min_coverage", self.min_coverage, unit="")
        if cov is not None and not 0.0 <= cov <= 1.0:
            raise OptionError("min_coverage", "{name} is a fraction of the inspected area, "
                              f"0..1; got {self.min_coverage!r}")
        put("min_coverage", cov)
        put("init", _init(self.init))
        put("plan", _plan(self.plan))
        put("scan_unit", _unit("scan_unit", self.scan_unit))
        put("model_unit", _unit("model_unit", self.model_unit))
        put("per_face", _pairs(self.per_face, key=lambda f: f))   # face numbers: Tolerance checks them
        if self.min_region_points is not None:
            n = _number("min_region_points", self.min_region_points, positive=True, unit="")
            if n != int(n):
                raise OptionError("min_region_points", "{name} must be a whole number, got "
                                  f"{self.min_region_points!r}")
            put("min_region_points", int(n))
        put("min_inlier_fraction", _number("min_inlier_fraction", self.min_inlier_fraction,
                                           unit=""))
        put("missing", bool(self.missing))
        put("registration", _pairs(self.registration))

    # -- views of the settings ---------------------------------------------------------------

    @property
    def init_pose(self):
        """``init`` as the registration takes it: None, a strategy name, a (4, 4) array, or a
        list (one pose or None per view)."""
        if self.init is None or isinstance(self.init, str):
            return self.init
        if _is_one_pose(self.init):
            return np.array(self.init, dtype=np.float64)
        return [None if p is None else np.array(p, dtype=np.float64) for p in self.init]

    @property
    def register_kwargs(self) -> dict:
        """The extra keywords of :func:`shapeverify.register` as a dict."""
        return dict(self.registration)

    def view_kwargs(self) -> dict:
        """The keywords of :func:`shapeverify.inspection.inspect_views` (not ``poses``, not
        ``plan``: several views take no plan yet)."""
        out = {"tolerance": self.tolerance, "rng": self.rng,
               "register_kwargs": self.register_kwargs or None,
               "per_face": dict(self.per_face) or None, "missing": self.missing}
        for k in ("evaluation_distance", "lower", "upper", "faces", "min_coverage",
                  "min_region_points", "min_inlier_fraction"):
            if getattr(self, k) is not None:
                out[k] = getattr(self, k)
        return out

    def replace(self, **changes) -> "InspectionOptions":
        """A copy with ``changes`` (checked again)."""
        return dataclasses.replace(self, **changes)

    # -- the boundaries ----------------------------------------------------------------------

    @classmethod
    def from_kwargs(cls, *, tolerance=None, max_distance=None, stacklevel: int = 3,
                    **kwargs) -> "InspectionOptions":
        """The options of :func:`shapeverify.inspect`'s keywords: ``tolerance`` None is 0.2 mm
        (its default; ``lower``/``upper`` override it); ``max_distance`` is the old name of
        ``evaluation_distance`` (a :class:`DeprecationWarning`)."""
        if max_distance is not None:
            if kwargs.get("evaluation_distance") is not None:
                raise OptionError("max_distance", "give evaluation_distance only ({name} is its "
                                  "old name)")
            warnings.warn("max_distance= is now called evaluation_distance= (the old name will "
                          "go)", DeprecationWarning, stacklevel=stacklevel)
            kwargs["evaluation_distance"] = max_distance
        if tolerance is None and (kwargs.get("lower") is None or kwargs.get("upper") is None):
            tolerance = 0.2
        unknown = sorted(set(kwargs) - _FIELDS)
        if unknown:
            raise TypeError(f"unknown inspection option(s) {unknown}; known: {sorted(_FIELDS)}")
        return cls(tolerance=tolerance, **kwargs)

    @classmethod
    def from_plan(cls, plan, **kwargs) -> "InspectionOptions":
        """The options of an inspection by ``plan`` (a path, dict, YAML text or Plan): without
        a tolerance, the colour map's is half the plan's first surface-profile zone (else
        0.1 mm)."""
        loaded = _plan(plan)
        if kwargs.get("tolerance") is None and (kwargs.get("lower") is None
                                                or kwargs.get("upper") is None):
            kwargs["tolerance"] = _plan_tolerance(loaded)
        return cls(plan=loaded, **kwargs)

    @classmethod
    def from_cli(cls, values: Mapping[str, Any], n_scans: int = 1) -> "InspectionOptions":
        """The options of ``shapeverify inspect`` / ``batch`` (``values``: their option values by
        Python name).  ``init`` is a strategy or a ``T.json``/``T.npy`` file, ``poses`` a JSON
        file of per-view poses, ``plan`` a ``plan.yaml``; errors name the ``--option``."""
        v = {k: x for k, x in values.items() if x is not None}
        try:
            poses = v.pop("poses", None)
            if poses is not None:
                if "init" in v:
                    raise OptionError("poses", "give either --init (one scan) or {name} (several "
                                      "views), not both")
                v["init"] = read_poses(poses, n_scans)
            elif isinstance(v.get("init"), (str, os.PathLike)) and is_pose_file(v["init"]):
                from shapeverify.registration import read_init

                v["init"] = read_init(Path(v["init"]))    # a strategy's name is not a file
            if "plan" in v:
                return cls.from_plan(v.pop("plan"), **v)
            if v.get("tolerance") is None and (v.get("lower") is None or v.get("upper") is None):
                raise OptionError("tolerance", "give {name} MM (or --lower/--upper limits in mm, "
                                  "or a --plan)")
            return cls(**v)
        except OptionError as exc:
            raise exc.spelled("--" + exc.option.replace("_", "-")) from None

    @classmethod
    def from_query(cls, params: Mapping[str, Any]) -> "InspectionOptions":
        """The options of a service request's query parameters (strings): ``tolerance``,
        ``lower``, ``upper``, ``evaluation_distance`` (``max_distance``: its old name, a
        :class:`DeprecationWarning`), ``faces`` (``0,3,7``), ``min_coverage``, ``init`` (a
        strategy or 16 comma-separated numbers, row by row), ``scan_unit``, ``plan`` (the plan's
        YAML text, never a file name).  Errors name the query parameter."""
        v = {k: x for k, x in params.items() if x is not None and x != ""}
        try:
            old = v.pop("max_distance", None)
            if old is not None:
                if "evaluation_distance" in v:
                    raise OptionError("max_distance", "give evaluation_distance only ({name} is "
                                      "its old name)")
                warnings.warn("the query parameter max_distance is now called "
                              "evaluation_distance (the old name will go)", DeprecationWarning,
                              stacklevel=2)
                v["evaluation_distance"] = old
            unknown = sorted(set(v) - _QUERY)
            if unknown:
                raise OptionError(unknown[0], "unknown inspection parameter {name}; known: "
                                  + ", ".join(sorted(_QUERY)))
            if "init" in v:
                v["init"] = _query_init(v["init"])
            if "plan" in v:
                from shapeverify.characteristics.plan import parse_plan

                plan = parse_plan(str(v.pop("plan")), source="the plan query parameter")
                return cls.from_plan(plan, **v)
            return cls(**v)
        except OptionError as exc:
            raise exc.spelled(exc.option) from None


_FIELDS = {f.name for f in dataclasses.fields(InspectionOptions)}
#: the options a service query may set (the others keep their defaults)
_QUERY = {"tolerance", "lower", "upper", "evaluation_distance", "faces", "min_coverage", "init",
          "scan_unit", "plan"}


def _is_tolerance(x) -> bool:
    return type(x).__name__ == "Tolerance" and hasattr(x, "max_abs")


def _plan_tolerance(plan) -> float:
    """Half the first surface profile's zone width (ISO 1101: a profile tolerance t is a zone of
    total width t), else 0.1 mm."""
    for c in plan.characteristics:
        if c.type == "surface_profile" and getattr(c, "tol", None):
            return 0.5 * float(c.tol)
    return 0.1


def is_pose_file(init) -> bool:
    """Whether a command line's ``--init`` value is a file (``T.json``, ``T.npy``), not the
    name of a start strategy."""
    from shapeverify.registration.options import InitMode

    try:
        InitMode.parse(os.fspath(init))
    except ValueError:
        return True
    return False


def _query_init(text: str):
    """The ``init`` query parameter: a strategy name or 16 numbers (T_model_scan row by row)."""
    key = str(text).strip().lower()
    if key == "auto":
        return None           # the service's 'auto': the model's fixture pose if it has one
    if key in ("identity", "global", "principal-axes", "pca"):
        return key
    try:
        T = np.array([float(v) for v in key.replace(";", ",").split(",")], dtype=np.float64)
    except ValueError:
        T = np.zeros(0)
    if T.shape != (16,) or not np.all(np.isfinite(T)):
        raise OptionError("init", "{name} must be 'auto', 'identity', 'global', 'principal-axes' "
                          "or 16 comma-separated numbers (T_model_scan row by row)")
    return T.reshape(4, 4)


def read_poses(path, n_scans: int) -> list:
    """``--poses``: a JSON list of 4x4 start poses (or null), one per view."""
    import json

    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a JSON file ({exc})") from None
    if not isinstance(data, list) or not all(p is None or np.shape(p) == (4, 4) for p in data):
        raise ValueError(f"{path}: --poses must be a JSON list of 4x4 matrices (or null), one "
                         "per view")
    if n_scans > 1 and len(data) != n_scans:
        raise ValueError(f"{path}: {len(data)} poses for {n_scans} scans: give one per view")
    return [None if p is None else np.asarray(p, dtype=np.float64) for p in data]


@dataclass(frozen=True)
class OutputRequest:
    """What to write after one inspection (None: not written); the one writer is
    :func:`shapeverify.pipeline.write_outputs` (command line, service and batch).

    Attributes
    ----------
    json, report, pdf, png, colored : path, optional
        The result as JSON, the HTML report, the PDF report, a PNG summary, a PLY coloured by
        deviation.
    db : path, optional
        A SQLite history (:class:`~shapeverify.report.history.HistoryDB`) the result is stored
        in (with a plan, its characteristics too).
    part : str, optional
        The part id of the history row and the reports.
    model_hash : str, optional
        The SHA-256 of the model file, stored with the row.
    replace_record : int, optional
        Overwrite this history row instead of adding one (a batch scan inspected again).
    """

    json: Path | None = None
    report: Path | None = None
    pdf: Path | None = None
    png: Path | None = None
    colored: Path | None = None
    db: Path | None = None
    part: str | None = None
    model_hash: str | None = None
    replace_record: int | None = None

    def __post_init__(self):
        for name in _FILES:
            v = getattr(self, name)
            if v is not None and not isinstance(v, Path):
                object.__setattr__(self, name, Path(v))

    @property
    def files(self) -> bool:
        """Whether anything is to be written."""
        return any(getattr(self, name) is not None for name in _FILES)

    def replace(self, **changes) -> "OutputRequest":
        """A copy with ``changes``."""
        return dataclasses.replace(self, **changes)


#: the outputs of an :class:`OutputRequest` that are files (or the history)
_FILES = ("json", "report", "pdf", "png", "colored", "db")
