"""shapeverify: shape verification of manufactured free-form parts against their CAD model.

After Per Bergström, *Computational Methods for Shape Verification of Free-Form Surfaces* (2011).
All lengths are in millimetres (CAD files in other units are converted at import).

>>> import shapeverify as sv
>>> sv.__version__
'0.1.0'

The public names are imported lazily, so that ``import shapeverify`` is cheap and OpenCASCADE is
loaded only when a CAD file is read.
"""

from __future__ import annotations

import importlib
import logging

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

# public name -> (module, attribute)
_PUBLIC = {
    "load_model": ("shapeverify.cad.load", "load_model"),
    "Model": ("shapeverify.cad.model", "Model"),
    "Face": ("shapeverify.cad.model", "Face"),
    "ModelPoints": ("shapeverify.cad.model", "ModelPoints"),
    "NurbsCurve": ("shapeverify.cad.nurbs", "NurbsCurve"),
    "NurbsSurface": ("shapeverify.cad.nurbs", "NurbsSurface"),
    "read_points": ("shapeverify.io.points", "read_points"),
    "write_ply": ("shapeverify.io.points", "write_ply"),
    "prepare": ("shapeverify.nearest", "prepare"),
    "load_prepared": ("shapeverify.nearest", "load_prepared"),
    "Prepared": ("shapeverify.nearest", "Prepared"),
    "register": ("shapeverify.registration", "register"),
    "Registration": ("shapeverify.registration", "Registration"),
    "deviations": ("shapeverify.inspection", "deviations"),
    "inspect": ("shapeverify.inspection", "inspect"),
    "InspectionResult": ("shapeverify.inspection", "InspectionResult"),
    "InspectionOptions": ("shapeverify.options", "InspectionOptions"),
    "OutputRequest": ("shapeverify.options", "OutputRequest"),
    "ShapeVerifyError": ("shapeverify.errors", "ShapeVerifyError"),
}
_SUBMODULES = {"cad", "io", "nearest", "registration", "inspection", "report", "simulate",
               "camera", "phase", "fitting", "errors", "pipeline", "options"}

__all__ = sorted(_PUBLIC) + sorted(_SUBMODULES) + ["__version__"]


def __getattr__(name: str):
    if name in _PUBLIC:
        module, attr = _PUBLIC[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    if name in _SUBMODULES:
        value = importlib.import_module(f"shapeverify.{name}")
        globals()[name] = value
        return value
    raise AttributeError(f"module 'shapeverify' has no attribute {name!r}")


def __dir__():
    return __all__
