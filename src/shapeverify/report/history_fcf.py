"""Feature control frames in a characteristic's history (issue 28 item 4): what
``shapeverify history --characteristic NAME`` shows above and beside its Cp/Cpk table.

Each stored value keeps the frame it was inspected against (``fcf`` column of the
``characteristics`` table, :mod:`shapeverify.characteristics.spc`); a series is shown with its
latest frame, and a frame that changed during the history (a revised drawing) is said so with
the earlier ones, since Cp/Cpk then mixes values judged against different zones.
"""
from __future__ import annotations

__all__ = ["series_frames", "frame_header", "series_unit"]

_NO_FRAME = "–"


def series_frames(rows) -> dict[str, list[str]]:
    """``{series name: [frame texts, oldest first]}``: the distinct frames each series was
    stored with (rows oldest first; a row stored before the frames, ``fcf`` empty, is
    skipped)."""
    out: dict[str, list[str]] = {}
    for r in rows:
        fs = out.setdefault(str(r["name"]), [])
        f = r.get("fcf")
        if f and f not in fs:
            fs.append(f)
    return out


def frame_header(characteristic: str, rows) -> str:
    """One line naming the characteristic's frame(s): ``H2  Ø9.000 +0.4/−0.4; ⌖|Ø1.6``
    (each series' latest; ``–`` when the history predates the frames)."""
    latest = []
    for name in sorted({str(r["name"]) for r in rows}):
        f = next((r.get("fcf") for r in reversed(rows) if r["name"] == name and r.get("fcf")),
                 None)
        if f and f not in latest:
            latest.append(f)
    return f"{characteristic}  frame: {'; '.join(latest) if latest else _NO_FRAME}"


def series_unit(rows) -> str:
    """The unit of a series' values: ``mm``, or ``°`` for an angle (the registry's ``unit``
    of the row's type; a hole's series types are ``hole diameter``/``hole position``)."""
    from ..characteristics import registry

    for r in rows:
        t = str(r.get("type") or "").split(" ")[0]
        try:
            if registry.by_name(t).unit == "deg":
                return "°"
        except KeyError:
            continue
    return "mm"
