"""How many faces a STEP or IGES file declares, read from its text (no OpenCASCADE).

OpenCASCADE silently leaves out a face whose entity is missing or broken (a shell that lists
``#17`` when there is no ``#17``, a face whose surface entity is gone): the import then has fewer
faces than the part, and nothing says so.  :func:`declared_faces` counts what the file means to
have, so that :func:`shapeverify.cad.occ_import.read_cad` can compare and warn.

* STEP: the ``ADVANCED_FACE`` and ``FACE_SURFACE`` entities, plus every entity that a
  ``CLOSED_SHELL``, ``OPEN_SHELL`` or ``CONNECTED_FACE_SET`` lists but the file does not define
  (a dangling reference).
* IGES: the directory entries of faces (type 510), trimmed and bounded surfaces (144, 143), and
  of surfaces that stand on their own (subordinate switch 00; types 114, 118, 120, 122, 128, 140,
  190-198).

Both counts agree with OpenCASCADE's face count on undamaged files (the tests check the bundled
and the shared example files).
"""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["declared_faces"]

_STEP_ENTITY = re.compile(rb"#(\d+)\s*=\s*([A-Za-z_][A-Za-z0-9_]*)?\s*\(")
_STEP_SHELL = re.compile(rb"#(\d+)\s*=\s*(CLOSED_SHELL|OPEN_SHELL|CONNECTED_FACE_SET)\s*\(\s*"
                         rb"'(?:[^']|'')*'\s*,\s*\(([^)]*)\)")
_STEP_REF = re.compile(rb"#(\d+)")
_STEP_FACES = (b"ADVANCED_FACE", b"FACE_SURFACE")
_IGES_FACES = {510, 144, 143}
_IGES_FREE_SURFACES = {114, 118, 120, 122, 128, 140, 190, 192, 194, 196, 198}


def declared_faces(path, fmt: str) -> tuple[int, list[str]]:
    """Faces declared by a STEP (``fmt="step"``) or IGES (``fmt="iges"``) file.

    Returns
    -------
    n : int
        The number of faces the file declares.
    notes : list of str
        One line per dangling face reference (STEP), e.g.
        ``"#17: listed by CLOSED_SHELL #16 but not defined in the file"``.
    """
    data = Path(path).read_bytes()
    return _step_faces(data) if fmt == "step" else (_iges_faces(data), [])


def _step_faces(data: bytes) -> tuple[int, list[str]]:
    start = data.find(b"DATA;")
    body = data[start:] if start >= 0 else data
    defined, faces = set(), 0
    for m in _STEP_ENTITY.finditer(body):
        defined.add(int(m.group(1)))
        faces += (m.group(2) or b"").upper() in _STEP_FACES
    notes, seen = [], set()
    for m in _STEP_SHELL.finditer(body):
        for ref in _STEP_REF.findall(m.group(3)):
            r = int(ref)
            if r not in defined and r not in seen:
                seen.add(r)
                notes.append(f"#{r}: listed by {m.group(2).decode()} #{int(m.group(1))} but not "
                             "defined in the file")
    return faces + len(notes), notes


def _iges_faces(data: bytes) -> int:
    n = 0
    for line in data.decode("latin-1").splitlines():
        if len(line) < 73 or line[72] != "D":
            continue
        try:
            if int(line[73:80]) % 2 == 0:
                continue  # the second line of a directory entry
            kind = int(line[0:8])
        except ValueError:
            continue
        status = line[64:72].replace(" ", "0").rjust(8, "0")
        if kind in _IGES_FACES or (kind in _IGES_FREE_SURFACES and status[2:4] == "00"):
            n += 1
    return n
