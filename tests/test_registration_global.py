"""Registration with no start (init='auto'/'global'), determinism across runs and processes,
read_init, the honest convergence test and its warnings (issue 14 items 1-2, issue 13 item 4)."""

import hashlib
import json
import os
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface
from shapeverify.nearest import prepare
from shapeverify.registration import register
from shapeverify.registration.global_search import global_alignment
from shapeverify.registration.initial import read_init
from shapeverify.registration.rigid import make_transform, rodrigues
from shapeverify.simulate import ScanEffects, virtual_scan

UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@pytest.fixture(scope="module")
def panel(example_step):
    from shapeverify.cad.load import load_model

    return load_model(example_step)


@pytest.fixture(scope="module")
def panel_prep(panel):
    return prepare(panel, spacing=1.0)


def _sensor_motion(seed, distance=800.0):
    """model -> sensor frame: any rotation, the part ``distance`` mm from the sensor's origin."""
    M = np.eye(4)
    M[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    M[:3, 3] = np.random.default_rng(seed).normal(0.0, 1.0, 3)
    M[:3, 3] *= distance / np.linalg.norm(M[:3, 3])
    return M


def _digest(reg) -> str:
    h = hashlib.sha256()
    for a in (reg.T_model_scan, reg.weights, reg.covariance, np.array([reg.rms, reg.scale])):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(repr((reg.iterations, reg.converged, reg.message, reg.init)).encode())
    return h.hexdigest()


# ------------------------------------------------------------------------------ determinism
def test_register_is_bit_identical_on_repeated_calls_and_rng_none_is_the_fixed_seed(panel,
                                                                                     panel_prep):
    vs = virtual_scan(panel, pixel=3.0, noise=0.02,
                      effects=ScanEffects(outlier_fraction=0.1), motion=(6.0, 12.0),
                      rng=3)
    a = register(vs.scan, panel_prep)
    b = register(vs.scan, panel_prep)
    c = register(vs.scan, panel_prep, rng=None)
    assert _digest(a) == _digest(b) == _digest(c)
    assert a.converged and vs.accuracy(a.T_model_scan).crb < 6.0


_CHILD = textwrap.dedent("""
    import hashlib, sys, warnings
    import numpy as np
    warnings.simplefilter("ignore")
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.nearest import prepare
    from shapeverify.registration import register
    from shapeverify.simulate import virtual_scan
    model = load_model(example_part_step(sys.argv[1]))
    prep = prepare(model, spacing=2.0)
    M = np.array({motion})
    vs = virtual_scan(model, pixel=3.0, noise=0.02, outlier_fraction=0.1, motion=M, rng=5)
    out = []
    for init in ("auto", None):
        reg = register(vs.scan, prep, init=init)
        h = hashlib.sha256()
        for a in (reg.T_model_scan, reg.weights, reg.covariance, np.array([reg.rms, reg.scale])):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(repr((reg.iterations, reg.converged, reg.message, reg.init)).encode())
        out.append(h.hexdigest())
    print(" ".join(out), reg.init, float(vs.accuracy(reg.T_model_scan).rotation_deg))
""")


@pytest.mark.slow
def test_register_is_bit_identical_across_processes(tmp_path):
    """Two fresh interpreters (different hash seeds) give the same bytes, also through the
    global search (a scan in a far sensor frame)."""
    code = _CHILD.format(motion=_sensor_motion(7).tolist())
    outs = []
    for k, hs in enumerate(("1", "12345")):
        env = dict(os.environ, PYTHONHASHSEED=hs)
        r = subprocess.run([sys.executable, "-c", code, str(tmp_path / f"p{k}.step")],
                           capture_output=True, text=True, env=env, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        outs.append(r.stdout.split())
    assert outs[0][:2] == outs[1][:2] and outs[0][0] == outs[0][1]
    assert outs[0][2].startswith("global") and float(outs[0][-1]) < 0.5


# ------------------------------------------------------------------------------ no start
@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scan_in_a_far_sensor_frame_is_found_with_no_start(panel, panel_prep, seed):
    vs = virtual_scan(panel, pixel=2.5, noise=0.03, effects=ScanEffects(outlier_fraction=0.05),
                      motion=_sensor_motion(seed), rng=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = register(vs.scan, panel_prep)
    acc = vs.accuracy(reg.T_model_scan)
    assert reg.init.startswith("global"), reg
    assert reg.converged, reg.message
    assert acc.crb < 6.0 and acc.rotation_deg < 0.05, acc


def test_identity_is_kept_when_the_scan_overlaps_the_model(panel, panel_prep):
    vs = virtual_scan(panel, pixel=3.0, noise=0.02, motion=(4.0, 8.0), rng=4)
    reg = register(vs.scan, panel_prep)
    assert reg.init == "identity" and reg.converged and reg.warnings == ()
    assert vs.accuracy(reg.T_model_scan).crb < 6.0
    assert [h.stage for h in reg.history][0] == "coarse"


def test_global_alignment_alone_lands_in_the_basin(panel, panel_prep):
    vs = virtual_scan(panel, pixel=2.0, noise=0.03, effects=ScanEffects(outlier_fraction=0.05),
                      motion=_sensor_motion(11), rng=11)
    ga = global_alignment(vs.scan, panel_prep)
    acc = vs.accuracy(ga.T_model_scan)
    assert acc.rotation_deg < 2.0 and acc.translation < 5.0, (acc, ga)
    assert ga.fit > 0.7 and ga.n_hypotheses > 24 and "GlobalAlignment(" in repr(ga)


def test_explicit_init_modes_and_bad_names(panel, panel_prep):
    vs = virtual_scan(panel, pixel=4.0, noise=0.02, motion=(3.0, 5.0), rng=6)
    ident = register(vs.scan, panel_prep, init="identity")
    glob = register(vs.scan, panel_prep, init="global")
    given = register(vs.scan, panel_prep, init=np.eye(4))
    assert ident.init == "identity" and given.init == "given"
    assert glob.init.startswith("global: ")
    for r in (ident, glob, given):
        assert r.converged and vs.accuracy(r.T_model_scan).crb < 6.0, r
    with pytest.raises(ValueError, match="unknown init.*'auto'"):
        register(vs.scan, panel_prep, init="best-guess")


# ------------------------------------------------------------------------------ read_init
def test_read_init_reads_json_and_npy_and_rejects_bad_files(tmp_path):
    T = make_transform(rodrigues([0.1, -0.2, 0.3]), [10.0, -5.0, 2.0])
    (tmp_path / "a.json").write_text(json.dumps(T.tolist()))
    (tmp_path / "b.json").write_text(json.dumps({"T_model_scan": T.tolist(), "note": "fixture"}))
    np.save(tmp_path / "c.npy", T)
    for name in ("a.json", "b.json", "c.npy"):
        np.testing.assert_allclose(read_init(tmp_path / name), T, atol=1e-15)
    (tmp_path / "bad.json").write_text("{not json")
    (tmp_path / "key.json").write_text(json.dumps({"T": T.tolist()}))
    (tmp_path / "shape.json").write_text(json.dumps(T[:3].tolist()))
    (tmp_path / "mirror.json").write_text(json.dumps(np.diag([1.0, 1, -1, 1]).tolist()))
    (tmp_path / "T.txt").write_text("1 0 0 0")
    with pytest.raises(ValueError, match="not valid JSON"):
        read_init(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="T_model_scan"):
        read_init(tmp_path / "key.json")
    with pytest.raises(ValueError, match=r"\(4, 4\)"):
        read_init(tmp_path / "shape.json")
    with pytest.raises(ValueError, match="rigid"):
        read_init(tmp_path / "mirror.json")
    with pytest.raises(ValueError, match=".json.*.npy"):
        read_init(tmp_path / "T.txt")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_init(tmp_path / "missing.json")


# ------------------------------------------------------------------------------ honesty
@pytest.mark.parametrize("axis", [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
def test_wrong_pose_is_never_converged_without_a_warning(panel, panel_prep, axis):
    """Started turned by 180 deg about z or upside down about y (no global search): the ICP
    ends in a wrong pose or cannot start; it must say so (an error, not converged, or a
    warning)."""
    from shapeverify.errors import RegistrationError

    vs = virtual_scan(panel, pixel=3.0, noise=0.02, rng=8)
    c = vs.scan.mean(axis=0)
    R = rodrigues(np.pi * np.asarray(axis))
    flip = make_transform(R, c - R @ c)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            reg = register(vs.scan, panel_prep, init=flip)
        except RegistrationError:
            return
    acc = vs.accuracy(reg.T_model_scan)
    assert acc.rotation_deg > 10.0
    assert (not reg.converged) or reg.warnings, reg


# ------------------------------------------------------------------------------ real data
def _bun_pose(conf, name):
    for line in conf.read_text().splitlines():
        f = line.split()
        if len(f) == 9 and f[0] == "bmesh" and f[1] == name:
            R = Rotation.from_quat(np.array(f[5:9], float)).as_matrix()
            return make_transform(R.T, np.array(f[2:5], float) * 1000.0)
    raise KeyError(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bun045.ply", "bun090.ply"])
def test_bunny_views_from_30_degree_starts_with_no_init(shared_data, name):
    """Real partial views given in a frame 30 deg / 20 mm off the bun000 reference, no init:
    the right pose (bun.conf within 0.15 deg / 0.25 mm: the peers' accuracy, issue 14 item 7;
    bun090 was 0.26 deg before the overlap-aware scale), or a pose that says it is not right."""
    import dataclasses

    from shapeverify.cad.load import load_model
    from shapeverify.io.points import read_points
    from shapeverify.registration.rigid import apply_transform, rotation_vector
    from shapeverify.simulate import random_motion

    d = shared_data / "scans" / "bunny"
    ref = load_model(d / "bun000.ply")
    prep = prepare(dataclasses.replace(ref, vertices=ref.vertices * 1000.0), spacing=1.0)
    scan0 = read_points(d / name) * 1000.0
    T0 = np.linalg.inv(_bun_pose(d / "bun.conf", "bun000.ply")) @ _bun_pose(d / "bun.conf", name)
    good = 0
    for seed in range(3):
        Pm = random_motion(30.0, 20.0, center=apply_transform(T0, scan0.mean(0)), rng=seed)
        scan = apply_transform(Pm @ T0, scan0)
        T_true = np.linalg.inv(Pm)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reg = register(scan, prep)
        dT = reg.T_model_scan @ np.linalg.inv(T_true)
        cm = apply_transform(T_true, scan.mean(0))
        ang = np.degrees(np.linalg.norm(rotation_vector(dT[:3, :3])))
        trans = np.linalg.norm(dT[:3, :3] @ cm + dT[:3, 3] - cm)
        right = ang < 0.15 and trans < 0.25
        good += right
        assert right or not reg.converged or reg.warnings, (seed, ang, trans, reg)
    assert good == 3
