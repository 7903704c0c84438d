"""A prismatic part scanned at a random pose, no start given (issue 27 row 2, issue 30 item 4):
the coarse ICP from the identity once turned NIST CTC 01's scan 180 deg and kept it because
two thirds of the points then lay on the surface ("auto" kept any end that fitted half the
points): 4 of 4 random poses ended flipped, two with no warning. An end the coarse stage had to
turn far is now only one hypothesis of the global search."""

from __future__ import annotations

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.registration.rigid import pose_error

from model_cache import cached_prepared
from test_plan_nist import CTC01, _scan, occ_mesh

pytestmark = [pytest.mark.slow, pytest.mark.shared]


@pytest.fixture(scope="module")
def ctc01(shared_data):
    path = shared_data / CTC01
    # the same part and spacing as test_plan_nist: prepared once per run (tests/model_cache.py)
    return cached_prepared(path, spacing=4.0), occ_mesh(path)


@pytest.mark.parametrize("seed", [1, 3])   # seed 1: flipped with no warning; 3: 50 mm off too
def test_ctc01_at_a_random_pose_registers_right_from_no_start(ctc01, seed):
    prep, (V, T) = ctc01
    scan, T_true = _scan(V, T, 40000, 0.02, seed)
    reg = sv.register(scan, prep)
    err = pose_error(reg.T_model_scan, T_true)
    assert np.degrees(np.linalg.norm(err[:3])) < 0.01 and np.linalg.norm(err[3:]) < 0.01, \
        (reg.init, err)
    assert not reg.warnings
