"""Synthetic evaluations of a plan for the report tests (issue 28 item 4): every
characteristic gets a result of its type's form (a zone width, a size, a hole's two values)
without a scan, so the reports and SPC can be checked on every registered type fast.

The values are set from the plan's own limits: ``fraction`` of the zone (or of the size's
upper limit), decided by the ISO 14253-1 rule of :mod:`shapeverify.characteristics.zones`.
"""
from __future__ import annotations

import numpy as np

from shapeverify.characteristics import registry
from shapeverify.characteristics.alignment import AlignmentResult
from shapeverify.characteristics.evaluate import CharacteristicResult, PlanResult
from shapeverify.characteristics.plan import load_plan
from shapeverify.characteristics.zones import decide, worst_verdict, zone_decide

U = 0.004


def _size_limits(entry):
    for key in ("diameter",):
        t = getattr(entry, key, None)
        if t is not None:
            return t.limits()
    if getattr(entry, "lower", None) is not None and getattr(entry, "upper", None) is not None:
        return float(entry.lower), float(entry.upper)
    return -float(entry.tol), float(entry.tol)


def synthetic_result(entry, fraction: float = 0.4) -> CharacteristicResult:
    """A result of ``entry``'s type at ``fraction`` of its zone (a zone width: ``fraction *
    tol``; a size: ``fraction * upper`` from its nominal)."""
    t = entry.type
    if t == "hole":
        nom, meas, dev, lo, hi, u, vs = ({"center": [0.0, 0.0, 0.0]}, {"center": [0.0, 0.0, 0.0]},
                                         {}, {}, {}, {}, {})
        if entry.diameter is not None:
            a, b = entry.diameter.limits()
            nom["diameter"], dev["diameter"] = 10.0, fraction * b
            meas["diameter"] = 10.0 + fraction * b
            lo["diameter"], hi["diameter"], u["diameter"] = a, b, U
            vs["diameter"] = decide(fraction * b, a, b, U)
        if entry.position is not None:
            dev["position"] = fraction * entry.position.tol
            lo["position"], hi["position"], u["position"] = 0.0, entry.position.tol, U
            vs["position"] = decide(dev["position"], None, entry.position.tol, U)
        return CharacteristicResult(entry.name, t, nom, meas, dev, lo, hi, u,
                                    worst_verdict(list(vs.values())), {"verdicts": vs})
    if registry.by_name(t).one_sided:
        tol = entry.tol if getattr(entry, "tol", None) is not None else entry.upper - entry.lower
        v = fraction * tol
        details = {}
        if getattr(entry, "datums", None):
            details["drf"] = {"datums": "|".join(entry.datums)}
        return CharacteristicResult(entry.name, t, 0.0, v, v, 0.0, float(tol), U,
                                    zone_decide(t, v, 0.0, float(tol), U), details)
    lo, hi = _size_limits(entry)
    nominal = 0.0 if t == "check_point" else (getattr(entry, "nominal", None) or 25.0)
    dev = fraction * hi if hi else fraction * lo
    return CharacteristicResult(entry.name, t, nominal, nominal + dev, dev, lo, hi, U,
                                decide(dev, lo, hi, U), {})


def synthetic_plan_result(plan, fraction: float = 0.4) -> PlanResult:
    """A :class:`PlanResult` of ``plan`` (path, YAML or Plan) with every characteristic at
    ``fraction`` of its zone, a few points and an identity alignment."""
    plan = load_plan(plan)
    chars = tuple(synthetic_result(c, fraction) for c in plan.characteristics)
    al = AlignmentResult(np.eye(4), np.zeros((6, 6)), np.zeros(0), 0.0, (), (), "best_fit",
                         {"source": "synthetic"})
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 100, (200, 3))
    X[:, 2] = 0.0
    return PlanResult(plan, al, chars, worst_verdict([c.verdict for c in chars]), X,
                      rng.normal(0, 0.01, 200), np.zeros(200, np.int32), np.ones(200, bool),
                      0.01)
