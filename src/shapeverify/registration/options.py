"""The options of :func:`~shapeverify.registration.register`, parsed once at its boundary.

Users pass strings (with aliases: ``'plane'``, ``'pca'``, ``'eye'``, ``None`` ...);
:func:`~shapeverify.registration.register` turns them into the enums below once, and everything
behind it (the stages of :mod:`._irls`, the global search) takes the enums and the small named
structures :class:`StageSettings`.  The enums are :class:`enum.StrEnum`: a member equals its
canonical string (``Method.POINT_TO_PLANE == 'point-to-plane'``), so results and JSON keep the
plain names.

>>> Method.parse("plane"), InitMode.parse("pca")[0]
(<Method.POINT_TO_PLANE: 'point-to-plane'>, <InitMode.PRINCIPAL_AXES: 'principal-axes'>)
"""
from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .losses import Loss

__all__ = ["Method", "InitMode", "MethodName", "LossName", "InitName", "StageSettings",
           "RegistrationOptions"]

#: the canonical names (the values of the enums; what results and reports carry)
MethodName = Literal["point-to-plane", "point-to-point", "point-then-plane"]
LossName = Literal["tukey", "huber", "cauchy", "welsch", "l2"]
InitName = Literal["auto", "identity", "principal-axes", "global"]


def _key(value) -> str:
    return str(value).lower().replace("_", "-").strip()


class Method(enum.StrEnum):
    """Rigid step of the ICP (see :func:`~shapeverify.registration.register`)."""

    POINT_TO_PLANE = "point-to-plane"
    POINT_TO_POINT = "point-to-point"
    POINT_THEN_PLANE = "point-then-plane"

    @classmethod
    def parse(cls, value) -> "Method":
        """The method named by ``value`` (a Method, a canonical name or an alias).

        Raises
        ------
        ValueError
            For an unknown name (the message lists the valid ones).
        """
        if isinstance(value, cls):
            return value
        key = _key(value)
        if key not in _METHOD_ALIASES:
            raise ValueError(f"unknown method {value!r}; use 'point-to-plane', 'point-to-point' "
                             "or 'point-then-plane'")
        return _METHOD_ALIASES[key]

    @property
    def coarse(self) -> "Method":
        """The step of the coarse stage (point-to-point for 'point-then-plane')."""
        return Method.POINT_TO_POINT if self is Method.POINT_THEN_PLANE else self

    @property
    def final(self) -> "Method":
        """The step of the final stage (point-to-plane for 'point-then-plane')."""
        return Method.POINT_TO_PLANE if self is Method.POINT_THEN_PLANE else self


_METHOD_ALIASES = {"point-to-plane": Method.POINT_TO_PLANE, "plane": Method.POINT_TO_PLANE,
                   "point-to-point": Method.POINT_TO_POINT, "point": Method.POINT_TO_POINT,
                   "point-then-plane": Method.POINT_THEN_PLANE,
                   "point-to-point-then-plane": Method.POINT_THEN_PLANE}


class InitMode(enum.StrEnum):
    """How the start of the registration is found."""

    AUTO = "auto"
    IDENTITY = "identity"
    PRINCIPAL_AXES = "principal-axes"
    GLOBAL = "global"
    GIVEN = "given"

    @classmethod
    def parse(cls, init, validate=None) -> "tuple[InitMode, np.ndarray | None]":
        """``(mode, None)`` for a named start (None = 'auto'), ``(GIVEN, T)`` for a matrix.

        ``validate(T)`` checks and returns a given (4, 4) matrix.

        Raises
        ------
        ValueError
            For an unknown name.
        """
        if init is None:
            return cls.AUTO, None
        if isinstance(init, str):
            key = _key(init)
            if key not in _INIT_ALIASES:
                raise ValueError(f"unknown init {init!r}; use 'auto' (None), 'identity', "
                                 "'principal-axes', 'global' or a (4, 4) T_model_scan")
            return _INIT_ALIASES[key], None
        return cls.GIVEN, (validate(init) if validate is not None else np.asarray(init))


_INIT_ALIASES = {"auto": InitMode.AUTO, "none": InitMode.AUTO, "identity": InitMode.IDENTITY,
                 "eye": InitMode.IDENTITY, "principal-axes": InitMode.PRINCIPAL_AXES,
                 "pca": InitMode.PRINCIPAL_AXES, "global": InitMode.GLOBAL}


@dataclass(frozen=True)
class StageSettings:
    """What one IRLS-ICP stage needs besides the points and the pose (see :mod:`._irls`).

    Attributes
    ----------
    method : Method
        Rigid step (point-to-plane or point-to-point; never 'point-then-plane' here).
    loss : Loss
        Robust rho-function.
    scale : float or None
        Fixed robust scale sigma (mm); None re-estimates it every iteration.
    floor : float
        Smallest scale (mm), for exact data.
    radius : float
        RMS radius of the scan about its centroid (mm): scales rotations against translations.
    max_iterations : int
        Rigid steps allowed in the stage.
    tolerance : float
        Relative stopping tolerance (see :func:`~shapeverify.registration.register`).
    overlap : bool
        The robust scale may drop to that of the residuals near zero when most points lie off
        the model (a partial overlap, see :func:`._irls.overlap_scale`); the final stage's.
    """

    method: Method
    loss: Loss
    scale: float | None
    floor: float
    radius: float
    max_iterations: int
    tolerance: float
    overlap: bool = False


@dataclass(frozen=True)
class RegistrationOptions:
    """Which of :func:`~shapeverify.registration.register`'s safeguards against a wrong minimum
    run (they were the module flags ``icp.PROBE``, ``icp.RESTART`` and ``icp.ANNEAL``).

    Attributes
    ----------
    probe : bool
        Probe the least-determined direction for a better minimum (:mod:`._basin`), at most
        ``probe_rounds`` times (another direction may rest on few points once one is right; a
        start several wall thicknesses deep moves one wall per round).
    probe_rounds : int
        Probe rounds at most (default 6).
    restart : bool
        Restart a pose flagged as a wrong minimum about the model's near-symmetry axis
        (:mod:`._restart`).
    anneal : float, optional
        The coarse stage's robust scale may fall by at most this factor per iteration
        (graduated scale, see ``_irls.stage_rematch``); None (default): off (it did not keep
        the impeller out of its wrong minima and costs a second matching of the final stage on
        the example panel).

    >>> RegistrationOptions(probe=False)
    RegistrationOptions(probe=False, probe_rounds=6, restart=True, anneal=None)
    """

    probe: bool = True
    probe_rounds: int = 6
    restart: bool = True
    anneal: float | None = None

    def __post_init__(self):
        if isinstance(self.probe_rounds, bool) or int(self.probe_rounds) != self.probe_rounds \
                or self.probe_rounds < 0:
            raise ValueError(f"probe_rounds must be a whole number >= 0, got {self.probe_rounds!r}")
        if self.anneal is not None and not (np.isfinite(self.anneal) and self.anneal > 1.0):
            raise ValueError(f"anneal is the largest factor the coarse scale may fall per "
                             f"iteration (> 1) or None, got {self.anneal!r}")
        object.__setattr__(self, "probe", bool(self.probe))
        object.__setattr__(self, "restart", bool(self.restart))
