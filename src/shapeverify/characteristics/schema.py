"""The characteristic schemas of a plan (pydantic models), shared base types.

Each characteristic type is one model here and one row of :mod:`.registry` (which ties it to
its evaluator, its zone sidedness and its label); :mod:`.plan` builds the plan's union of
characteristics from that table.  Lengths in mm.
"""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["Tol", "PmiSource", "Unsupported", "Vec3", "FeatureId", "FeatureRef", "Hole",
           "DatumTargetSpec", "DatumSize", "SurfaceProfile", "Flatness", "Cylinder", "CheckPoint", "DatumSpec",
           "Straightness",
           "Circularity", "Cylindricity", "Parallelism", "Perpendicularity", "Angularity",
           "Position", "CircularRunout", "TotalRunout", "Concentricity", "Width", "SizeLimits", "Distance",
           "DrillCircle",
           "Angle", "LineProfile", "PositionZone",
           "FeatureSize", "Symmetry"]

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
FeatureId = Annotated[str, Field(pattern=r"^(hole|face|cylinder|plane):\d+$")]
#: a feature id, or the CAD name of a face (a STEP face name: no colon, not blank)
FeatureRef = Annotated[str, Field(pattern=r"^((hole|face|cylinder|plane):\d+|[^:\s][^:]*)$")]
#: a datum reference frame: datum letters of the plan's ``datums`` table, primary first
DrfRef = Annotated[list[Annotated[str, Field(min_length=1)]], Field(min_length=1, max_length=3)]


class _Strict(BaseModel):
    # NaN and infinity are no limits and no coordinates (a tol of .inf would pass anything)
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Tol(_Strict):
    """Limits of a deviation: ``tol`` (symmetric ±tol, or a zone width, see module doc) or
    ``lower``/``upper`` (mm)."""

    tol: Optional[float] = Field(default=None, gt=0)
    lower: Optional[float] = None
    upper: Optional[float] = None

    @model_validator(mode="after")
    def _one_form(self):
        if self.tol is None and (self.lower is None or self.upper is None):
            raise ValueError("give tol (> 0) or both lower and upper")
        if self.tol is not None and (self.lower is not None or self.upper is not None):
            raise ValueError("give either tol or lower/upper, not both")
        if self.tol is None and not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self

    def limits(self) -> tuple[float, float]:
        """(lower, upper) of a symmetric tolerance (±tol) or the given limits."""
        if self.tol is not None:
            return -self.tol, self.tol
        return float(self.lower), float(self.upper)


class PmiSource(BaseModel):
    """Where a plan entry came from: a semantic PMI item of the CAD file (``shapeverify plan``).

    ``kind``: ``geometric_tolerance``, ``dimension`` or ``datum``; ``type``: OpenCASCADE's type
    name (``Position``, ``ProfileOfSurface``, ``Size_Diameter``, ``Datum`` ...); further keys
    (``id``, ``value``, ``datums`` ...) describe the item and are kept as they are."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)
    kind: Literal["geometric_tolerance", "dimension", "datum"]
    type: str = Field(min_length=1)


class Unsupported(_Strict):
    """A PMI item of the CAD file that the plan does not check, and why."""

    pmi: PmiSource
    reason: str = Field(min_length=1)



# ------------------------------------------------------------------------------ characteristics
class _Char(_Strict):
    name: str = Field(min_length=1)
    pmi: Optional[PmiSource] = None


class _Located(_Char):
    feature: Optional[FeatureRef] = None
    near: Optional[Vec3] = None

    @model_validator(mode="after")
    def _where(self):
        if (self.feature is None) == (self.near is None):
            raise ValueError("give exactly one of feature (e.g. 'hole:3') or near: [x, y, z]")
        return self


class Hole(_Located):
    """Diameter and/or position of a hole (circular inner trim loop of a face)."""

    type: Literal["hole"]
    diameter: Optional[Tol] = None
    position: Optional[Tol] = None

    @model_validator(mode="after")
    def _something(self):
        if self.diameter is None and self.position is None:
            raise ValueError("a hole needs diameter: {tol: ...} and/or position: {tol: ...}")
        if self.position is not None and self.position.tol is None:
            raise ValueError("position takes tol (the diameter of the tolerance zone)")
        return self


class SurfaceProfile(_Char, Tol):
    """Profile of a surface (ISO 1101) of a face group; ``datum: false`` fits the group first."""

    type: Literal["surface_profile"]
    faces: Union[Literal["all"], list[Union[FeatureId, int, str]]] = "all"
    datum: bool = True
    #: located in this datum reference frame of the plan's ``datums`` (fitted, :mod:`.drf`)
    #: instead of the plan's alignment
    datums: Optional[DrfRef] = None
    #: datums of ``datums`` referenced at MMB (``M``) or LMB (``L``): the frame may shift
    #: within what the datum feature's departure from that boundary allows, and the profile
    #: is evaluated at the best pose within it (:mod:`.datum_shift`)
    datum_modifiers: Optional[dict[str, Literal["M", "L"]]] = None
    #: a segment of a composite feature control frame (ASME Y14.5-2009 §7.5.1, §8.3.1):
    #: ``upper`` (pattern-locating: located to all its datums, as without it) or ``lower``
    #: (feature-relating: its datums orient the zone framework only; the framework translates
    #: and turns about the free datum axes to its best place: :mod:`.composite`)
    composite: Optional[Literal["upper", "lower"]] = None

    @model_validator(mode="after")
    def _drf(self):
        if self.datums is not None and not self.datum:
            raise ValueError("datums and datum: false contradict each other (a profile "
                             "without datums floats)")
        extra = sorted(set(self.datum_modifiers or ()) - set(self.datums or ()))
        if extra:
            raise ValueError(f"datum_modifiers name datums {extra} that are not in datums "
                             f"{self.datums or []}")
        if self.composite == "lower" and self.datum_modifiers:
            raise ValueError("composite: lower with datum_modifiers: the frame of a lower "
                             "segment moves freely already")
        return self


class Flatness(_Char):
    """Flatness of one planar face (``feature`` or ``near``) or of coplanar faces (``faces``,
    one zone)."""

    type: Literal["flatness"]
    tol: float = Field(gt=0)
    feature: Optional[FeatureRef] = None
    near: Optional[Vec3] = None
    faces: Optional[Annotated[list[Union[FeatureId, int, str]], Field(min_length=1)]] = None

    @model_validator(mode="after")
    def _where(self):
        if sum(x is not None for x in (self.feature, self.near, self.faces)) != 1:
            raise ValueError("give exactly one of feature (e.g. 'face:3'), near: [x, y, z] or "
                             "faces: [...] (coplanar faces)")
        return self


class Cylinder(_Located):
    """Diameter of a cylinder (a boss, a bore's wall): one face (``feature`` or ``near``),
    or the coaxial faces of one radius that the CAD splits it into (``faces``: two
    half-cylinders, a face cut at a seam), fitted as one cylinder."""

    type: Literal["cylinder"]
    diameter: Tol
    faces: Optional[Annotated[list[Union[FeatureId, int, str]], Field(min_length=1)]] = None

    @model_validator(mode="after")
    def _where(self):
        if sum(x is not None for x in (self.feature, self.near, self.faces)) != 1:
            raise ValueError("give exactly one of feature (e.g. 'face:3'), near: [x, y, z] or "
                             "faces: [...] (the faces of one cylinder)")
        return self


class CheckPoint(_Char, Tol):
    """Deviation along the CAD normal at a named point (mean of the scan within ``radius``)."""

    type: Literal["check_point"]
    at: Vec3
    radius: float = Field(default=2.0, gt=0)



# ------------------------------------------------------------------------------ GD&T (issue 28)
FaceList = Annotated[list[Union[FeatureId, int, str]], Field(min_length=1)]


class DatumTargetSpec(_Strict):
    """One datum target of a datum (ASME Y14.5 / ISO 5459, :mod:`.datum_targets`): ``point``
    (a contact at ``at`` on ``face``), ``line`` (a line contact through ``at`` along
    ``direction``, ``length`` long), ``circle`` (a circular area of diameter ``length`` centred
    at ``at``, ``direction`` its normal) or ``rectangle`` (``length`` along ``xdirection``,
    ``width`` across) or ``circular_line`` (a ring of diameter ``length`` about ``at``,
    normal ``direction``, touching the part along a circle: a boss or a hole, maybe drafted,
    on ``faces``)."""

    type: Literal["point", "line", "circle", "rectangle", "circular_line"]
    at: Vec3
    face: Optional[Union[FeatureId, int, str]] = None
    #: the faces a target drawn across several faces lies on (a circular line around a boss
    #: split in halves); instead of ``face``
    faces: Optional[FaceList] = None
    direction: Optional[Vec3] = None
    xdirection: Optional[Vec3] = None
    length: float = Field(default=0.0, ge=0)
    width: float = Field(default=0.0, ge=0)

    @model_validator(mode="after")
    def _sized(self):
        if (self.face is None) == (self.faces is None):
            raise ValueError(f"a {self.type} datum target takes face: (the face it lies on) or "
                             "faces: [...] (several), not both or neither")
        if self.faces is not None and self.type != "circular_line":
            raise ValueError(f"a {self.type} datum target lies on one face (face:)")
        if self.type != "point" and not self.length > 0:
            raise ValueError(f"a {self.type} datum target needs its length (> 0; a circle's "
                             "diameter)")
        if self.type == "rectangle" and not self.width > 0:
            raise ValueError("a rectangle datum target needs its width (> 0)")
        if self.type in ("line", "circle", "rectangle", "circular_line") and \
                self.direction is None:
            raise ValueError(f"a {self.type} datum target needs its direction (a line's "
                             "direction, an area's normal)")
        return self


class SizeLimits(_Strict):
    """Limits of a feature of size's deviation from nominal (mm): ``lower < upper``;
    ``nominal``: the drawing's size (default: the CAD's diameter)."""

    lower: float
    upper: float
    nominal: Optional[float] = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _order(self):
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self


class DatumSize(_Strict):
    """The size of a datum feature of size (a hole's or boss's diameter, mm) for a datum
    referenced at MMB/LMB (:mod:`.datum_shift`): ``nominal`` and its limits ``lower`` <
    ``upper`` (the boundary is then the size's MMC / LMC), or the boundary's diameter itself,
    ``mmb`` / ``lmb`` (a size without limits: the boundary worked out from the nominal and the
    geometric tolerances applied to the feature, :func:`.pmi_datums.derived_boundary`; ``rule``
    says how)."""

    nominal: float = Field(gt=0)
    lower: Optional[float] = None
    upper: Optional[float] = None
    mmb: Optional[float] = Field(default=None, gt=0)
    lmb: Optional[float] = Field(default=None, gt=0)
    rule: Optional[str] = None

    @model_validator(mode="after")
    def _limits(self):
        if (self.lower is None) != (self.upper is None):
            raise ValueError("a datum size takes both lower and upper (or neither, with mmb "
                             "or lmb)")
        if self.lower is not None and not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        if self.lower is None and self.mmb is None and self.lmb is None:
            raise ValueError("a datum size takes lower and upper, or the boundary mmb / lmb")
        return self


class DatumSpec(_Strict):
    """A datum feature of the plan's ``datums`` table (see :mod:`.drf`).

    ``faces``: the faces of the datum feature (one plane, or the cylinder faces of a hole or
    boss, or coplanar faces, or with ``kind: midplane`` the two opposite faces of a width); ``at`` with ``kind: point``: a point datum (target) on the
    surface; ``targets``: datum targets (:class:`DatumTargetSpec`, the datum set up from
    the scan at each target, :mod:`.datum_targets`).  ``kind`` (default: from the faces' CAD
    geometry): ``plane``, ``axis``, ``point``, ``midplane``, ``pattern`` (the axes of several
    cylinders fitted together at their CAD positions: a pattern of holes or bosses as one datum,
    or a common axis of coaxial ones), ``targets``.
    """

    faces: Optional[FaceList] = None
    at: Optional[Vec3] = None
    targets: Optional[Annotated[list[DatumTargetSpec], Field(min_length=1)]] = None
    kind: Optional[Literal["plane", "midplane", "axis", "point", "pattern", "targets"]] = None
    #: a hole's or boss's diameter limits (needed when a characteristic references the datum
    #: at MMB or LMB: ``datum_modifiers``)
    size: Optional[DatumSize] = None
    #: a pattern or common datum of features of different sizes (``E-F`` of a 5.8 and a 6.1
    #: hole): the size limits of the feature each of ``faces`` belongs to, in ``faces``' order
    face_sizes: Optional[list[DatumSize]] = None
    pmi: Optional[PmiSource] = None

    @model_validator(mode="after")
    def _what(self):
        if sum(x is not None for x in (self.faces, self.at, self.targets)) != 1:
            raise ValueError("a datum takes faces: [...] (a datum feature), at: [x, y, z] "
                             "(a point) or targets: [...] (datum targets)")
        if (self.kind == "targets") != (self.targets is not None) and self.kind is not None:
            raise ValueError("kind: targets goes with targets: [...] (and only with it)")
        if self.kind == "pattern" and self.faces is None:
            raise ValueError("a pattern datum takes faces: [...] (the cylinder faces of its "
                             "features)")
        if self.face_sizes is not None and (self.faces is None
                                            or len(self.face_sizes) != len(self.faces)):
            raise ValueError("face_sizes gives one size per face of faces: [...] (the size of "
                             "the feature each face belongs to)")
        if self.at is not None and self.kind not in (None, "point"):
            raise ValueError("a datum given by at: [x, y, z] is a point (kind: point)")
        return self


class _Gdt(_Char):
    """A geometric tolerance: zone width ``tol`` (mm) of the faces ``faces``."""

    faces: FaceList
    tol: float = Field(gt=0)


class _Each(_Gdt):
    """A tolerance that may apply to several separate features (a "3X" frame on three pins):
    ``features`` splits ``faces`` into the features (each a list of faces: one cylinder, one
    plane), and each is evaluated on its own (ASME Y14.5: a frame that applies to several
    features applies to each individually; :mod:`.each_feature`).  Without it, ``faces`` is
    one feature."""

    features: Optional[Annotated[list[FaceList], Field(min_length=2)]] = None

    @model_validator(mode="after")
    def _split(self):
        if self.features is not None and sorted(
                str(f) for g in self.features for f in g) != sorted(str(f) for f in self.faces):
            raise ValueError(f"features {self.features} must split faces {self.faces} (each "
                             "face in exactly one feature)")
        return self


class _Form(_Each):
    pass


class Straightness(_Form):
    """Straightness of a cylinder's axis (``zone: diameter``) or of the line elements of the
    faces along ``direction`` (two parallel lines, default).  With ``through`` (and
    ``length``): the one line element of the faces through that point along ``direction``
    (a straight line of the CAD surface, e.g. a cylinder's generator: a line drawn on the face
    in the file), ``length`` mm long centred there, in the section plane that holds it and the
    face's normal."""

    type: Literal["straightness"]
    zone: Literal["lines", "diameter"] = "lines"
    direction: Optional[Vec3] = None
    through: Optional[Vec3] = None
    length: Optional[float] = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _line(self):
        if self.through is not None and (self.direction is None or self.length is None
                                         or self.zone != "lines"):
            raise ValueError("straightness through a point takes direction and length "
                             "(zone: lines)")
        return self


class Circularity(_Form):
    type: Literal["circularity"]


class Cylindricity(_Form):
    type: Literal["cylindricity"]


class _Oriented(_Each):
    """Orientation/location of ``faces`` relative to the datum reference frame ``datums``.
    ``zone``: ``planes`` (two parallel planes: a plane, or an axis in one direction) or
    ``diameter`` (a cylinder about the axis of a hole or boss) or ``median_plane`` (two
    parallel planes holding the derived median plane of a width: ``faces`` are its two
    opposite sides, :mod:`.median_plane`)."""

    datums: DrfRef
    zone: Literal["planes", "diameter", "median_plane"] = "planes"
    #: the zone holds the surface's tangent (contacting) plane, not every point (ASME (T))
    tangent_plane: bool = False
    #: an axis's bonus tolerance from its measured size (``size``: the diameter's limits)
    material: Optional[Literal["M", "L"]] = None
    size: Optional[SizeLimits] = None
    #: a segment of a composite feature control frame (ASME Y14.5-2009 §7.5.1, §8.3.1):
    #: ``upper`` (pattern-locating: located to all its datums, as without it) or ``lower``
    #: (feature-relating: its datums orient the zone framework only; the framework translates
    #: and turns about the free datum axes to its best place: :mod:`.composite`)
    composite: Optional[Literal["upper", "lower"]] = None
    #: a projected zone (Ⓟ, ASME Y14.5-2009 §7.4.1) of this length (mm) of an axis (zone:
    #: diameter): the zone holds the axis extended out of the hole's mouth (:mod:`.gdt`)
    projected: Optional[float] = Field(default=None, gt=0)
    #: the direction out of the hole's mouth (model frame); default: the ``hole:k``'s axis
    projected_direction: Optional[Vec3] = None

    @model_validator(mode="after")
    def _bonus(self):
        if self.material is not None and (self.size is None or self.zone != "diameter"):
            raise ValueError(f"material {self.material} applies to an axis (zone: diameter) "
                             "and needs size: {lower, upper}")
        if self.projected is not None and self.zone != "diameter":
            raise ValueError("projected applies to an axis (zone: diameter)")
        if self.projected_direction is not None and self.projected is None:
            raise ValueError("projected_direction without projected (the zone's length)")
        return self


class Parallelism(_Oriented):
    type: Literal["parallelism"]


class Perpendicularity(_Oriented):
    type: Literal["perpendicularity"]


class Angularity(_Oriented):
    """The nominal angle to the datums is the CAD's (the zone has the CAD face's
    orientation in the DRF)."""

    type: Literal["angularity"]


class Position(_Char):
    """Position of the axes of holes/bosses (``features``: each ``hole:N``, a cylinder face
    ``face:N`` or a list of coaxial cylinder faces; several: a pattern under one tolerance), in the datum reference frame
    ``datums`` (none: the plan's alignment).  ``zone: diameter``: a cylindrical zone of
    diameter ``tol``; ``zone: planes``: two parallel planes ``tol`` apart, perpendicular to
    ``direction`` (across the axes; ASME Y14.5-2009 §7.7.3, bidirectional positional
    tolerancing), about the true position.  ``material: M`` or ``L``: the bonus tolerance
    from the measured size (``size``: the diameter's limits of deviation), capped at
    ``max_tol``.  ``projected``: a projected zone of that length out of each hole's mouth."""

    type: Literal["position"]
    features: Annotated[list[Union[FeatureRef, Annotated[list[FeatureRef], Field(min_length=1)]]],
                        Field(min_length=1)]
    #: 0 only with a material modifier (ASME Y14.5-2009 §7.3.3.3: zero at MMC/LMC, all of the
    #: tolerance is bonus)
    tol: float = Field(ge=0)
    zone: Literal["diameter", "planes"] = "diameter"
    #: ``zone: planes``: the planes' normal (model frame, across the axes): the zone bounds
    #: the axes' offset from the true position along it
    direction: Optional[Vec3] = None
    datums: Optional[DrfRef] = None
    material: Optional[Literal["M", "L"]] = None
    size: Optional[SizeLimits] = None
    #: features of different sizes under one frame (a counterbored hole: the hole and its
    #: counterbore, coaxial, each an entry of ``features`` with the same true position): the
    #: size limits of each, in ``features``' order, for each one's own bonus (instead of
    #: ``size``)
    feature_sizes: Optional[list[SizeLimits]] = None
    #: the maximum tolerance with a material modifier (ASME Y14.5-2009 §7.3.4, "MAX" in the
    #: frame): the limit is ``min(tol + bonus, max_tol)``
    max_tol: Optional[float] = Field(default=None, gt=0)
    #: a projected tolerance zone (Ⓟ, ASME Y14.5-2009 §7.4.1) of this length (mm): the zone
    #: holds the axis extended out of the hole's mouth over ``projected`` mm (:mod:`.gdt`)
    projected: Optional[float] = Field(default=None, gt=0)
    #: the direction out of the holes' mouth (model frame) the projected zone goes; default:
    #: the ``hole:k`` feature's axis (its entry face's outward side)
    projected_direction: Optional[Vec3] = None
    #: datums of ``datums`` referenced at MMB (``M``) or LMB (``L``): the axes are evaluated
    #: at the best pose within the datum feature shift (:mod:`.datum_shift`)
    datum_modifiers: Optional[dict[str, Literal["M", "L"]]] = None
    #: a segment of a composite feature control frame (ASME Y14.5-2009 §7.5.1, §8.3.1):
    #: ``upper`` (pattern-locating: located to all its datums, as without it) or ``lower``
    #: (feature-relating: its datums orient the zone framework only; the framework translates
    #: and turns about the free datum axes to its best place: :mod:`.composite`)
    composite: Optional[Literal["upper", "lower"]] = None

    @model_validator(mode="after")
    def _bonus(self):
        if self.material is not None and self.size is None and self.feature_sizes is None:
            raise ValueError(f"material {self.material} needs size: {{lower, upper}} (the "
                             "diameter's limits of deviation) for the bonus tolerance")
        if self.feature_sizes is not None and (self.material is None or self.size is not None
                                               or len(self.feature_sizes)
                                               != len(self.features)):
            raise ValueError("feature_sizes gives one size per entry of features, with "
                             "material: M or L and instead of size")
        if self.tol == 0 and self.material is None:
            raise ValueError("tol 0 needs material: M or L (a zero tolerance at MMC/LMC is all "
                             "bonus); without one, give the zone's diameter (> 0)")
        if self.projected_direction is not None and self.projected is None:
            raise ValueError("projected_direction without projected (the zone's length)")
        if self.max_tol is not None and (self.material is None or self.max_tol < self.tol):
            raise ValueError(f"max_tol {self.max_tol} caps a bonus tolerance: it needs "
                             f"material: M or L and max_tol >= tol ({self.tol})")
        extra = sorted(set(self.datum_modifiers or ()) - set(self.datums or ()))
        if extra:
            raise ValueError(f"datum_modifiers name datums {extra} that are not in datums "
                             f"{self.datums or []}")
        if (self.zone == "planes") != (self.direction is not None):
            raise ValueError("zone: planes takes direction (the planes' normal), and "
                             "direction applies to zone: planes only")
        if self.direction is not None and not sum(x * x for x in self.direction) > 0:
            raise ValueError("direction must be a non-zero vector")
        if self.zone == "planes" and (self.datum_modifiers or self.composite == "lower"):
            raise ValueError("zone: planes is evaluated at the datums' pose (no "
                             "datum_modifiers, no composite lower segment)")
        return self


class LineProfile(_Char):
    """Profile of a line (:mod:`.profile_line`): the line elements of ``faces`` in sections
    normal to ``normal`` (at ``sections`` mm along it, or ``count`` evenly spaced), each
    sampled by the points within ``slab`` mm of its plane, within a zone of width ``tol``;
    in the datum reference frame ``datums`` (none: the plan's alignment)."""

    type: Literal["line_profile"]
    faces: FaceList
    tol: float = Field(gt=0)
    normal: Vec3
    sections: Optional[Annotated[list[float], Field(min_length=1)]] = None
    count: int = Field(default=10, ge=1)
    slab: float = Field(default=0.5, gt=0)
    datums: Optional[DrfRef] = None

    @model_validator(mode="after")
    def _normal(self):
        if not sum(x * x for x in self.normal) > 0:
            raise ValueError("normal must be a non-zero vector (the section planes' normal)")
        return self


class PositionZone(_Char):
    """Position in a zone of two parallel planes (``zone: planes``: the centre plane of the
    width feature whose opposite planar sides are ``faces``) or a sphere (``zone: sphere``:
    the centre of the sphere of ``faces``), of width/diameter ``tol``, in the datum reference
    frame ``datums`` (none: the plan's alignment); :mod:`.position_zones`."""

    type: Literal["position_zone"]
    faces: FaceList
    tol: float = Field(gt=0)
    zone: Literal["planes", "sphere"]
    datums: Optional[DrfRef] = None


class FeatureSize(_Char):
    """Size (radius or diameter, ``size``) of a cylinder (coaxial faces of one radius), a
    sphere, or a torus's tube (a fillet's radius) (``shape``) against ``lower``/``upper``
    limits of deviation (mm) from the CAD's size (``nominal``: the drawing's, for the report);
    :mod:`.size_features`."""

    type: Literal["feature_size"]
    faces: FaceList
    shape: Literal["cylinder", "sphere", "torus"]
    size: Literal["radius", "diameter"]
    lower: float
    upper: float
    nominal: Optional[float] = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _order(self):
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self


class ConeAngle(_Char):
    """The angle (degrees) of the least-squares cone of ``faces`` (one cone: a countersink, a
    chamfer; the CAD may split it in several faces): ``angle: included`` (the apex angle, as a
    countersink's 90° is drawn) or ``half`` (to the axis), within ``lower``/``upper`` of the
    CAD's angle (``nominal``: the drawing's, for the report); :mod:`.cone_sizes`."""

    type: Literal["cone_angle"]
    faces: FaceList
    angle: Literal["included", "half"] = "included"
    lower: float
    upper: float
    nominal: Optional[float] = Field(default=None, gt=0, lt=180)

    @model_validator(mode="after")
    def _order(self):
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self


class ConeDiameter(_Char):
    """A countersink's diameter (mm): the least-squares cone of ``faces`` where its axis meets
    the least-squares plane of ``at`` (the surface it is cut in), within ``lower``/``upper``
    of the CAD's (``nominal``: the drawing's, for the report); :mod:`.countersink`."""

    type: Literal["cone_diameter"]
    faces: FaceList
    at: FaceList
    lower: float
    upper: float
    nominal: Optional[float] = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _order(self):
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self


class _Runout(_Gdt):
    """Runout of the surfaces ``faces`` about the datum axis (``datums``: an axis datum)."""

    datums: DrfRef


class CircularRunout(_Runout):
    type: Literal["circular_runout"]


class TotalRunout(_Runout):
    type: Literal["total_runout"]


class Concentricity(_Runout):
    """Concentricity (ASME Y14.5-2009 7.6.4): the median points of diametrically opposed
    elements of ``faces`` (a surface of revolution) in a cylindrical zone of diameter ``tol``
    about the datum axis (:mod:`.concentricity`)."""

    type: Literal["concentricity"]
    zone: Literal["diameter"] = "diameter"


class Symmetry(_Gdt):
    """Symmetry (ASME Y14.5-2009 7.7.2): the median points of opposed elements of the width
    whose two opposite planar sides are ``faces`` in two parallel planes ``tol`` apart centred
    on the datum centre plane (the CAD's centre plane in the DRF ``datums``;
    :mod:`.symmetry`)."""

    type: Literal["symmetry"]
    datums: DrfRef


class _TwoPlanes(_Char):
    """A dimension between two planar faces (``faces``: two) with limits of deviation
    ``lower < upper`` from its nominal (the CAD's, or the type's ``nominal``)."""

    faces: Annotated[list[Union[FeatureId, int, str]], Field(min_length=2, max_length=2)]
    lower: float
    upper: float

    @model_validator(mode="after")
    def _order(self):
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self


class Width(_TwoPlanes):
    """Size: the distance between two opposite parallel planar faces (``faces``: two)
    within ``lower``/``upper`` of the CAD's distance (two-point sizes, ISO 14405-1)."""

    type: Literal["width"]


_Faces = Union[FeatureId, int, str, list[Union[FeatureId, int, str]]]


class DrillCircle(_Strict):
    """The circle where a hole's cylindrical wall (``cylinder``: a face or the faces of one
    cylinder) meets its drill point (``cone``: a face or the faces of one cone)."""

    cylinder: _Faces
    cone: _Faces


class Distance(_TwoPlanes):
    """The distance (mm) between two parallel planar sides, either facing (a step or a
    width), between their least-squares planes.  A side is a face, or a list of coplanar
    planar faces fitted as one plane (``faces: [face:68, [face:70, face:72]]``: a thickness
    to a face split in four).  The second side may be the circle where a hole's wall meets
    its drill point, ``{cylinder: face:20, cone: face:18}``: a drilled hole's depth, from the
    plane to that circle's centre (:mod:`.drill_point`)."""

    type: Literal["distance"]
    faces: Annotated[list[Union[FeatureId, int, str, list[Union[FeatureId, int, str]],
                                DrillCircle]],
                     Field(min_length=2, max_length=2)]
    nominal: Optional[float] = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _circle_second(self):
        if isinstance(self.faces[0], DrillCircle):
            raise ValueError("a distance's first side is a plane; a drill point's circle "
                             "({cylinder, cone}) is its second side")
        return self


class Angle(_TwoPlanes):
    """The angle (degrees) between two planar faces' least-squares planes; ``nominal``
    (degrees, default the CAD's angle between the outward normals) may be that angle or its
    supplement (the drawing's side).  A side is a face or a list of coplanar faces (as for
    ``distance``)."""

    type: Literal["angle"]
    faces: Annotated[list[Union[FeatureId, int, str, list[Union[FeatureId, int, str]]]],
                     Field(min_length=2, max_length=2)]
    nominal: Optional[float] = Field(default=None, gt=0, lt=180)
