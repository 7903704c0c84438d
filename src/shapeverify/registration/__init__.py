"""Registration: robust ICP of a scan to a prepared model (thesis ch. 5-6, Papers I-II).

>>> from shapeverify.registration import register, Registration   # doctest: +SKIP
"""
from .icp import DegenerateGeometryWarning, IterationRecord, Registration, register
from .initial import InitialAlignment, principal_axes_alignment
from .losses import LOSSES, get_loss, robust_scale
from .rigid import fisher_information, pose_error

__all__ = ["register", "Registration", "IterationRecord", "DegenerateGeometryWarning",
           "principal_axes_alignment", "InitialAlignment", "LOSSES", "get_loss",
           "robust_scale", "fisher_information", "pose_error"]
