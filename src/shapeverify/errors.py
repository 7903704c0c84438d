"""Exceptions raised by shapeverify.

Every error the library raises on purpose derives from :class:`ShapeVerifyError`, so that a front end
(the CLI, a service) can catch "expected" failures -- bad input files, registrations that cannot
start -- in one place and show the message, while programming errors still surface as tracebacks.
The input-related classes also derive from :class:`ValueError`, so that code written against the
standard library's conventions keeps working.

A missing file raises the standard :class:`FileNotFoundError` (with the path in its ``filename``).

Example
-------
>>> from shapeverify.errors import CADImportError, ShapeVerifyError
>>> issubclass(CADImportError, ShapeVerifyError) and issubclass(CADImportError, ValueError)
True
"""

from __future__ import annotations

from pathlib import Path

__all__ = [
    "ShapeVerifyError",
    "CADImportError",
    "IncompleteModelError",
    "ModelFileError",
    "UnsupportedFormatError",
    "EmptyModelError",
    "ScanError",
    "RegistrationError",
    "is_input_error",
]


class ShapeVerifyError(Exception):
    """Base class of the errors shapeverify raises on purpose."""


class CADImportError(ShapeVerifyError, ValueError):
    """A CAD file could not be read: corrupt, empty, truncated, or not what its extension says."""


class IncompleteModelError(CADImportError):
    """A CAD model lacks faces its file declares (a dangling face reference, a face OpenCASCADE
    could not convert) or a solid's faces do not close (open seams); refused by ``prepare``
    unless ``allow_incomplete=True`` (``--allow-incomplete-model``)."""


class ModelFileError(CADImportError):
    """A saved model (``.svmodel``) or prepared model (``.svm``) is damaged, truncated or foreign.

    The message names the file and says how to make it again (``shapeverify prepare``).
    """


class UnsupportedFormatError(ShapeVerifyError, ValueError):
    """The file extension is not one shapeverify reads (the message lists the supported ones)."""


class EmptyModelError(ShapeVerifyError, ValueError):
    """A model file was read but holds nothing usable (for a CAD file: no faces)."""


class ScanError(ShapeVerifyError, ValueError):
    """A scan (point cloud) file is empty, malformed, or holds no finite points."""


class RegistrationError(ShapeVerifyError):
    """Registration cannot start or produced no usable result (e.g. no correspondences)."""


_PACKAGE_DIR = Path(__file__).resolve().parent


def is_input_error(exc: BaseException) -> bool:
    """Whether ``exc`` is an error about the input rather than a bug.

    Input errors are the :class:`ShapeVerifyError` family, :class:`OSError` (a file that cannot be
    read or written, a full disk) and a :class:`ValueError` raised by shapeverify's own code (its
    deliberate "bad argument" messages).  Anything else -- a ``TypeError``, a ``KeyError``, a
    ``ValueError`` raised inside numpy or another library -- is a bug.

    Example
    -------
    >>> is_input_error(CADImportError("x.step: truncated")), is_input_error(KeyError("k"))
    (True, False)
    """
    if isinstance(exc, (ShapeVerifyError, OSError)):
        return True
    if not isinstance(exc, ValueError):
        return False
    tb = exc.__traceback__
    if tb is None:
        return False
    while tb.tb_next is not None:
        tb = tb.tb_next
    return Path(tb.tb_frame.f_code.co_filename).resolve().is_relative_to(_PACKAGE_DIR)
