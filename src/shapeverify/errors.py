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

__all__ = [
    "ShapeVerifyError",
    "CADImportError",
    "ModelFileError",
    "UnsupportedFormatError",
    "EmptyModelError",
    "ScanError",
    "RegistrationError",
]


class ShapeVerifyError(Exception):
    """Base class of the errors shapeverify raises on purpose."""


class CADImportError(ShapeVerifyError, ValueError):
    """A CAD file could not be read: corrupt, empty, truncated, or not what its extension says."""


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
