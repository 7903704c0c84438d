"""A near-symmetric part registered onto a copy of its true pose: :mod:`shapeverify.inspection.
ambiguity` (the verdict at the registration's alternative poses).

A plate 100 x 60 x 5 mm with one chamfered corner, seen nearly from above in a sensor's frame:
a copy turned 180 deg about its normal fits every scan point but those near the chamfer, the
global search's subset does not see them, and the good part failed ("material where the CAD
has none" at the chamfer) with only a warning that another start fits nearly as well."""
import warnings

import numpy as np
import pytest

from shapeverify.inspection import ambiguity


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    from shapeverify.cad.examples import chamfered_plate_step
    from shapeverify.cad.load import load_model
    from shapeverify.nearest import prepare

    path = chamfered_plate_step(tmp_path_factory.mktemp("plate") / "plate.step")
    return prepare(load_model(path))


def _view_scan(model, seed):
    from shapeverify.simulate import virtual_scan

    rng = np.random.default_rng(seed)
    v = rng.normal(size=3)
    v[2] = abs(v[2]) + 1.0
    return virtual_scan(model, view=v / np.linalg.norm(v), pixel=0.5, noise=0.02,
                        motion=(120.0, 300.0), rng=seed)


@pytest.mark.slow
def test_good_plate_registered_onto_its_turned_copy_passes_at_the_alternative(plate,
                                                                              monkeypatch):
    import sys

    from shapeverify import inspect

    vs = _view_scan(plate.model, 1)
    module = sys.modules["shapeverify.inspection.inspect"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = inspect(plate, vs.scan, tolerance=0.1)
        assert str(res.verdict) == "pass", res.reasons
        assert any("pass at a second pose that fits the scan alike" in r for r in res.reasons)
        # without the alternatives the registration's pose (a copy) fails the good part
        monkeypatch.setattr(module, "_at_alternatives", lambda prep, scan, result, *a: result)
        before = inspect(plate, vs.scan, tolerance=0.1)
    assert str(before.verdict) == "fail"
    assert before.registration.alternatives


def test_resolve_keeps_a_failed_part_when_the_alternative_fits_worse():
    """The alternative passes only where it fits the scan alike: one that passes by leaving
    points unevaluated (they fit nowhere) does not."""
    from types import SimpleNamespace

    def result(verdict, d, scale=0.02):
        dev = SimpleNamespace(values=np.asarray(d, float), evaluated=np.isfinite(d))
        reg = SimpleNamespace(scale=scale, T_model_scan=np.eye(4))
        return SimpleNamespace(verdict=verdict, deviations=dev, registration=reg,
                               reasons=(f"{verdict}: ...",), timings={})

    first = result("fail", np.r_[np.zeros(97), 0.5, 0.5, 0.5])     # 3 % far off
    worse = result("pass", np.r_[np.zeros(90), [np.nan] * 10])     # 10 % not evaluated
    assert ambiguity.resolve(first, worse, np.zeros((100, 3))) is first
    passed = result("pass", np.zeros(100))
    assert ambiguity.resolve(passed, worse, np.zeros((100, 3))) is passed   # a pass stands
