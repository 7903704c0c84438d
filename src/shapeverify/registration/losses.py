"""Robust loss functions of registration: those of :mod:`shapeverify.robust` (the one module).

Kept so that ``from shapeverify.registration.losses import get_loss`` keeps working.
"""
from ..robust import LOSSES, MAD_TO_SIGMA, Loss, get_loss, robust_scale

__all__ = ["Loss", "LOSSES", "get_loss", "robust_scale", "MAD_TO_SIGMA"]
