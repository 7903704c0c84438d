"""Feature control frames in a characteristic's history (issue 28 item 4): what
``shapeverify history --characteristic NAME`` shows above and beside its Cp/Cpk table.

Each stored value keeps the frame it was inspected against (``fcf`` column of the
``characteristics`` table, :mod:`shapeverify.characteristics.spc`); a series is shown with its
latest frame, and a frame that changed during the history (a revised drawing) is said so with
the earlier ones, since Cp/Cpk then mixes values judged against different zones.
"""
from __future__ import annotations

__all__ = ["series_frames", "frame_header", "series_unit", "characteristic_listing"]

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


def characteristic_listing(db, part: str | None = None, inspections=None) -> list[dict]:
    """The characteristic series a history holds, for ``shapeverify history``'s listing:
    ``[{"name", "type", "n", "frame", "verdict", "lower", "upper", "unit", "frames"}, ...]``
    (sorted by name; ``frame``/``verdict``/limits the latest value's).

    Parameters
    ----------
    db : path
        The SQLite history; read only (a history without characteristics gives ``[]`` and is
        left unchanged).
    part : str, optional
        Only this part's values.
    inspections : collection of int, optional
        Only the values of these inspection rows (the ones the listing shows).
    """
    import sqlite3
    from pathlib import Path

    path = Path(getattr(db, "path", db))
    if not path.exists():
        return []
    try:
        con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True, timeout=30.0)
    except sqlite3.Error:
        return []
    try:
        con.row_factory = sqlite3.Row
        have = con.execute("SELECT name FROM sqlite_master WHERE type = 'table' AND "
                           "name = 'characteristics'").fetchone()
        if have is None:
            return []
        cols = {r[1] for r in con.execute("PRAGMA table_info(characteristics)")}
        sql = ("SELECT id, inspection_id, part, name, type, lower, upper, verdict"
               + (", fcf" if "fcf" in cols else "") + " FROM characteristics")
        args: list = []
        if part is not None:
            sql += " WHERE part = ?"
            args.append(part)
        rows = [dict(r) for r in con.execute(sql + " ORDER BY id", args)]
    except sqlite3.DatabaseError:
        return []
    finally:
        con.close()
    if inspections is not None:
        keep = set(inspections)
        rows = [r for r in rows if r["inspection_id"] in keep]
    frames = series_frames(rows)
    out = []
    for name in sorted(frames):
        rs = [r for r in rows if r["name"] == name]
        last = rs[-1]
        fs = frames[name]
        out.append({"name": name, "type": last["type"], "n": len(rs),
                    "frame": fs[-1] if fs else _NO_FRAME, "frames": fs,
                    "verdict": last["verdict"], "lower": last["lower"], "upper": last["upper"],
                    "unit": series_unit(rs)})
    return out
