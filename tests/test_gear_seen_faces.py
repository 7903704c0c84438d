"""A good gear passes at ±0.05 mm when the inspection is limited to the faces it saw (issue 30).

Issue 30: rim-only focus-variation scans of a 19-tooth micro gear (held back, not on this
machine) could never pass: the coverage counts the whole gear, of which a rim scan sees a
sixth.  ``inspect(faces="seen")`` limits the inspection to the faces the scan saw
(:func:`shapeverify.inspection.coverage.seen_faces`: at least 10 % of a face's area covered at
the registered pose, named in the reasons).

The gear is a proxy made here with OpenCASCADE (no gear CAD is in the repository): 19 teeth,
module 0.25 mm, straight flanks between a root arc and a tip arc (tip diameter 5.25 mm), 1 mm
face width, a hub (diameter 2.8 mm) standing 1.25 mm out on each side and a 1.6 mm bore through
it; it is written to STEP and read back by the project's CAD import
(:func:`shapeverify.load_model`).  Its symmetry group is the 19 spins by a pitch and their flips
upside down: 38 equally right poses.  (With the hub on one side only, a rim scan that does not
see the hub fits the upside-down gear exactly as well: the rim data cannot tell the two apart,
and the global search took the flip.  The symmetric hub makes that flip a true symmetry.)

The scan is drawn independently of the project's sampler and simulator: OpenCASCADE's
tessellation (0.001 mm deflection), sampled uniformly by area at 0.02 mm, kept only on the
rim -- the tooth tops outside the root circle, and the flanks, tips and root arcs in the top
0.3 mm of the face width -- in random order, displaced along the normal by a smooth form
deviation (ovality, three lobes and a tooth-wise term: 13 um RMS, up to 35 um) and 1 um noise,
and moved by a random rigid motion.  It is placed from no start.

Measured (seed 3, 33k points): placed 0.08 deg / 0.006 mm from a symmetric copy; the seen faces
are the 76 tooth faces and one flat face (the hub, the bore and the other flat face are not
seen; 41 % of the part's area), of which the scan covers 36 %; of the whole part 15 %, under the
20 % needed for a verdict.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import shapeverify as sv
from independent_scans import random_points, tessellate
from shapeverify.inspection import inspect_registered

pytestmark = pytest.mark.slow

#: teeth, module (mm), face width (mm), bore radius, hub radius, hub length each side (mm)
TEETH, MODULE, THICK, BORE, HUB_R, HUB_LEN = 19, 0.25, 1.0, 0.8, 1.4, 1.25
#: tooth half-widths at the tip and at the root circle, in pitches
TIP_HALF, ROOT_HALF = 0.15, 0.32
RA, RF = MODULE * TEETH / 2 + MODULE, MODULE * TEETH / 2 - 1.25 * MODULE
#: the rim band the scan sees: the top BAND mm of the tooth faces
BAND = 0.3


def gear_shape():
    """The gear proxy (module docstring) as an OpenCASCADE solid, the teeth at |z| < THICK/2."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
    from OCP.BRepBuilderAPI import (BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace,
                                    BRepBuilderAPI_MakeWire)
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder, BRepPrimAPI_MakePrism
    from OCP.GC import GC_MakeArcOfCircle, GC_MakeSegment
    from OCP.gp import gp_Ax2, gp_Circ, gp_Dir, gp_Pnt, gp_Vec

    p, h = 2 * np.pi / TEETH, THICK / 2
    ax = gp_Ax2(gp_Pnt(0, 0, -h), gp_Dir(0, 0, 1))

    def pt(r, a):
        return gp_Pnt(float(r * np.cos(a)), float(r * np.sin(a)), -h)

    def arc(r, a0, a1):
        return GC_MakeArcOfCircle(gp_Circ(ax, r), float(a0), float(a1), True).Value()

    wire = BRepBuilderAPI_MakeWire()
    for k in range(TEETH):
        c = k * p
        for curve in (arc(RF, c - (1 - ROOT_HALF) * p, c - ROOT_HALF * p),
                      GC_MakeSegment(pt(RF, c - ROOT_HALF * p), pt(RA, c - TIP_HALF * p)).Value(),
                      arc(RA, c - TIP_HALF * p, c + TIP_HALF * p),
                      GC_MakeSegment(pt(RA, c + TIP_HALF * p), pt(RF, c + ROOT_HALF * p)).Value()):
            wire.Add(BRepBuilderAPI_MakeEdge(curve).Edge())
    body = BRepPrimAPI_MakePrism(BRepBuilderAPI_MakeFace(wire.Wire()).Face(),
                                 gp_Vec(0, 0, THICK)).Shape()
    hub = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, -h - HUB_LEN), gp_Dir(0, 0, 1)), HUB_R,
                                   2 * HUB_LEN + THICK).Shape()
    body = BRepAlgoAPI_Fuse(body, hub).Shape()
    bore = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, -h - HUB_LEN - 1), gp_Dir(0, 0, 1)),
                                    BORE, THICK + 2 * HUB_LEN + 2).Shape()
    return BRepAlgoAPI_Cut(body, bore).Shape()


@pytest.fixture(scope="module")
def gear(tmp_path_factory):
    """(prepared model read from STEP, tessellation V, T)."""
    from shapeverify.cad.examples import _write_step

    shape = gear_shape()
    path = _write_step(shape, tmp_path_factory.mktemp("gear") / "gear19.step", "gear proxy")
    V, T, _ = tessellate(shape, 0.001)
    return sv.prepare(sv.load_model(path), spacing=0.03), V, T


def rim_scan(V, T, seed, dent=None, form=0.015, noise=0.001, spacing=0.02):
    """The rim-only scan (module docstring): (scan, T_model_scan, points and normals in the model
    frame before the form deviation).  ``dent`` = (centre, radius, depth): a smooth dent into
    the material, ``depth cos^2(pi r / 2 radius)``."""
    rng = np.random.default_rng(seed)
    P, N = random_points(V, T, spacing, rng)
    r, h = np.hypot(P[:, 0], P[:, 1]), THICK / 2
    top = (N[:, 2] > 0.99) & (P[:, 2] > h - 1e-6) & (r > RF)
    teeth = (np.abs(N[:, 2]) < 0.01) & (r > RF - 0.01) & (P[:, 2] > h - BAND)
    P, N = P[top | teeth], N[top | teeth]
    th, ph = np.arctan2(P[:, 1], P[:, 0]), rng.uniform(0, 2 * np.pi, 3)
    dev = form * (np.cos(2 * th + ph[0]) + 0.6 * np.cos(3 * th + ph[1])
                  + 0.4 * np.sin(TEETH * th + ph[2]))
    if dent is not None:
        c, rad, depth = dent
        d = np.linalg.norm(P - c, axis=1)
        dev = dev - depth * np.cos(0.5 * np.pi * np.minimum(d / rad, 1.0)) ** 2
    X = P + (dev + rng.normal(0.0, noise, len(P)))[:, None] * N
    M = np.eye(4)
    M[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    v = rng.normal(size=3)
    M[:3, 3] = 20.0 * v / np.linalg.norm(v)
    return X @ M[:3, :3].T + M[:3, 3], np.linalg.inv(M), P, N


def pose_error(T_found, T_true):
    """(deg, mm at the gear's tip circle) to the nearest of the 38 equally right poses."""
    D = np.asarray(T_found) @ np.linalg.inv(T_true)          # model -> model: a symmetry
    best = (np.inf, np.inf)
    for k in range(2 * TEETH):
        S = Rotation.from_rotvec([0.0, 0.0, 2 * np.pi * k / TEETH]).as_matrix()
        if k >= TEETH:
            S = S @ np.diag([1.0, -1.0, -1.0])                # upside down
        ang = np.degrees(np.linalg.norm(Rotation.from_matrix(S.T @ D[:3, :3]).as_rotvec()))
        tip = np.array([[RA, 0, 0], [0, RA, 0], [-RA, 0, 0], [0, -RA, 0]], float)
        move = np.max(np.linalg.norm(tip @ D[:3, :3].T + D[:3, 3] - tip @ S.T, axis=1))
        best = min(best, (ang, move))
    return best


@pytest.fixture(scope="module")
def good(gear):
    prep, V, T = gear
    scan, T_true, P, N = rim_scan(V, T, seed=3)
    return scan, T_true, P, N, sv.inspect(prep, scan, tolerance=0.05, faces="seen")


def test_good_gear_rim_scan_passes_limited_to_the_faces_it_saw(gear, good):
    prep = gear[0]
    scan, T_true, _, _, res = good
    ang, move = pose_error(res.registration.T_model_scan, T_true)
    assert ang < 0.2 and move < 0.01, (ang, move)         # a right pose, up to the 38 copies
    assert str(res.verdict) == "pass", res.reasons
    # the seen faces: the 76 tooth faces (flanks, tips, root arcs) and the gear's flat face on
    # the side the scan was placed (the top, or the bottom for a flipped copy); not the hub, the
    # bore or the other flat face.  Faces told apart by their model points.
    P, F = np.asarray(prep.points.points), np.asarray(prep.points.face)
    r = np.hypot(P[:, 0], P[:, 1])
    faces = np.unique(F)
    tooth = {int(f) for f in faces if r[F == f].min() > RF - 1e-3}
    flat = [int(f) for f in faces if np.ptp(P[F == f, 2]) < 1e-6
            and abs(abs(P[F == f, 2][0]) - THICK / 2) < 1e-6]
    assert len(tooth) == 4 * TEETH and len(flat) == 2
    seen = set(res.coverage.faces)
    assert tooth <= seen and len(seen - tooth) == 1 and (seen - tooth) <= set(flat), seen
    assert any("faces the scan saw" in r and "not measured" in r for r in res.reasons)
    assert res.coverage.fraction >= 0.25, res.coverage


def test_gear_rim_scan_is_incomplete_when_the_whole_gear_is_inspected(gear, good):
    scan, _, _, _, res = good
    whole = inspect_registered(gear[0], scan, res.registration, tolerance=0.05)
    assert str(whole.verdict) == "incomplete" and whole.rule == "coverage", whole.reasons
    assert whole.coverage.fraction < 0.18


def test_dented_flank_fails_limited_to_the_faces_it_saw(gear, good):
    prep, V, T = gear
    _, T_true, P, N, res = good
    # a point mid-flank (a planar tooth side: its normal is not radial), in the middle of the band
    radial = np.c_[P[:, :2], np.zeros(len(P))] / np.hypot(P[:, 0], P[:, 1])[:, None]
    flank = (np.abs(N[:, 2]) < 0.01) & (np.einsum("ij,ij->i", N, radial) < 0.95) \
        & (np.abs(np.hypot(P[:, 0], P[:, 1]) - 0.5 * (RA + RF)) < 0.03) \
        & (np.abs(P[:, 2] - (THICK / 2 - BAND / 2)) < 0.03)
    centre = P[np.flatnonzero(flank)[0]]
    scan, T_true2, _, _ = rim_scan(V, T, seed=3, dent=(centre, 0.12, 0.08))
    assert np.allclose(T_true2, T_true)
    dented = sv.inspect(prep, scan, tolerance=0.05, faces="seen",
                        init=res.registration.T_model_scan)
    assert str(dented.verdict) == "fail", dented.reasons
    assert len(dented.regions) == 1
    reg = dented.regions[0]
    D = np.asarray(dented.registration.T_model_scan) @ np.linalg.inv(T_true)  # a symmetry
    assert np.linalg.norm(np.asarray(reg.centroid) - (D[:3, :3] @ centre + D[:3, 3])) < 0.1
    assert -0.09 < reg.extreme < -0.06, reg
