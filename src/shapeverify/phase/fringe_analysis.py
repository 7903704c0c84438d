"""Single-image fringe analysis (FTP, WFF), kept under its old path.

It lives in :mod:`shapeverify.camera.fringe_analysis` since :func:`shapeverify.camera.measure`
uses it: the camera package must not import the phase package, whose CAD-prior unwrapping
(:mod:`shapeverify.phase.cad_unwrap`) renders through the camera (no import cycle between the
folders, issue 31).  This module and :mod:`shapeverify.phase` re-export it unchanged.
"""
from shapeverify.camera.fringe_analysis import FringeAnalysis, find_carrier, ftp, wff  # noqa: F401

__all__ = ["FringeAnalysis", "find_carrier", "ftp", "wff"]
