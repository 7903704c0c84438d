"""A NIST PMI test part's plan and face numbering, for the tests that run part of a plan on an
independent scan (tests/test_datum_targets_ftc06.py, test_median_plane_ftc06.py,
test_datum_shift_pattern_nist.py, test_perpendicularity_projected_ftc07.py,
test_symmetry_ftc10.py)."""
from __future__ import annotations

from types import SimpleNamespace

import pytest


def nist_plan(shared_data, name: str):
    """``path``, ``model`` (the imported model), ``result`` (:func:`pmi_plan`'s), ``fmap`` (PMI
    face -> model face) and ``inv`` (its inverse) of ``shared_data/cad/nist/name``; the test is
    skipped when the file is not there."""
    from model_cache import cached_model, cached_pmi

    from shapeverify.characteristics.pmi_plan import _face_map, pmi_plan

    path = shared_data / "cad" / "nist" / name
    if not path.exists():
        pytest.skip(f"{path} not present (NIST MBE PMI test model)")
    # the import, PMI and the model's features: once per code version for every NIST module
    # (tests/model_cache.py: bitwise what load_model, read_pmi, model_features give)
    model = cached_model(path, features=True)
    result = pmi_plan(path, model=model, pmi=cached_pmi(path))
    m = getattr(model, "model", model)
    fmap = _face_map(result.pmi, m)
    return SimpleNamespace(path=path, model=m, result=result, fmap=fmap,
                           inv={v: k for k, v in fmap.items()})


def cached_pmi_plan(path):
    """``pmi_plan(path)`` with the import, the PMI and the model's features from
    tests/model_cache.py (bitwise what load_model, read_pmi and model_features give, computed
    once per code version and shared by every module and pytest-xdist worker that plans the
    same file: the features are most of a plan's CPU, the PMI read and import the rest)."""
    from model_cache import cached_model, cached_pmi

    from shapeverify.characteristics.pmi_plan import pmi_plan

    return pmi_plan(path, model=cached_model(path, features=True), pmi=cached_pmi(path))


def one_tolerance_on_faces(gz, folder, gid: str, faces, deflection: float = 0.01):
    """One geometric tolerance ``gid`` of a bundled NIST file (``gz``, gunzipped into
    ``folder``) as a plan aligned by a best fit of the CAD faces ``faces`` (the file's face
    numbers), with what a test needs to scan those faces independently: ``path``, ``data`` (the
    plan), ``prep`` (prepared at 1 mm), ``inv`` (the file's face -> the model's) and the
    tessellation ``V, T, F`` of those faces only (``F``: each triangle's model face)."""
    import gzip
    import shutil

    import numpy as np
    from independent_scans import file_tessellation
    from model_cache import cached_model, cached_pmi, cached_prepared

    from shapeverify.characteristics.pmi_plan import _face_map, pmi_plan

    path = folder / gz.name[:-3]
    with gzip.open(gz, "rb") as src, open(path, "wb") as dst:
        shutil.copyfileobj(src, dst)
    # the model's features once per code version for the plan and the prepared model's copy
    # (tests/model_cache.py: bitwise what model_features gives)
    model, pmi = cached_model(path, features=True), cached_pmi(path)
    res = pmi_plan(path, model=model, pmi=pmi)
    inv = {v: k for k, v in _face_map(pmi, model).items()}
    data = dict(res.data)
    data["characteristics"] = [c for c in data["characteristics"] if c["pmi"]["id"] == gid]
    data.pop("unsupported", None)
    data["alignment"] = {"type": "best_fit", "faces": [f"face:{f}" for f in sorted(faces)]}
    prep = cached_prepared(path, spacing=1.0, features=True)
    V, T, F = file_tessellation(path, deflection)
    keep = np.isin(F, [inv[f] for f in faces])
    return SimpleNamespace(path=path, data=data, prep=prep, inv=inv, V=V, T=T[keep], F=F[keep])


def ftc10_gt10_scan(folder, noise: float = 0.02):
    """NIST FTC 10 (bundled, gunzipped into ``folder``) scanned whole as an independent sampler
    scans it -- OpenCASCADE's tessellation of every face of the file at 0.002 mm, 1 point/mm^2
    at random (seed 0), ``noise`` along the normal -- and its plan cut to the profile GT10:
    ``(prep, X, N, on_supplemental, plan_yaml)`` (``on_supplemental``: the points drawn on the
    file's supplemental faces).  For tests/test_scan_points_on_supplemental_geometry.py and
    benchmarks/check_supplemental_points.py."""
    import gzip
    import shutil
    from pathlib import Path

    import numpy as np
    import yaml
    from independent_scans import file_tessellation, random_points
    from model_cache import cached_prepared

    gz = Path(__file__).parent / "data" / "nist_extra" / "nist_ftc_10_asme1_ap242-e2.stp.gz"
    path = folder / gz.name[:-3]
    with gzip.open(gz, "rb") as src, open(path, "wb") as dst:
        shutil.copyfileobj(src, dst)
    prep = cached_prepared(path, spacing=1.0, features=True)
    V, T, F = file_tessellation(path, 0.002)
    rng = np.random.default_rng(0)
    P, N, t = random_points(V, T, 1.0, rng, with_triangles=True)
    X = P + rng.normal(0.0, noise, len(P))[:, None] * N
    data = dict(cached_pmi_plan(path).data)
    data.pop("unsupported", None)
    data["characteristics"] = [c for c in data["characteristics"] if c["name"] == "GT10_profile"]
    return prep, X, N, np.isin(F[t], prep.model.supplemental), yaml.safe_dump(data)
