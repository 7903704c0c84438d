"""A plan whose only tolerance is a position of zone 0 at MMC (all of it bonus: NIST FTC 10
GT25, and any plan cut down to it) raised "tolerance must be > 0 mm" before any
characteristic was evaluated: the default evaluation distance is 5 x the largest tolerance."""
from __future__ import annotations

from types import SimpleNamespace

from shapeverify.characteristics.evaluate import _largest_tolerance
from shapeverify.measures.checks import default_evaluation_distance


def test_plan_of_zero_tolerance_at_mmc_only_gets_the_default_evaluation_distance():
    only_zero = SimpleNamespace(characteristics=[
        {"name": "GT25", "type": "hole", "position": {"tol": 0.0, "material": "M"}}])
    assert _largest_tolerance(only_zero) == 0.2
    assert default_evaluation_distance(_largest_tolerance(only_zero), 100.0) == 1.0
    mixed = SimpleNamespace(characteristics=[
        {"name": "GT25", "type": "hole", "position": {"tol": 0.0, "material": "M"}},
        {"name": "GT1", "type": "surface_profile", "tol": 0.5}])
    assert _largest_tolerance(mixed) == 0.5
