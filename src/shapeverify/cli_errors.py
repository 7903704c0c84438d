"""How the command line words the errors it shows: file-system errors with the file and what to
do, terminal-safe file names, and the command-line form of the library's advice.

The library's messages speak Python (``init='principal-axes'``, "multiply its coordinates by
1000"); on the command line the same fix is an option (``--init principal-axes``,
``--scan-unit m``), and :func:`cli_hint` says so.

>>> clean("scan\\udcff.ply")
'scan\\\\xff.ply'
>>> os_error_message(IsADirectoryError(21, "Is a directory", "out"))
'out: is a directory; give a file name'
"""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path

__all__ = ["clean", "os_error_message", "cli_hint", "size_note"]


def clean(text) -> str:
    """``text`` printable on any terminal: the bytes of a non-UTF-8 file name (decoded by Python
    as surrogates) shown as ``\\xNN`` escapes instead of failing to print."""
    text = str(text)
    try:
        raw = text.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:
        return text.encode("utf-8", "backslashreplace").decode("utf-8")
    return raw.decode("utf-8", "backslashreplace")


def os_error_message(exc: OSError) -> str:
    """One line for a file-system error: the file, what is wrong, what to do."""
    if exc.filename is None:
        return clean(exc)
    name = clean(os.fsdecode(exc.filename))
    if exc.strerror and str(exc.strerror).startswith(name):   # shapeverify's own wording
        return clean(exc.strerror)
    if isinstance(exc, FileNotFoundError):
        parent = Path(os.fsdecode(exc.filename)).parent
        if not parent.exists():
            return (f"{name}: the folder {clean(parent)} does not exist; create it or give "
                    "another path")
        return f"{name}: no such file"
    if isinstance(exc, IsADirectoryError):
        return f"{name}: is a directory; give a file name"
    if isinstance(exc, NotADirectoryError):
        return f"{name}: a part of the path is a file, not a folder"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return (f"{name}: permission denied; give a path you may read/write, or change the "
                "file's permissions")
    if exc.errno == errno.EROFS:
        return f"{name}: the file system is read-only; write the output to another folder"
    if exc.errno == errno.ENOSPC:
        return f"{name}: no space left on the device; free some space or write elsewhere"
    return f"{name}: {clean(exc.strerror or exc)}"


_MIXUP_UNITS = {"metres": "m", "inches": "in", "centimetres": "cm", "micrometres": "um"}


def cli_hint(message: str, scan_unit: str | None = None) -> str:
    """The command-line form of the fix a library message suggests (``""`` when none), to be
    appended to ``message``.

    >>> cli_hint("scale mismatch: ...; the scan seems to be in metres: multiply ...")
    '; on the command line: --scan-unit m'
    >>> cli_hint("... give a better init (e.g. init='principal-axes') or check the model")[:40]
    '; on the command line: --init principal-'
    """
    if message.startswith("scale mismatch"):
        if scan_unit not in (None, "mm"):
            return (f"; the scan was read in {scan_unit} (--scan-unit {scan_unit}): check that "
                    "option")
        m = re.search(r"seems to be in (\w+)", message)
        if m and m.group(1) in _MIXUP_UNITS:
            return f"; on the command line: --scan-unit {_MIXUP_UNITS[m.group(1)]}"
        return ("; on the command line, --scan-unit (and --model-unit for a mesh or point-cloud "
                "model) give the units of files that carry none")
    if "init=" in message:
        return ("; on the command line: --init principal-axes, --init global (search), or "
                "--init T.json (a 4x4 start pose)")
    return ""


def size_note(kind: str, unit: str, size: float) -> str:
    """A note when a model's size (bounding-box diagonal, mm) is implausible for a part, else
    ``""``: a unitless mesh or point cloud read as mm that is under 2 mm or over 10 m across
    (with the unit that makes it a part of 5 mm .. 5 m, and the option), or a CAD model over
    10 m across in its declared unit.

    >>> size_note("points", "mm", 0.247)[:66]
    'STL/PLY/OBJ and point-cloud files carry no unit: read as mm, this '
    >>> size_note("cad", "MM", 40854.0)[:48], size_note("cad", "mm", 300.0)
    ('this CAD model is 40.9 m across in its declared ', '')
    """
    if not size > 0:
        return ""
    if kind == "cad":
        if size > 10_000.0:
            return (f"this CAD model is {size / 1000:.3g} m across in its declared unit "
                    f"({unit}): check the unit the CAD system exported")
        return ""
    if 2.0 <= size <= 10_000.0 or unit not in ("mm", None):
        return ""
    from shapeverify.units import MIXUPS, fitting_factor

    fit = fitting_factor(size / 100.0, MIXUPS, 0.05, 50.0, 1.0)
    guess = (f": if it is in {fit[2]}, give --model-unit {fit[3]} to prepare and inspect"
             if fit else "")
    return (f"STL/PLY/OBJ and point-cloud files carry no unit: read as mm, this model is "
            f"{size:.3g} mm across{guess}")
