"""A form or orientation tolerance on several separate features, each evaluated on its own.

A feature control frame that points at several features (a "3X" cylindricity of three pins,
a perpendicularity of four bores) applies to each feature individually (ASME Y14.5; ISO 1101
likewise, unless a common zone "CZ" is drawn): three pins are not one cylinder.  A plan entry
with ``features: [[face:77, face:78], [face:79, face:80], ...]`` (:class:`.schema._Each`) is
evaluated as one characteristic per feature (the type's own evaluator, :mod:`.gdt`, on that
feature's faces) and reported as one result: the numbers of the feature with the least
margin to its limit (``upper - value - U``), the verdict the worst of all features'
(:func:`.zones.worst_verdict`: a feature not measured leaves at best 'undecided'), and every
feature's value, U and verdict in ``details['features']``.  Without ``features`` the type's
evaluator runs unchanged.
"""
from __future__ import annotations

import dataclasses

from .evaluate import _not_measured
from .zones import worst_verdict

__all__ = ["each_feature", "eval_straightness", "eval_circularity", "eval_cylindricity",
           "eval_orientation"]


def each_feature(evaluate, c, ctx):
    """The result of ``evaluate(c, ctx)`` applied to each of ``c.features`` (module
    docstring)."""
    results = [evaluate(c.model_copy(update={"faces": list(g), "features": None}), ctx)
               for g in c.features]
    rows = []
    for g, r in zip(c.features, results):
        row = {"faces": list(g), "value": r.measured, "uncertainty": r.uncertainty,
               "verdict": r.verdict}
        if "n" in r.details:
            row["n"] = r.details["n"]
        for key in ("zone_of_points", "noise_bias", "fitted_zone"):     # a zone less its noise (.zone_noise)
            if key in r.details:
                row[key] = r.details[key]
        if r.measured is None:
            row["reason"] = r.details.get("reason")
        rows.append(row)
    measured = [r for r in results if r.measured is not None]
    if not measured:
        return _not_measured(c, "no feature measured: " + "; ".join(
            f"{row['faces']}: {row.get('reason')}" for row in rows))
    worst = min(measured, key=lambda r: float(r.upper) - float(r.measured) - float(r.uncertainty))
    details = dict(worst.details)
    details.update({"features": rows, "n_features": len(rows),
                    "worst_feature": rows[results.index(worst)]["faces"]})
    return dataclasses.replace(worst, name=c.name, details=details,
                               verdict=worst_verdict(r.verdict for r in results))


def _each(evaluate):
    def run(c, ctx):
        if getattr(c, "features", None):
            return each_feature(evaluate, c, ctx)
        return evaluate(c, ctx)

    run.__name__ = evaluate.__name__
    run.__doc__ = f"{evaluate.__name__} of each of ``features`` (:func:`each_feature`)."
    return run


def _gdt(name):
    from . import gdt

    return _each(getattr(gdt, name))


eval_straightness = _gdt("eval_straightness")
eval_circularity = _gdt("eval_circularity")
eval_cylindricity = _gdt("eval_cylindricity")
eval_orientation = _gdt("eval_orientation")
