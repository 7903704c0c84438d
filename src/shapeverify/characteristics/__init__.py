"""Inspection plans: datum alignments, GD&T characteristics with uncertainty, reports, SPC.

>>> from shapeverify.characteristics import evaluate_plan, load_plan
>>> plan = load_plan("alignment: {type: best_fit}\\ncharacteristics:\\n"
...                  "  - {name: SKIN, type: surface_profile, faces: all, tol: 0.2}\\n")
>>> [c.name for c in plan.characteristics]
['SKIN']

``evaluate_plan(prep, scan, plan)`` measures them (an example: :func:`.evaluate.evaluate_plan`).

Modules: :mod:`.plan` (the YAML plan and its schema), :mod:`.pmi_plan` (a plan from the CAD
file's semantic PMI), :mod:`.features` (holes, planes,
cylinders of the CAD topology), :mod:`.alignment` (best fit on faces, constrained, RPS), :mod:`.datums` (datum features),
:mod:`.holes` (measuring a hole on a scan), :mod:`.zones` (minimum-zone flatness, ISO 14253-1
decisions), :mod:`.evaluate` (the characteristics), :mod:`.pdf` (PDF report), :mod:`.spc`
(characteristic history, Cp/Cpk, run charts, CSV), :mod:`.parts` (small test parts).
"""
from .alignment import AlignmentResult, align, best_fit, constrained_fit, rps_alignment
from .datums import datum_alignment
from .evaluate import CharacteristicResult, PlanResult, evaluate_plan
from .features import Feature, features_table, find_feature, model_features
from .holes import HoleMeasurement, measure_hole
from .plan import Plan, PlanError, load_plan, parse_plan
from .pmi_plan import plan_from_pmi
from .zones import decide, minimum_zone_flatness

__all__ = ["evaluate_plan", "PlanResult", "CharacteristicResult", "Plan", "PlanError",
           "load_plan", "parse_plan", "model_features", "features_table", "find_feature",
           "Feature", "align", "best_fit", "constrained_fit", "rps_alignment",
           "datum_alignment", "AlignmentResult", "measure_hole", "HoleMeasurement",
           "minimum_zone_flatness", "decide", "plan_from_pmi"]
