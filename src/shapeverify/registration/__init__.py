"""Registration: robust ICP of a scan to a prepared model (thesis ch. 5-6, Papers I-II).

>>> from shapeverify.registration import register, Registration
>>> register.__name__, Registration.__name__
('register', 'Registration')
"""
from .icp import DegenerateGeometryWarning, IterationRecord, Registration, register
from .global_search import GlobalAlignment, global_alignment
from .initial import InitialAlignment, principal_axes_alignment, read_init
from .losses import LOSSES, get_loss, robust_scale
from .options import RegistrationOptions
from .rigid import fisher_information, pose_error

__all__ = ["register", "Registration", "IterationRecord", "DegenerateGeometryWarning",
           "principal_axes_alignment", "InitialAlignment", "global_alignment",
           "GlobalAlignment", "read_init", "LOSSES", "get_loss",
           "robust_scale", "fisher_information", "pose_error", "RegistrationOptions"]
