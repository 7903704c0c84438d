"""Feature control frames: a characteristic as the drawing writes it (ISO 1101 / ASME Y14.5).

:func:`frames` turns a characteristic (its result and, when there is one, its plan entry) into
one or more :class:`Frame`: a *geometric tolerance* is a row of compartments -- the symbol, the
zone (``Ø`` for a cylindrical zone, the material and zone modifiers Ⓜ Ⓛ Ⓕ Ⓟ Ⓣ Ⓤ, CZ ...) and
the datums in order with their modifiers; a *size* is a dimension, ``Ø20.000 +0.05/−0.05``.
A hole (diameter and position) gives both.

Everything follows the characteristic registry (:mod:`shapeverify.characteristics.registry`,
its ``symbol`` column): a type whose symbol is a geometric-tolerance symbol (:data:`SYMBOLS`)
becomes a frame, any other a dimension.  A row without a symbol takes its PMI's
(:data:`PMI_SYMBOLS`: ``ProfileOfLine`` -> ``⌒``), or, a zone width (``one_sided``), is framed
with its label in the symbol's place.  The zone is the plan entry's ``tol`` (the drawing's
value, not the bonus-enlarged limit of the result), ``Ø`` where its ``zone`` is ``diameter``,
Ⓜ/Ⓛ from ``material``, Ⓣ from ``tangent_plane``; the datums are the entry's ``datums`` (else
its PMI's, else the evaluated DRF's); the PMI's own modifiers (``pmi.modifiers``,
``pmi.zone_modifier``, ``pmi.datum_modifiers``) map through :data:`MODIFIERS`,
:data:`ZONE_MODIFIERS` and :data:`DATUM_MODIFIERS`.  A modifier not in those tables is written
by its name in brackets, never dropped.

Three renderings of the same :class:`Frame`: :attr:`Frame.text` (``⌖|Ø0.5Ⓜ|A|B|C``, the
terminal and the CSV), :func:`frame_html` (boxed compartments, the symbols as inline SVG so that
no font is needed) and :func:`draw_frame` (matplotlib: boxes, the symbols drawn as strokes).

A composite frame (``composite: upper | lower``, paired by :func:`composite_pairs`) is drawn
as ASME Y14.5 writes it: one symbol cell spanning two rows, the upper segment's zone and datums
in the top row, the lower's below, the columns aligned (:func:`composite_html`, a CSS grid;
:func:`draw_composite`); the reports keep a row of values and verdict per segment, the pair
together under the upper's DRF (:func:`group_by_drf`'s ``follows``).

Fonts: DejaVu Sans (matplotlib's, the PDF's) has ⏥ ⊥ ∥ ∠ ○ ↗ ◎ Ø but not ⌖ ⌓ ⌒ ⌭ ⌰ ⏤ ⌯ nor the
circled letters Ⓜ Ⓛ Ⓕ Ⓟ Ⓣ Ⓤ (checked with ``FT2Font.get_charmap``).  So the drawn forms never
rely on a font for them: each symbol of :data:`SYMBOLS` is drawn from :data:`STROKES` (lines in a
unit square) and a circled letter as a circle around the letter.  A symbol with no strokes is
written as text when the font has it, else as the standard's abbreviation
(:data:`SYMBOLS`, e.g. ``POS``) -- :func:`drawn_symbol` decides.
"""
from __future__ import annotations

import html as _html
import math
from dataclasses import dataclass

from ..characteristics import registry

__all__ = ["Frame", "frames", "fcf_text", "drf_key", "drf_title", "group_by_drf",
           "frame_html", "svg_symbol", "draw_frame", "frame_width", "drawn_symbol", "font_text",
           "SYMBOLS", "PMI_SYMBOLS", "STROKES", "MODIFIERS", "ZONE_MODIFIERS", "DATUM_MODIFIERS",
           "SIZE_SYMBOLS", "FCF_CSS", "composite_pairs", "composite_frames", "composite_html",
           "draw_composite", "composite_width"]

#: geometric-tolerance symbol -> (name, abbreviation written where no glyph can be drawn)
SYMBOLS: dict[str, tuple[str, str]] = {
    "⏤": ("straightness", "STR"),
    "⏥": ("flatness", "FLT"),
    "○": ("circularity", "CIR"),
    "⌭": ("cylindricity", "CYL"),
    "⌒": ("profile of a line", "PRL"),
    "⌓": ("profile of a surface", "PRS"),
    "∥": ("parallelism", "PAR"),
    "⊥": ("perpendicularity", "PER"),
    "∠": ("angularity", "ANG"),
    "⌖": ("position", "POS"),
    "◎": ("concentricity", "CON"),
    "⌯": ("symmetry", "SYM"),
    "↗": ("circular runout", "CRO"),
    "⌰": ("total runout", "TRO"),
}

#: OpenCASCADE's geometric tolerance types (``pmi.type``) -> symbol: a frame for a registry
#: row that has no symbol yet
PMI_SYMBOLS = {"Straightness": "⏤", "Flatness": "⏥", "CircularityOrRoundness": "○",
               "Cylindricity": "⌭", "ProfileOfLine": "⌒", "ProfileOfSurface": "⌓",
               "Parallelism": "∥", "Perpendicularity": "⊥", "Angularity": "∠",
               "Position": "⌖", "Concentricity": "◎", "Coaxiality": "◎", "Symmetry": "⌯",
               "CircularRunout": "↗", "TotalRunout": "⌰"}

#: a size's key in a compound result (a hole's ``diameter``) -> its symbol
SIZE_SYMBOLS = {"diameter": "Ø", "radius": "R", "width": "", "distance": ""}

#: tolerance modifiers (OpenCASCADE's ``XCAFDimTolObjects_GeomToleranceModif`` names, the
#: plan's ``pmi.modifiers``) -> ("circled", letter) | ("text", text) | ("note", text written
#: beside the frame: it belongs to the leader or under the frame)
MODIFIERS: dict[str, tuple[str, str]] = {
    "Free_State": ("circled", "F"),
    "Tangent_Plane": ("circled", "T"),
    "Maximum_Material_Requirement": ("circled", "M"),
    "Least_Material_Requirement": ("circled", "L"),
    "Reciprocity_Requirement": ("circled", "R"),
    "Statistical_Tolerance": ("text", "⟨ST⟩"),
    "Common_Zone": ("text", "CZ"),
    "Line_Element": ("text", "LE"),
    "Not_Convex": ("text", "NC"),
    "Any_Cross_Section": ("text", "ACS"),
    "Major_Diameter": ("text", "MD"),
    "Minor_Diameter": ("text", "LD"),
    "Pitch_Diameter": ("text", "PD"),
    "Each_Radial_Element": ("note", "each radial element"),
    "Separate_Requirement": ("note", "SEP REQT"),
    "All_Around": ("note", "all around"),
    "All_Over": ("note", "all over"),
}

#: zone modifiers (``pmi.zone_modifier``, with ``pmi.zone_modifier_value``): ("circled", letter)
ZONE_MODIFIERS: dict[str, tuple[str, str]] = {
    "Projected": ("circled", "P"),
    "NonUniform": ("circled", "U"),
    "NotUniform": ("circled", "U"),
}

#: datum modifiers (``XCAFDimTolObjects_DatumSingleModif`` names; ``pmi.datum_modifiers``:
#: ``{letter: [names]}``)
DATUM_MODIFIERS: dict[str, tuple[str, str]] = {
    "MaximumMaterialRequirement": ("circled", "M"),
    "LeastMaterialRequirement": ("circled", "L"),
    "FreeState": ("circled", "F"),
    "Translation": ("text", "▷"),
    "ContactingFeature": ("text", "CF"),
    "DistanceVariable": ("text", "DV"),
    "Point": ("text", "PT"),
    "Line": ("text", "SL"),
    "Plane": ("text", "PL"),
    "AnyCrossSection": ("text", "ACS"),
    "AnyLongitudinalSection": ("text", "ALS"),
    "MajorDiameter": ("text", "MD"),
    "MinorDiameter": ("text", "LD"),
    "PitchDiameter": ("text", "PD"),
}

_CIRCLED = {c: chr(0x24B6 + i) for i, c in enumerate("ABCDEFGHIJKLMNOPQRSTUVWXYZ")}


# ------------------------------------------------------------------------------ the model
@dataclass(frozen=True)
class Frame:
    """One feature control frame (or one size dimension) of a characteristic.

    Attributes
    ----------
    symbol : str
        The registry's symbol (``⌖``; ``Ø`` or ``""`` for a size).
    compartments : tuple of tuple of (kind, str)
        A tolerance: the symbol's, the zone's, one per datum.  A size: one, the dimension.
        Tokens: ``("symbol", "⌖")``, ``("text", "0.5")``, ``("circled", "M")``.
    datums : tuple of str
        The datum reference frame, primary first (``()``: none).
    notes : tuple of str
        What the drawing writes beside the frame (``all around``, ``SEP REQT``).
    part : str or None
        The key of a compound result this frame is of (a hole's ``diameter``/``position``).
    framed : bool or None
        A geometric tolerance drawn as a frame (None: when ``symbol`` is one of
        :data:`SYMBOLS`).
    """

    symbol: str
    compartments: tuple
    datums: tuple = ()
    notes: tuple = ()
    part: str | None = None
    framed: bool | None = None

    @property
    def is_tolerance(self) -> bool:
        """A geometric tolerance (framed), not a size."""
        return self.symbol in SYMBOLS if self.framed is None else self.framed

    @property
    def text(self) -> str:
        """``⌖|Ø0.5Ⓜ|A|B|C`` (compartments joined by ``|``); a size as its dimension."""
        comp = ["".join(_token_text(t) for t in c) for c in self.compartments]
        out = "|".join(comp) if self.is_tolerance else " ".join(comp)
        return out + "".join(f" ({n})" for n in self.notes)


def _token_text(tok) -> str:
    kind, val = tok
    return _CIRCLED.get(val, f"({val})") if kind == "circled" else val


def _num(v: float) -> str:
    """A tolerance as a drawing writes it: up to 4 decimals, no trailing zeros.

    >>> _num(0.38099999999999995), _num(0.05), _num(1.0), _num(0.0)
    ('0.381', '0.05', '1', '0')
    """
    text = f"{float(v):.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _nominal(v: float) -> str:
    """A nominal size to 3 decimals (4 where the 4th is not 0).

    >>> _nominal(20.0), _nominal(5.4102), _nominal(10.540999999999999)
    ('20.000', '5.4102', '10.541')
    """
    v = float(v)
    return f"{v:.3f}" if abs(v - round(v, 3)) < 5e-7 else f"{v:.4f}"


def _limits(lower: float, upper: float, unit: str = "") -> str:
    """``+0.05/−0.05`` (a zero limit as ``0``; U+2212 minus; ``unit`` after each number).

    >>> _limits(-0.05, 0.05), _limits(0.0, 0.2), _limits(-0.2, 0.0), _limits(-0.5, 0.5, "°")
    ('+0.05/−0.05', '+0.2/0', '0/−0.2', '+0.5°/−0.5°')
    """
    def one(x):
        s = _num(x)
        return "0" if s == "0" else (f"+{s}{unit}" if x > 0 else "−" + s.lstrip("-") + unit)
    return f"{one(upper)}/{one(lower)}"


def _get(obj, key, default=None):
    if obj is None:
        return default
    if isinstance(obj, dict):
        return obj.get(key, default)
    return getattr(obj, key, default)


def _pmi(entry) -> dict:
    p = _get(entry, "pmi")
    if p is None:
        return {}
    return dict(p) if isinstance(p, dict) else p.model_dump()


def _datums(entry, result) -> tuple:
    """The datum reference frame: the entry's ``datums``, else its PMI's, else the DRF the
    result was evaluated in (``details['drf']``)."""
    d = _get(entry, "datums")
    if d:
        return tuple(str(x) for x in d)
    p = _pmi(entry).get("datums")
    if p:
        return tuple(p.split("|")) if isinstance(p, str) else tuple(map(str, p))
    drf = (_get(result, "details") or {}).get("drf") or {}
    names = drf.get("datums")
    return tuple(names.split("|")) if names else ()


def _default_zone(type_name) -> str:
    """The zone a type's plan entry has by default (its schema's ``zone``: ``diameter`` for a
    position, also a hole's), "" when it has none."""
    try:
        field = registry.by_name(str(type_name)).schema.model_fields.get("zone")
    except (KeyError, AttributeError):
        return ""
    return field.default if field is not None and isinstance(field.default, str) else ""


def _modifier(table, name) -> tuple:
    """A modifier's token, or ``("text", "[name]")`` for one not in ``table``."""
    return table.get(name, ("text", f"[{name}]"))


def _tolerance_frame(symbol, entry, result, part=None, tol=None) -> Frame:
    pmi = _pmi(entry)
    if tol is None:
        tol = _get(entry, "tol")
    zone: list = []
    unequal = None
    if tol is None:                       # a profile given by lower/upper, or no plan entry
        lo, hi = _get(entry, "lower"), _get(entry, "upper")
        if lo is not None and hi is not None:
            tol = float(hi) - float(lo)
            if abs(float(hi) + float(lo)) > 1e-12:
                unequal = float(hi)        # the zone's part outside the material (Ⓤ)
        else:
            up = _get(result, "upper")
            if isinstance(up, dict):
                up = up.get(part) if part else None
            tol = up
    zone_kind = str(_get(entry, "zone", "") or pmi.get("zone", "")
                    or _default_zone(part or _get(entry, "type") or _get(result, "type"))).lower()
    if zone_kind in ("diameter",):
        zone.append(("text", "Ø"))
    elif zone_kind in ("sphericaldiameter", "spherical_diameter", "sphere"):
        zone.append(("text", "SØ"))
    zone.append(("text", "–" if tol is None else _num(tol)))
    tokens, notes = [], []
    mods = list(pmi.get("modifiers") or [])
    mat = _get(entry, "material") or pmi.get("material")
    if mat:
        mods.insert(0, {"M": "Maximum_Material_Requirement",
                        "L": "Least_Material_Requirement"}.get(str(mat), str(mat)))
    if _get(entry, "tangent_plane"):
        mods.append("Tangent_Plane")
    zm = pmi.get("zone_modifier")
    if zm and zm != "None":
        kind, val = _modifier(ZONE_MODIFIERS, zm)
        tokens.append((kind, val))
        zv = pmi.get("zone_modifier_value")
        if zv:
            tokens.append(("text", _num(zv)))
    if unequal is not None:
        tokens += [("circled", "U"), ("text", _num(unequal))]
    seen = set()
    for m in mods:
        if m in seen:
            continue
        seen.add(m)
        kind, val = _modifier(MODIFIERS, m)
        if kind == "note":
            notes.append(val)
        else:
            tokens.append((kind, val))
    zone += tokens
    datums = _datums(entry, result)
    dmods = pmi.get("datum_modifiers") or {}
    comps = [(("symbol", symbol),), tuple(zone)]
    for d in datums:
        comps.append((("text", d),) + tuple(_modifier(DATUM_MODIFIERS, m)
                                             for m in dmods.get(d, ())))
    return Frame(symbol, tuple(comps), datums, tuple(notes), part, True)


def _size_frame(symbol, entry, result, part=None, unit="") -> Frame:
    """A size's frame: the nominal and its limits (``unit``: "°" after an angle's numbers)."""
    pmi = _pmi(entry)
    nom, lo, hi = (_get(result, k) for k in ("nominal", "lower", "upper"))
    if part is not None:
        nom, lo, hi = (x.get(part) if isinstance(x, dict) else None for x in (nom, lo, hi))
    # the plan's limits: a part's (a hole's diameter), a size's own (a cylinder's diameter,
    # a width's lower/upper); the result's where the plan gives none
    sub = _get(entry, part or "diameter")
    for src in (sub, None if part else entry):
        if src is None:
            continue
        if _get(src, "lower") is not None and _get(src, "upper") is not None:
            lo, hi = _get(src, "lower"), _get(src, "upper")
            break
        if isinstance(_get(src, "tol"), (int, float)):
            lo, hi = -float(_get(src, "tol")), float(_get(src, "tol"))
            break
    if pmi.get("kind") == "dimension" and pmi.get("nominal") is not None:
        nom = pmi["nominal"]                             # the drawing's size
    text = symbol
    if nom is not None and float(nom) != 0.0:
        text += _nominal(nom) + unit
    if lo is not None and hi is not None:
        text += (" " if text else "") + _limits(float(lo), float(hi), unit)
    return Frame(symbol, ((("text", text or "–"),),), (), (), part)


def _type_names() -> set:
    return {t.name for t in registry.TYPES} | set(getattr(registry, "_BY_NAME", {}))


def _parts_of(ctype, entry) -> list:
    """The parts of a compound type's entry (a hole: ``diameter`` and/or ``position``): its
    schema's fields named after a registered type or a size (:data:`SIZE_SYMBOLS`), when it
    has two or more; ``[]`` for a simple type (a cylinder's one ``diameter``)."""
    if entry is None:
        return []
    try:
        fields = registry.by_name(str(ctype)).schema.model_fields
    except (KeyError, AttributeError):
        return []
    names = [k for k in fields if k in _type_names() or k in SIZE_SYMBOLS]
    return [k for k in names if _get(entry, k) is not None] if len(names) >= 2 else []


def frames(result, entry=None) -> tuple:
    """The feature control frames of one characteristic.

    Parameters
    ----------
    result : CharacteristicResult or dict
        Its ``type``, ``nominal``, ``lower``, ``upper`` (a compound result -- a hole -- has
        dicts keyed ``diameter``/``position``) and ``details`` (the DRF it was evaluated in).
    entry : plan characteristic (pydantic model) or dict, optional
        Its plan entry (zone, material, datums, PMI modifiers); without one the frame is
        made from the result alone (zone = the result's upper limit).

    Returns
    -------
    tuple of Frame
        One per tolerance or size (a hole: diameter, then position).

    Raises
    ------
    KeyError
        The result has no ``type``.
    """
    ctype = _get(result, "type")
    if ctype is None:
        ctype = _get(entry, "type")
    if ctype is None:
        raise KeyError("a characteristic result needs its 'type' to make its frame")
    up = _get(result, "upper")
    keys = list(up) if isinstance(up, dict) else [] if up is not None else \
        _parts_of(ctype, entry)                        # not measured: the entry's parts
    if keys:
        out = []
        for k in keys:
            sym = registry.symbol(k) if k in _type_names() else SIZE_SYMBOLS.get(k, "")
            if sym in SYMBOLS:
                sub = _get(entry, k)
                out.append(_tolerance_frame(sym, entry, result, k, _get(sub, "tol")))
            else:
                out.append(_size_frame(sym, entry, result, k))
        return tuple(out)
    sym = registry.symbol(str(ctype))
    if not sym:                     # a row without its symbol yet: the PMI's, or its label
        pmi = _pmi(entry)
        sym = PMI_SYMBOLS.get(str(pmi.get("type")), "") \
            if pmi.get("kind") == "geometric_tolerance" else ""
        if not sym and str(ctype) in registry.one_sided_types():
            sym = registry.label(str(ctype))
    if sym in SYMBOLS or str(ctype) in registry.one_sided_types():
        return (_tolerance_frame(sym, entry, result),)
    deg = str(ctype) in _type_names() and registry.by_name(str(ctype)).unit == "deg"
    if str(ctype) == "feature_size" and entry is not None:     # R, Ø, SR, SØ from the entry
        sym = ("S" if _get(entry, "shape") == "sphere" else "") + \
            SIZE_SYMBOLS.get(str(_get(entry, "size")), "")
    return (_size_frame(sym, entry, result, unit="°" if deg else ""),)


def fcf_text(result, entry=None, part: str | None = None) -> str:
    """The frames of a characteristic as text, ``; ``-separated (``part``: only that key's of
    a compound result, e.g. a hole's ``"position"``).

    >>> fcf_text({"type": "position", "upper": 0.5}, {"type": "position", "tol": 0.5,
    ...           "zone": "diameter", "material": "M", "datums": ["A", "B", "C"]})
    '⌖|Ø0.5Ⓜ|A|B|C'
    >>> fcf_text({"type": "cylinder", "nominal": 20.0, "lower": -0.05, "upper": 0.05})
    'Ø20.000 +0.05/−0.05'
    """
    fs = frames(result, entry)
    if part is not None:
        fs = tuple(f for f in fs if f.part == part) or fs
    return "; ".join(f.text for f in fs)


def drf_key(fs) -> tuple:
    """The datum reference frame a characteristic is grouped under: its first frame's with
    datums (``()``: none)."""
    for f in fs:
        if f.datums:
            return f.datums
    return ()


def group_by_drf(items, key=lambda x: x[1], follows: dict | None = None,
                 name=lambda x: x[0]) -> list:
    """``[(datums, [item, ...]), ...]``: the items grouped by :func:`drf_key` of ``key(item)``
    (their frames), each DRF in the order it first appears, those without datums last; the
    items keep their order within a group.

    ``follows``: ``{lower name: upper name}`` (:func:`composite_pairs`, names by
    ``name(item)``): the lower segment of a composite frame goes right after its upper, in the
    upper's group (its own datums only orient it), when the upper is among the items."""
    follows = follows or {}
    names = {name(it) for it in items}
    after: dict = {}
    for it in items:
        up = follows.get(name(it))
        if up is not None and up in names and up != name(it):
            after.setdefault(up, []).append(it)
    moved = {id(x) for v in after.values() for x in v}
    groups: dict = {}
    for it in items:
        if id(it) in moved:
            continue
        g = groups.setdefault(drf_key(key(it)), [])
        g.append(it)
        g += after.get(name(it), [])
    none = groups.pop((), None)
    out = list(groups.items())
    if none is not None:
        out.append(((), none))
    return out


def drf_title(datums) -> str:
    """``"DRF A|B|C"``, or ``"without datums"``."""
    return f"DRF {'|'.join(datums)}" if datums else "without datums"


# ------------------------------------------------------------------------------ composite
def composite_pairs(entries) -> dict:
    """``{lower name: upper name}``: the two segments of each composite feature control frame
    among the plan's ``entries`` (``composite: upper | lower``).  A lower segment's upper is
    the entry whose PMI is the one its ``pmi.composite.with`` names (``shapeverify plan``,
    :mod:`shapeverify.cad.step_composite`); without that link (a hand-written plan), the
    nearest unpaired upper of the same type before it.  Each upper pairs with one lower."""
    entries = list(entries or ())
    ups = [e for e in entries if _get(e, "composite") == "upper"]
    used: set = set()
    out: dict = {}
    for i, lo in enumerate(entries):
        if _get(lo, "composite") != "lower":
            continue
        link = (_pmi(lo).get("composite") or {})
        other = link.get("with") if isinstance(link, dict) else None
        cands = [u for u in ups if other is not None and _pmi(u).get("id") == other] \
            if other is not None else []
        if not cands:
            cands = [u for u in reversed(entries[:i]) if _get(u, "composite") == "upper"
                     and _get(u, "type") == _get(lo, "type")
                     and (_pmi(u).get("composite") or {}).get("with") in (None, _pmi(lo).get("id"))]
        for u in cands:
            if id(u) not in used:
                used.add(id(u))
                out[str(_get(lo, "name"))] = str(_get(u, "name"))
                break
    return out


def composite_frames(upper_frames, lower_frames):
    """``(upper, lower)``: the two frames drawn as one composite frame, or None when the two
    segments are not one tolerance frame each of the same symbol (then each is drawn alone)."""
    if len(upper_frames) != 1 or len(lower_frames) != 1:
        return None
    u, lo = upper_frames[0], lower_frames[0]
    if not (u.is_tolerance and lo.is_tolerance and u.symbol == lo.symbol):
        return None
    return u, lo



# ------------------------------------------------------------------------------ strokes
def _arc(cx, cy, r, a0, a1, n=24):
    return [(cx + r * math.cos(math.radians(a0 + (a1 - a0) * i / n)),
             cy + r * math.sin(math.radians(a0 + (a1 - a0) * i / n))) for i in range(n + 1)]


def _arrow(x0, y0, x1, y1, head=0.22):
    """A line (x0, y0) -> (x1, y1) and its filled head."""
    dx, dy = x1 - x0, y1 - y0
    L = math.hypot(dx, dy)
    ux, uy = dx / L, dy / L
    bx, by = x1 - head * ux, y1 - head * uy
    w = 0.4 * head
    return [([(x0, y0), (bx, by)], False, False),
            ([(x1, y1), (bx - w * uy, by + w * ux), (bx + w * uy, by - w * ux)], True, True)]


def _cyl():
    a = math.radians(60)
    d, n, r = (math.cos(a), math.sin(a)), (-math.sin(a), math.cos(a)), 0.3
    lines = []
    for s in (1, -1):
        cx, cy = 0.5 + s * r * n[0], 0.5 + s * r * n[1]
        lines.append(([(cx - 0.48 * d[0], cy - 0.48 * d[1]), (cx + 0.48 * d[0], cy + 0.48 * d[1])],
                      False, False))
    return [(_arc(0.5, 0.5, r, 0, 360, 36), True, False)] + lines


#: symbol -> strokes in the unit square (y up): ``(points, closed, filled)``; drawn by
#: :func:`draw_frame` and :func:`svg_symbol` alike, so no font needs the symbol
STROKES: dict[str, list] = {
    "⏤": [([(0.08, 0.5), (0.92, 0.5)], False, False)],
    "⏥": [([(0.08, 0.28), (0.68, 0.28), (0.92, 0.72), (0.32, 0.72)], True, False)],
    "○": [(_arc(0.5, 0.5, 0.38, 0, 360, 36), True, False)],
    "⌭": _cyl(),
    "⌒": [(_arc(0.5, 0.25, 0.42, 0, 180), False, False)],
    "⌓": [(_arc(0.5, 0.25, 0.42, 0, 180), True, False)],
    "∥": [([(0.22, 0.1), (0.52, 0.9)], False, False), ([(0.48, 0.1), (0.78, 0.9)], False, False)],
    "⊥": [([(0.08, 0.12), (0.92, 0.12)], False, False), ([(0.5, 0.12), (0.5, 0.9)], False, False)],
    "∠": [([(0.08, 0.12), (0.92, 0.12)], False, False), ([(0.08, 0.12), (0.85, 0.72)], False, False)],
    "⌖": [(_arc(0.5, 0.5, 0.28, 0, 360, 36), True, False),
          ([(0.05, 0.5), (0.95, 0.5)], False, False), ([(0.5, 0.05), (0.5, 0.95)], False, False)],
    "◎": [(_arc(0.5, 0.5, 0.4, 0, 360, 36), True, False),
          (_arc(0.5, 0.5, 0.2, 0, 360, 36), True, False)],
    "⌯": [([(0.25, 0.25), (0.75, 0.25)], False, False), ([(0.05, 0.5), (0.95, 0.5)], False, False),
          ([(0.25, 0.75), (0.75, 0.75)], False, False)],
    "↗": _arrow(0.2, 0.1, 0.8, 0.9),
    "⌰": (_arrow(0.12, 0.1, 0.5, 0.9) + _arrow(0.5, 0.1, 0.88, 0.9)
          + [([(0.12, 0.1), (0.5, 0.1)], False, False)]),
}


def svg_symbol(symbol: str, size: float = 12.0) -> str:
    """The symbol as an inline ``<svg>`` (its strokes; ``role=img`` and the Unicode symbol as
    its label), or the symbol as text when it has no strokes."""
    strokes = STROKES.get(symbol)
    if not strokes:
        return _html.escape(symbol)
    paths = []
    for pts, closed, filled in strokes:
        d = "M" + " L".join(f"{x:.3f},{1 - y:.3f}" for x, y in pts) + (" Z" if closed else "")
        paths.append(f'<path d="{d}" fill="{"currentColor" if filled else "none"}"/>')
    name = SYMBOLS.get(symbol, (symbol, ""))[0]
    return (f'<svg class="fcf-sym" role="img" aria-label="{_html.escape(symbol)} {name}" '
            f'width="{size:g}" height="{size:g}" viewBox="-0.05 -0.05 1.1 1.1" '
            f'stroke="currentColor" stroke-width="0.09" stroke-linejoin="round">'
            f'<title>{_html.escape(symbol)} {name}</title>{"".join(paths)}</svg>')



# ------------------------------------------------------------------------------ HTML
#: the frames' CSS (boxes: compartments with borders; circled letters)
FCF_CSS = """
.fcf{display:inline-flex;border:1px solid #1d1d1f;font-family:DejaVu Sans,Arial,sans-serif;
font-size:13px;line-height:18px;vertical-align:middle;white-space:nowrap;margin:1px 0}
.fcf>span{padding:0 5px;border-left:1px solid #1d1d1f;display:inline-flex;align-items:center}
.fcf>span:first-child{border-left:none}
.fcf-c{display:inline-block;border:1px solid currentColor;border-radius:50%;width:13px;
height:13px;line-height:13px;font-size:9px;text-align:center;margin:0 1px}
.fcf-comp{display:inline-grid;font-family:DejaVu Sans,Arial,sans-serif;font-size:13px;
line-height:18px;vertical-align:middle;white-space:nowrap;margin:1px 0}
.fcf-comp>span{padding:0 5px;display:inline-flex;align-items:center;
border-right:1px solid #1d1d1f;border-bottom:1px solid #1d1d1f}
.fcf-comp>span.fcf-r1{border-top:1px solid #1d1d1f}
.fcf-comp>span.fcf-symcell{border:1px solid #1d1d1f;justify-content:center}
.fcf-comp>span.fcf-empty{border:none}
.fcf-dim{white-space:nowrap}
.fcf-note{color:#555;font-size:12px;white-space:nowrap}
"""


def _token_html(tok) -> str:
    kind, val = tok
    if kind == "symbol":
        return svg_symbol(val)
    if kind == "circled":
        return f'<span class="fcf-c" title="{_html.escape(_token_text(tok))}">{_html.escape(val)}</span>'
    return _html.escape(val)


def frame_html(frame: Frame) -> str:
    """One frame as HTML: a box of compartments (a tolerance) or the dimension's text; the
    frame's text (:attr:`Frame.text`) in ``data-fcf``."""
    notes = "".join(f' <span class="fcf-note">{_html.escape(n)}</span>' for n in frame.notes)
    if not frame.is_tolerance:
        return (f'<span class="fcf-dim" data-fcf="{_html.escape(frame.text)}">'
                + "".join(_token_html(t) for c in frame.compartments for t in c)
                + "</span>" + notes)
    comps = "".join("<span>" + "".join(_token_html(t) for t in c) + "</span>"
                    for c in frame.compartments)
    return f'<span class="fcf" data-fcf="{_html.escape(frame.text)}">{comps}</span>{notes}'


def composite_html(upper: Frame, lower: Frame) -> str:
    """A composite frame as ASME Y14.5 draws it: one symbol cell spanning two rows, the upper
    segment's zone and datums in the first row, the lower's below, column by column (a CSS
    grid; the symbol cell ``grid-row:1 / span 2``).  Each row's text in ``data-fcf-upper`` /
    ``data-fcf-lower``; ``data-fcf`` is both, `` / ``-joined."""
    n = max(len(upper.compartments), len(lower.compartments))
    cells = ['<span class="fcf-symcell" style="grid-column:1;grid-row:1 / span 2">'
             + "".join(_token_html(t) for t in upper.compartments[0]) + "</span>"]
    for row, f in ((1, upper), (2, lower)):
        for j in range(1, n):
            cls = f"fcf-r{row}"           # each cell its own borders: the lower row's
            if j < len(f.compartments):   # outline steps in where it has fewer datums
                body = "".join(_token_html(t) for t in f.compartments[j])
            else:
                body, cls = "", "fcf-empty"
            cells.append(f'<span class="{cls}" style="grid-column:{j + 1};grid-row:{row}">'
                         f"{body}</span>")
    notes = "".join(f' <span class="fcf-note">{_html.escape(x)}</span>'
                    for x in upper.notes + lower.notes)
    return (f'<span class="fcf-comp" data-fcf="{_html.escape(upper.text + " / " + lower.text)}"'
            f' data-fcf-upper="{_html.escape(upper.text)}"'
            f' data-fcf-lower="{_html.escape(lower.text)}">{"".join(cells)}</span>{notes}')


# ------------------------------------------------------------------------------ matplotlib
_FONT_CHARS: dict = {}


def _font_has(ch: str) -> bool:
    """Whether matplotlib's default font (DejaVu Sans) has the glyph ``ch``."""
    if "cmap" not in _FONT_CHARS:
        from matplotlib import font_manager
        from matplotlib.ft2font import FT2Font

        path = font_manager.findfont(font_manager.FontProperties(family="DejaVu Sans"))
        _FONT_CHARS["cmap"] = set(FT2Font(path).get_charmap())
    return all(ord(c) in _FONT_CHARS["cmap"] for c in ch)


def drawn_symbol(symbol: str) -> tuple[str, str]:
    """How :func:`draw_frame` writes ``symbol``: ``("strokes", symbol)`` when
    :data:`STROKES` has it, ``("text", symbol)`` when the font has it, else ``("text",
    abbreviation)`` (:data:`SYMBOLS`; the font lacks the glyph)."""
    if symbol in STROKES:
        return "strokes", symbol
    if _font_has(symbol):
        return "text", symbol
    return "text", SYMBOLS.get(symbol, (symbol, symbol))[1]


_UNCIRCLED = {v: k for k, v in _CIRCLED.items()}


def font_text(text: str) -> str:
    """``text`` in characters matplotlib's font has: a symbol it lacks becomes the standard's
    abbreviation (:data:`SYMBOLS`), a circled letter ``(M)``, anything else ``?``.

    >>> font_text("⌖|Ø0.5Ⓜ|A")
    'POS|Ø0.5(M)|A'
    """
    def one(c):
        if _font_has(c):
            return c
        if c in _UNCIRCLED:
            return f"({_UNCIRCLED[c]})"
        return SYMBOLS.get(c, ("", "?"))[1]
    return "".join(one(c) for c in text)



def draw_frame(fig, frame: Frame, x: float, y: float, *, height: float = 11.0,
               fontsize: float = 8.0, gid: str | None = None,
               min_widths: tuple | None = None) -> float:
    """Draw one frame on ``fig`` with its lower left corner at ``(x, y)`` (points from the
    figure's lower left), ``height`` points high; returns its width in points
    (``min_widths``: each compartment at least that wide, points: a composite frame's columns).

    The compartments are boxes; a symbol is drawn from its strokes, a circled letter as a circle
    around the letter; texts are figure texts (so the page's text can be read back).  Every
    artist gets ``gid`` (default ``"fcf"``).  Positions are in inches
    (``fig.dpi_scale_trans``), so the frame stays in place at any output resolution.
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Polygon, Rectangle

    renderer = fig.canvas.get_renderer()
    inch = fig.dpi_scale_trans
    k = 1.0 / 72.0                                   # points -> inches
    gid = gid or "fcf"
    pad = 2.5
    artists = []

    def text(px, s, size, **kw):
        t = fig.text(px * k, (y + height / 2) * k, s, fontsize=size, transform=inch,
                     va="center_baseline", gid=gid, **kw)
        return t.get_window_extent(renderer).width * 72.0 / fig.dpi

    def place(obj):
        obj.set_gid(gid)
        obj.set_transform(inch)
        artists.append(obj)

    cx = x
    sym_h = 0.72 * height
    for ci, comp in enumerate(frame.compartments):
        start = cx
        cx += pad
        for kind, val in comp:
            if kind == "symbol":
                how, val = drawn_symbol(val)
                if how == "strokes":
                    x0, y0 = cx, y + (height - sym_h) / 2
                    for pts, closed, filled in STROKES[val]:
                        xy = [((x0 + sym_h * a) * k, (y0 + sym_h * b) * k) for a, b in pts]
                        if closed or filled:
                            place(Polygon(xy, closed=True, fill=filled, facecolor="black",
                                          edgecolor="black", lw=0.8))
                        else:
                            place(Line2D([q[0] for q in xy], [q[1] for q in xy],
                                         color="black", lw=0.8, solid_capstyle="butt"))
                    cx += sym_h
                    continue
            if kind == "circled":
                r = 0.36 * height
                place(Circle(((cx + r) * k, (y + height / 2) * k), r * k, fill=False,
                             edgecolor="black", lw=0.7))
                text(cx + r, val, 0.62 * fontsize, ha="center")
                cx += 2 * r + 1.0
                continue
            cx += text(cx, font_text(val), fontsize)
        cx += pad
        if min_widths is not None and ci < len(min_widths):
            cx = max(cx, start + min_widths[ci])
        if frame.is_tolerance:
            place(Rectangle((start * k, y * k), (cx - start) * k, height * k, fill=False,
                            edgecolor="black", lw=0.8))
    for a in artists:
        fig.add_artist(a)
    if frame.notes:
        cx += 2 + text(cx + 2, " ".join(frame.notes), 0.8 * fontsize, color="#555555")
    return cx - x


def frame_width(fig, frame: Frame, *, height: float = 11.0, fontsize: float = 8.0) -> float:
    """The width (points) :func:`draw_frame` takes for ``frame`` (drawn and removed)."""
    n_texts, n_artists = len(fig.texts), len(fig.artists)
    w = draw_frame(fig, frame, 0.0, 0.0, height=height, fontsize=fontsize, gid="_measure")
    for a in list(fig.texts[n_texts:]) + list(fig.artists[n_artists:]):
        a.remove()
    return w



def _column_widths(fig, frame: Frame, height: float, fontsize: float) -> list:
    """Each compartment's width (points) as :func:`draw_frame` draws it alone."""
    return [frame_width(fig, Frame(frame.symbol, (c,), framed=True), height=height,
                        fontsize=fontsize) for c in frame.compartments]


def draw_composite(fig, upper: Frame, lower: Frame, x: float, y: float, *,
                   height: float = 11.0, fontsize: float = 8.0, gid: str | None = None,
                   gids: tuple | None = None) -> float:
    """Draw a composite frame (ASME Y14.5): one symbol cell ``2 * height`` high at the left,
    the upper segment's compartments in the top row (lower edge at ``y + height``), the
    lower's in the bottom row (lower edge at ``y``), the columns as wide as the wider row's;
    returns the width in points.  ``gids``: the two rows' gids (default ``gid``); the symbol
    cell takes the upper's."""
    from matplotlib.patches import Rectangle

    gu, gl = gids or (gid or "fcf", gid or "fcf")
    wu = _column_widths(fig, upper, height, fontsize)
    wl = _column_widths(fig, lower, height, fontsize)
    n = max(len(wu), len(wl))
    cols = [max(wu[j] if j < len(wu) else 0.0, wl[j] if j < len(wl) else 0.0)
            for j in range(n)]
    k = 1.0 / 72.0
    # the symbol, centred in its cell of two rows (drawn unboxed, then boxed 2 rows high)
    sym = Frame(upper.symbol, (upper.compartments[0],), framed=False)
    draw_frame(fig, sym, x + (cols[0] - wu[0]) / 2, y + height / 2, height=height,
               fontsize=fontsize, gid=gu)
    box = Rectangle((x * k, y * k), cols[0] * k, 2 * height * k, fill=False,
                    edgecolor="black", lw=0.8, gid=gu, transform=fig.dpi_scale_trans)
    fig.add_artist(box)
    w = cols[0]
    for f, yy, g in ((upper, y + height, gu), (lower, y, gl)):
        rest = Frame(f.symbol, f.compartments[1:], f.datums, f.notes, f.part, True)
        w = max(w, cols[0] + draw_frame(fig, rest, x + cols[0], yy, height=height,
                                        fontsize=fontsize, gid=g, min_widths=cols[1:]))
    return w


def composite_width(fig, upper: Frame, lower: Frame, *, height: float = 11.0,
                    fontsize: float = 8.0) -> float:
    """The width (points) :func:`draw_composite` takes (drawn and removed)."""
    n_texts, n_artists = len(fig.texts), len(fig.artists)
    w = draw_composite(fig, upper, lower, 0.0, 0.0, height=height, fontsize=fontsize,
                       gid="_measure")
    for a in list(fig.texts[n_texts:]) + list(fig.artists[n_artists:]):
        a.remove()
    return w
