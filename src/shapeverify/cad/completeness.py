"""Whether a CAD model holds every face its file declares (issue 33 row 2).

A STEP file whose shell lists a face that is not in the file, or a face OpenCASCADE cannot
convert, imports with fewer faces than the part has (:attr:`Model.n_missing_faces`,
:attr:`Model.skipped_faces`); a solid whose faces do not close (``Model.open_seams``: boundary
segments of a closed shell that meet no other face) is incomplete too.  An inspection against such a model cannot see a defect on the
missing surface: the audit's scan with a 0.49 mm dent on the missing face *passed* (its points
were called "a reflection or a foreign object?").  So :func:`shapeverify.prepare` refuses an
incomplete model (:func:`require_complete`) unless the user asks for it
(``allow_incomplete=True``, ``--allow-incomplete-model``); every inspection against a model
prepared that way says which faces are missing (:func:`missing_faces_note`).
"""

from __future__ import annotations

from ..errors import IncompleteModelError

__all__ = ["is_incomplete", "missing_faces_text", "missing_faces_note", "require_complete"]


def is_incomplete(model) -> bool:
    """True when the CAD file declares faces the model does not hold."""
    return getattr(model, "kind", "cad") == "cad" and (
        getattr(model, "n_missing_faces", 0) > 0 or bool(getattr(model, "skipped_faces", ()))
        or bool(getattr(model, "open_seams", ())))


def missing_faces_text(model, limit: int = 8) -> str:
    """"N of M faces of FILE are missing: why, why, ..." (at most ``limit`` reasons), and the
    open seams of a solid."""
    seams = ""
    if model.open_seams:
        seams = (f"{model.source} declares a closed solid but has open seams (a face missing or "
                 f"not joined): {'; '.join(model.open_seams[:limit])}"
                 + (f" (and {len(model.open_seams) - limit} more)"
                    if len(model.open_seams) > limit else ""))
        if not (model.n_missing_faces or model.skipped_faces):
            return seams
        seams = "; " + seams
    n_file = model.n_faces_in_file if model.n_faces_in_file is not None else len(model.faces)
    n_missing = max(model.n_missing_faces, len(model.skipped_faces))
    why = list(model.skipped_faces[:limit])
    more = len(model.skipped_faces) - len(why)
    return (f"{n_missing} of the {max(n_file, len(model.faces) + n_missing)} faces of "
            f"{model.source} are missing from the model: {'; '.join(why)}"
            + (f" (and {more} more)" if more > 0 else "") + seams)


def missing_faces_note(model) -> str | None:
    """The line every inspection against an incomplete model carries in its reasons (None
    for a complete model)."""
    if not is_incomplete(model):
        return None
    return (f"incomplete model: {missing_faces_text(model)}; the surface of those faces is "
            "not inspected (a defect there cannot be found), prepared with "
            "--allow-incomplete-model")


def require_complete(model) -> None:
    """Raise :class:`~shapeverify.errors.IncompleteModelError` for an incomplete CAD model.

    Raises
    ------
    IncompleteModelError
        The message names the file and the missing faces, and how to proceed anyway.
    """
    if is_incomplete(model):
        raise IncompleteModelError(
            f"{missing_faces_text(model)}. An inspection against it cannot find a defect on the "
            "missing surface. Repair or export the CAD file again; to inspect against the "
            "faces that were read anyway, give --allow-incomplete-model (Python: "
            "prepare(model, allow_incomplete=True)): every inspection then names the missing "
            "faces in its reasons")
