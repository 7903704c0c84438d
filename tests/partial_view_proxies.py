"""Proxies of issue 30's held-back partial-view sets (made here, NOT the held-back data).

The held-back sets (depth-camera views of 10 objects, focus-variation rim scans of produced micro
gears, a structured-light ring scan of a turned part) are not on this machine.  These stand-ins
are built without the project's simulator (``shapeverify.simulate``): the scan points are drawn
uniformly by area on triangles (a mesh of our own, or OpenCASCADE's tessellation through
:mod:`independent_scans`), displaced along the triangle normal by a smooth form deviation and by
Gaussian noise, then put in a sensor frame by a seeded rigid motion.

* :func:`gear` -- a 19-tooth spur gear, tip diameter 5.25 mm, 1 mm thick (a mesh with a
  straight-flank tooth, the same for every tooth: its symmetry group is exactly D19, 38 copies,
  every one an equally right pose); :func:`gear_band` -- its toothed rim only: the top face
  outside the root circle and the upper 0.35 mm of the flanks, all round (``sector=None``) or a
  sector seen from one direction, noise 1 um, form deviation 10-20 um RMS (ovality, three-lobe
  and a tooth-wise term);
* :func:`turned_band` -- the bundled turned part (OpenCASCADE), a narrow ring band (z 12-32 mm,
  across the flange, the groove and the shaft), noise 0.02 mm, ovality 0.01 mm; every spin about
  its axis is an equally right pose;
* :func:`box_view` / :func:`panel_view` -- a 100 x 60 x 40 mm box (OpenCASCADE; 4 copies) and
  the bundled example panel, seen from one side like a depth camera: only the faces facing the
  sensor (normal . view > 0.15), depth noise 1-1.5 mm along the view, 1 % outliers;
* :func:`bunny` -- the Stanford bunny: each of the real partial views bun000/045/090 (in mm)
  against the merged cloud of the other two (the bun.conf poses) as the reference.
"""
from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from independent_scans import random_points, tessellate

#: the gear: teeth, module (mm), thickness (mm), bore radius (mm)
TEETH, MODULE, THICK, BORE = 19, 0.25, 1.0, 0.8
#: tooth half-widths at the tip and at the root, in pitches
TIP_HALF, ROOT_HALF = 0.15, 0.32


def _rz(phi):
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def gear_outline(step: float = 0.02) -> np.ndarray:
    """(n, 2) the gear's outline, counter-clockwise, strictly increasing polar angle."""
    p = 2 * np.pi / TEETH
    ra, rf = MODULE * TEETH / 2 + MODULE, MODULE * TEETH / 2 - 1.25 * MODULE
    corners = []       # one pitch: root arc, rising flank, tip arc, falling flank
    for a, r in ((-0.5, rf), (-ROOT_HALF, rf), (-TIP_HALF, ra), (TIP_HALF, ra), (ROOT_HALF, rf)):
        corners.append((a * p, r))
    pts = []
    for k in range(TEETH):
        seq = corners + [(0.5 * p, rf)]
        for (a0, r0), (a1, r1) in zip(seq[:-1], seq[1:]):
            length = np.hypot(r1 - r0, 0.5 * (r0 + r1) * (a1 - a0))
            m = max(2, int(np.ceil(length / step)))
            s = np.arange(m) / m
            a, r = a0 + s * (a1 - a0) + k * p, r0 + s * (r1 - r0)
            pts.append(np.c_[r * np.cos(a), r * np.sin(a)])
    return np.vstack(pts)


def gear_mesh(step: float = 0.02):
    """(V, T) a closed, outward-wound triangle mesh of the gear (z from -THICK/2 to THICK/2)."""
    O = gear_outline(step)
    n = O.shape[0]
    ang = np.arctan2(O[:, 1], O[:, 0])
    B = BORE * np.c_[np.cos(ang), np.sin(ang)]
    h = THICK / 2
    V = np.vstack([np.c_[O, np.full(n, -h)], np.c_[O, np.full(n, h)],
                   np.c_[B, np.full(n, -h)], np.c_[B, np.full(n, h)]])
    i = np.arange(n)
    j = (i + 1) % n
    ob, ot, bb, bt = i, i + n, i + 2 * n, i + 3 * n
    jb, jt, kb, kt = j, j + n, j + 2 * n, j + 3 * n
    T = np.vstack([
        np.c_[ob, jb, jt], np.c_[ob, jt, ot],        # outer side (outward)
        np.c_[bb, bt, kt], np.c_[bb, kt, kb],        # bore (towards the axis)
        np.c_[ot, jt, kt], np.c_[ot, kt, bt],        # top (+z)
        np.c_[ob, bb, kb], np.c_[ob, kb, jb],        # bottom (-z)
    ])
    return V, T.astype(np.int64)


def gear_model():
    from shapeverify.cad.model import Model

    V, T = gear_mesh()
    return Model(faces=(), unit="mm", scale_to_mm=1.0, source="gear proxy (19 teeth)",
                 kind="mesh", vertices=V, triangles=T.astype(np.int32))


def gear_copies():
    """The gear's 38 symmetries (4, 4): spins by a pitch, and the flip about x."""
    F = np.diag([1.0, -1.0, -1.0, 1.0])
    out = []
    for k in range(TEETH):
        S = np.eye(4)
        S[:3, :3] = _rz(2 * np.pi * k / TEETH)
        out += [S, S @ F]
    return out


def spin_copies(step_deg: float = 0.25):
    """Spins about z (a turned part): every one an equally right pose."""
    out = []
    for a in np.radians(np.arange(0.0, 360.0, step_deg)):
        S = np.eye(4)
        S[:3, :3] = _rz(a)
        out.append(S)
    return out


def box_copies():
    return [np.diag(d + (1.0,)) for d in ((1.0, 1.0, 1.0), (1.0, -1.0, -1.0),
                                         (-1.0, 1.0, -1.0), (-1.0, -1.0, 1.0))]


def _sensor_motion(rng, distance):
    """A random T_sensor_model: any rotation, the part ``distance`` away."""
    M = np.eye(4)
    M[:3, :3] = Rotation.random(random_state=int(rng.integers(2 ** 31))).as_matrix()
    v = rng.normal(size=3)
    M[:3, 3] = distance * v / np.linalg.norm(v)
    return M


def _to_sensor(P, M):
    """(scan in the sensor frame, T_model_scan)."""
    return P @ M[:3, :3].T + M[:3, 3], np.linalg.inv(M)


def gear_band(seed: int, sector: float | None = None, spacing: float = 0.015,
              noise: float = 0.001, form: float = 0.012):
    """A rim-only band scan of :func:`gear_mesh` (module docstring): (scan, T_model_scan,
    form RMS mm).  ``sector`` (deg): only that arc of the rim, faces facing its view."""
    rng = np.random.default_rng(seed)
    V, T = gear_mesh()
    n = V.shape[0] // 4
    side = np.arange(2 * n)                        # outer side and top triangles
    P, N = random_points(V, T, spacing, rng, tris=np.r_[side, np.arange(4 * n, 6 * n)])
    rf = MODULE * TEETH / 2 - 1.25 * MODULE
    r = np.hypot(P[:, 0], P[:, 1])
    top = N[:, 2] > 0.9
    keep = (top & (r > rf - 0.15)) | (~top & (np.abs(N[:, 2]) < 0.1)
                                       & (P[:, 2] > THICK / 2 - 0.35))
    theta = np.arctan2(P[:, 1], P[:, 0])
    if sector is not None:
        c = rng.uniform(-np.pi, np.pi)
        keep &= np.abs(np.angle(np.exp(1j * (theta - c)))) < np.radians(sector) / 2
        view = np.array([np.cos(c), np.sin(c), 1.0]) / np.sqrt(2.0)
        keep &= N @ view > 0.15
    P, N, theta = P[keep], N[keep], theta[keep]
    ph = rng.uniform(0, 2 * np.pi, 3)
    dev = (form * np.cos(2 * theta + ph[0]) + 0.6 * form * np.cos(3 * theta + ph[1])
           + 0.4 * form * np.sin(TEETH * theta + ph[2]))
    P = P + (dev + rng.normal(0.0, noise, P.shape[0]))[:, None] * N
    S, Tms = _to_sensor(P, _sensor_motion(rng, 20.0))
    return S, Tms, float(np.sqrt(np.mean(dev ** 2)))


_SHAPES: dict = {}


def _occ(name):
    """(model, tessellation V, T, face) of an OpenCASCADE proxy part, built once."""
    if name in _SHAPES:
        return _SHAPES[name]
    from shapeverify.cad import examples
    from shapeverify.cad.load import load_model

    d = Path(tempfile.mkdtemp())
    if name == "turned":
        shape = examples.turned_part_shape()
    elif name == "panel":
        shape = examples.panel_shape()
    else:
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
        from OCP.gp import gp_Pnt

        shape = BRepPrimAPI_MakeBox(gp_Pnt(-50, -30, -20), gp_Pnt(50, 30, 20)).Shape()
    path = examples._write_step(shape, d / f"{name}.step", f"proxy {name}")
    V, T, F = tessellate(shape, 0.02)
    _SHAPES[name] = (load_model(path), V, T, F)
    return _SHAPES[name]


def turned_model():
    return _occ("turned")[0]


def turned_band(seed: int, spacing: float = 0.5, noise: float = 0.02, ovality: float = 0.01):
    """A narrow ring band (z 12-32 mm) of the turned part, all round for even seeds, the half
    facing one direction for odd ones: (scan, T_model_scan)."""
    rng = np.random.default_rng(seed)
    _, V, T, _ = _occ("turned")
    P, N = random_points(V, T, spacing, rng)
    r = np.hypot(P[:, 0], P[:, 1])
    keep = (P[:, 2] > 12.0) & (P[:, 2] < 32.0) & (r > 20.0)
    if seed % 2:
        a = rng.uniform(-np.pi, np.pi)
        keep &= N @ np.array([np.cos(a), np.sin(a), 0.3]) > 0.1
    P, N = P[keep], N[keep]
    th = np.arctan2(P[:, 1], P[:, 0])
    dev = ovality * np.cos(2 * th + rng.uniform(0, 2 * np.pi))
    P = P + (dev + rng.normal(0.0, noise, P.shape[0]))[:, None] * N
    return _to_sensor(P, _sensor_motion(rng, 400.0))


def _depth_view(name, seed, spacing, noise, outliers=0.01, min_up=None):
    rng = np.random.default_rng(seed)
    model, V, T, _ = _occ(name)
    while True:
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        if min_up is None or v[2] > min_up:
            break
    P, N = random_points(V, T, spacing, rng)
    keep = N @ v > 0.15
    P = P[keep] + rng.normal(0.0, noise, (int(keep.sum()), 1)) * v
    k = int(outliers * P.shape[0])
    lo, hi = P.min(axis=0), P.max(axis=0)
    P = np.vstack([P, rng.uniform(lo, hi, (k, 3))])
    # the sensor looks along -v from 600 mm: its frame has z along -v
    R = Rotation.align_vectors([[0, 0, -1.0]], [v])[0].as_matrix()
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = np.array([0, 0, 600.0]) - R @ P.mean(axis=0)
    return _to_sensor(P, M)


def box_model():
    return _occ("box")[0]


def box_view(seed: int):
    """One side of the 100 x 60 x 40 mm box (2-3 faces), depth noise 1.5 mm."""
    return _depth_view("box", seed, 2.0, 1.5)


def panel_model():
    return _occ("panel")[0]


def panel_view(seed: int):
    """The example panel seen from above (view z > 0.5), depth noise 1 mm."""
    return _depth_view("panel", seed, 2.0, 1.0, min_up=0.5)


def _bunny_pose(d, name):
    for line in (d / "bun.conf").read_text().splitlines():
        f = line.split()
        if len(f) == 9 and f[0] == "bmesh" and f[1] == name:
            R = Rotation.from_quat(np.array(f[5:9], float)).as_matrix()
            M = np.eye(4)
            M[:3, :3], M[:3, 3] = R.T, np.array(f[2:5], float) * 1000.0
            return M


BUNNY_VIEWS = ("bun000.ply", "bun045.ply", "bun090.ply")


def bunny(data: Path):
    """{view name: (points in its own frame mm, T_model_view, reference Model)}: each view's
    reference is the merged cloud of the OTHER two views in bun000's frame (mm), so the view
    overlaps it only in part and none of its points is in it."""
    from shapeverify.cad.load import load_model
    from shapeverify.io.points import read_points

    d = data / "scans" / "bunny"
    base = np.linalg.inv(_bunny_pose(d, "bun000.ply"))
    raw = {}
    for name in BUNNY_VIEWS:
        P = read_points(d / name) * 1000.0
        T = base @ _bunny_pose(d, name)
        raw[name] = (P, T, P @ T[:3, :3].T + T[:3, 3])
    ref = load_model(d / "bun000.ply")
    out = {}
    for name in BUNNY_VIEWS:
        merged = np.vstack([raw[o][2] for o in BUNNY_VIEWS if o != name])
        out[name] = (raw[name][0], raw[name][1],
                     dataclasses.replace(ref, vertices=merged, cloud_normals=None))
    return out


def bunny_view(views, name, seed):
    """The view ``name`` in a random sensor frame: (scan, T_model_scan)."""
    P, T = views[name][:2]
    rng = np.random.default_rng(seed)
    M = _sensor_motion(rng, 500.0)
    return P @ M[:3, :3].T + M[:3, 3], T @ np.linalg.inv(M)
