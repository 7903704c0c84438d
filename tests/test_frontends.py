"""The three front ends -- ``shapeverify inspect``, ``POST /inspect`` and a batch task -- run one
inspection (:func:`shapeverify.pipeline.inspect_scan`): the same scan gives the same result."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("httpx")

# keys a front end adds around the result (where it came from, where it went, how long it took)
FRONT_END_KEYS = ("timings", "inputs", "model", "part", "scan", "scan_file", "record_id",
                  "worker_seconds", "batch")


def _core(d: dict) -> str:
    return json.dumps({k: v for k, v in d.items() if k not in FRONT_END_KEYS}, sort_keys=True)


@pytest.fixture(scope="module")
def wavy(tmp_path_factory):
    """A prepared two-face free-form panel (.svm) and a small simulated scan with a 0.5 mm dent."""
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.io.points import write_ply
    from shapeverify.nearest import prepare
    from shapeverify.simulate import ScanEffects, virtual_scan

    d = tmp_path_factory.mktemp("frontends")
    model = wavy_panel()
    prepare(model, spacing=2.0).save(d / "wavy.svm")
    sim = virtual_scan(model, pixel=2.5, noise=0.02,
                       effects=ScanEffects(dents=[(0.5, 12.0)]), motion=(1.0, 1.5), rng=5)
    assert 500 < len(sim.scan) < 5000
    write_ply(d / "scan.ply", sim.scan)
    return d


def test_cli_service_and_batch_give_the_same_result_dict_for_the_same_scan(wavy):
    from fastapi.testclient import TestClient
    from typer.testing import CliRunner

    from shapeverify.batch import inspect_bytes
    from shapeverify.cli import app
    from shapeverify.inspection import inspect
    from shapeverify.io.points import read_points
    from shapeverify.nearest import load_prepared
    from shapeverify.options import InspectionOptions
    from shapeverify.service import ServiceConfig, create_app

    svm, scan = wavy / "wavy.svm", wavy / "scan.ply"
    res = CliRunner().invoke(app, ["inspect", str(svm), str(scan), "--tolerance", "0.2",
                                   "--json", str(wavy / "cli.json")])
    assert res.exit_code == 1, res.output  # the dent (0.5 mm) is out of the 0.2 mm tolerance
    cli = json.loads((wavy / "cli.json").read_text())

    prep = load_prepared(svm)
    config = ServiceConfig(models={"wavy": prep}, db_path=wavy / "history.sqlite", threads=1)
    with TestClient(create_app(config)) as client:
        r = client.post("/inspect", params={"model": "wavy", "tolerance": 0.2},
                        content=scan.read_bytes())  # no content type: the first bytes decide
    assert r.status_code == 200, r.text
    service = r.json()

    svm_bytes = svm.read_bytes()
    batch = inspect_bytes(svm_bytes, hashlib.sha256(svm_bytes).hexdigest(), scan.name,
                          scan.read_bytes(), InspectionOptions(tolerance=0.2), False)

    library = inspect(prep, read_points(scan), tolerance=0.2).to_dict()  # the oracle
    assert cli["verdict"] == "fail" and any(g["extreme"] < -0.3 for g in cli["regions"])
    assert _core(cli) == _core(service) == _core(batch) == _core(library)
    assert cli["inputs"]["scan"] == "scan.ply" and service["record_id"] == 1
