"""Monte-Carlo runs for the check that the stated U (k = 2) covers the error (issue 27 item 6).

Each run makes a scan independently of the project's sampler (:mod:`independent_scans`:
OpenCASCADE's tessellation sampled uniformly by area, 0.02 mm noise along the normal), and
measures it as an inspection plan does.  The *error* is the measured value minus the part's
true value: 0 for a perfect part's profile, flatness and hole position; the nominal diameter;
for a known dent of depth ``delta`` (a smooth bump on the face, :func:`independent_scans.bump`)
the profile's true value is ``2 |delta|`` and the flatness's ``|delta|``.  A run *covers* when
``|error| <= U``.

Cases (one run = one independent scan):

``panel``   the bundled panel (a sheet: its Ø36 hole is seen only at its rim), 1 mm, random pose,
            ``best_fit`` plan: hole diameter, hole position, profile of all faces; every other
            run with a dent of -0.15 mm on the sheet.
``panelhole`` the panel's hole alone at the true pose, random and grid sampling (rim only).
``sheet9``  a Ø9 hole in a flat sheet (rim only), numpy random and grid sampling, 1 mm.
``plate``   the chamfered plate (100 x 60 x 5 mm), 1 mm, random pose, ``best_fit`` plan:
            flatness of the top face, profile of all faces; every other run a dent of +0.1 mm
            on the top.
``ctc01``   NIST CTC 01 (``../shared/data``), the Ø20 side-wall hole (``hole:11``), the Ø25
            and Ø35 top holes (``hole:3``, ``hole:7``): a region scan at the true pose, 1 mm,
            by area (the wall is seen) or by a raster of rays along the axis (rim only).
"""
from __future__ import annotations

import numpy as np

import independent_scans as isc

NOISE = 0.02
SPACING = 1.0


def _random_pose(rng, shift=100.0):
    from scipy.spatial.transform import Rotation

    R = Rotation.random(random_state=rng).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, rng.uniform(-shift, shift, 3)
    return T                                 # scan = R @ model + t


def _apply(T, P):
    return P @ T[:3, :3].T + T[:3, 3]


class Panel:
    """The bundled example panel, with its plan."""

    name = "panel"

    def __init__(self, workdir):
        from shapeverify.cad.examples import PANEL_HOLE, example_part_step

        path = example_part_step(workdir / "panel.step")
        from model_cache import cached_prepared

        self.prep = cached_prepared(path, spacing=1.0)  # built once per run (tests/model_cache.py)
        shape = isc.read_shape(path)
        self.V, self.T, self.F = isc.tessellate(shape, 0.005)
        x, y, r = PANEL_HOLE
        self.hole = (x, y, r)
        self.plan = {"alignment": {"type": "best_fit"}, "characteristics": [
            {"name": "H1", "type": "hole", "near": [x, y, 0], "diameter": {"tol": 0.5},
             "position": {"tol": 0.6}},
            {"name": "SKIN", "type": "surface_profile", "faces": "all", "tol": 0.4}]}
        from shapeverify.cad.examples import panel_height

        self.dent_at = np.array([80.0, 60.0, float(panel_height(80.0, 60.0))])

    def run(self, seed):
        from shapeverify.characteristics import evaluate_plan

        rng = np.random.default_rng(seed)
        depth = -0.15 if seed % 2 else 0.0
        dents = [(self.dent_at, depth, 12.0)] if depth else ()
        P = isc.scan(self.V, self.T, "random", SPACING, rng, noise=NOISE, dents=dents)
        Tp = _random_pose(rng)
        res = evaluate_plan(self.prep, _apply(Tp, P), self.plan, rng=seed)
        h, s = res["H1"], res["SKIN"]
        x, y, r = self.hole
        return [("hole diameter (rim only)", h.deviation["diameter"], h.uncertainty["diameter"]),
                ("hole position (rim only)", h.deviation["position"], h.uncertainty["position"]),
                ("profile", s.measured - 2 * abs(depth), s.uncertainty)], _pose_err(res, Tp)


class PanelHole:
    """The bundled panel's Ø36 hole (rim only) at the true pose: random and grid sampling."""

    name = "panelhole"

    def __init__(self, workdir):
        from shapeverify.cad.examples import example_part_step
        from shapeverify.characteristics.features import model_features

        path = example_part_step(workdir / "panel.step")
        from model_cache import cached_prepared

        self.prep = cached_prepared(path, spacing=1.0)  # built once per run (tests/model_cache.py)
        V, T, _ = isc.tessellate(isc.read_shape(path), 0.005)
        f = [g for g in model_features(self.prep.model) if g.kind == "hole"][0]
        near = np.linalg.norm(V[T].mean(axis=1)[:, :2] - f.center[:2], axis=1) < \
            0.5 * f.diameter + 30.0
        self.V, self.T, self.f = V, T[near], f

    def run(self, seed):
        from shapeverify.characteristics.holes import measure_hole, position_coverage

        f, out = self.f, []
        rng = np.random.default_rng(seed)
        for sampler in ("random", "grid"):
            X = isc.scan(self.V, self.T, sampler, SPACING, rng, noise=NOISE)
            cl = self.prep.closest(X, exact=True)
            hm = measure_hole(X, f.center, f.axis, f.diameter, face=self.prep.model.faces[f.face],
                              deviations=cl.distances, normals=cl.normals)
            d = hm.center - f.center
            pos = float(np.linalg.norm(d - (d @ f.axis) * f.axis))
            out.append((f"panel Ø36 diameter (rim only, {sampler})", hm.diameter - f.diameter,
                        2.0 * hm.u_diameter))
            out.append((f"panel Ø36 position (rim only, {sampler})", 2.0 * pos,
                        2.0 * position_coverage(2.0) * hm.u_center))
        return out, None


class Sheet9:
    """A Ø9 hole in a flat sheet seen only at its rim (issue 27 item 1: a 9 mm hole at 1 mm
    read U 7x its error): numpy sampling, uniform random or a square grid at a random angle and
    phase, 1 mm, 0.02 mm noise, the hole's centre at random within 0.3 mm of the nominal."""

    name = "sheet9"

    def __init__(self, workdir=None):
        pass

    def run(self, seed):
        from shapeverify.characteristics.holes import measure_hole, position_coverage

        rng = np.random.default_rng(seed)
        r0, half, out = 4.5, 4.5 + 23.0, []
        for sampler in ("random", "grid"):
            c = rng.uniform(-0.3, 0.3, 2)
            if sampler == "random":
                xy = rng.uniform(-half, half, (rng.poisson((2 * half / SPACING) ** 2), 2))
            else:
                g = np.arange(-half, half, SPACING)
                xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
                th = rng.uniform(0, np.pi)
                xy = xy @ np.array([[np.cos(th), np.sin(th)], [-np.sin(th), np.cos(th)]]) + \
                    rng.uniform(0, SPACING, 2)
            xy = xy[np.hypot(*(xy - c).T) > r0]
            P = np.column_stack([xy, rng.normal(0, NOISE, len(xy))])[rng.permutation(len(xy))]
            hm = measure_hole(P, [0, 0, 0], [0, 0, 1], 2 * r0)
            out.append((f"sheet Ø9 diameter (rim only, {sampler})", hm.diameter - 2 * r0,
                        2.0 * hm.u_diameter))
            out.append((f"sheet Ø9 position (rim only, {sampler})",
                        2.0 * float(np.hypot(*(hm.center[:2] - c))),
                        2.0 * position_coverage(2.0) * hm.u_center))
        return out, None


class Plate:
    """The chamfered example plate: flatness of its top, profile of all faces."""

    name = "plate"

    def __init__(self, workdir):
        from shapeverify.cad.examples import chamfered_plate_step

        path = chamfered_plate_step(workdir / "plate.step")
        from model_cache import cached_prepared

        self.prep = cached_prepared(path, spacing=1.0)  # built once per run (tests/model_cache.py)
        self.V, self.T, self.F = isc.tessellate(isc.read_shape(path), 0.005)
        self.plan = {"alignment": {"type": "best_fit"}, "characteristics": [
            {"name": "FLAT", "type": "flatness", "feature": "face:2", "tol": 0.2},
            {"name": "SKIN", "type": "surface_profile", "faces": "all", "tol": 0.4}]}
        # the top face (z = 5) has the largest z: the dent's site at its middle
        self.dent_at = np.array([40.0, 30.0, 5.0])

    def run(self, seed):
        from shapeverify.characteristics import evaluate_plan

        rng = np.random.default_rng(seed)
        depth = 0.1 if seed % 2 else 0.0
        dents = [(self.dent_at, depth, 10.0)] if depth else ()
        P = isc.scan(self.V, self.T, "random", SPACING, rng, noise=NOISE, dents=dents)
        Tp = _random_pose(rng)
        res = evaluate_plan(self.prep, _apply(Tp, P), self.plan, rng=seed)
        f, s = res["FLAT"], res["SKIN"]
        return [("flatness", f.measured - abs(depth), f.uncertainty),
                ("profile", s.measured - 2 * abs(depth), s.uncertainty)], _pose_err(res, Tp)


class Ctc01Holes:
    """Holes of NIST CTC 01 from region scans at the true pose."""

    name = "ctc01"
    HOLES = ("hole:11", "hole:3", "hole:7")

    def __init__(self, path):
        import shapeverify as sv
        from shapeverify.cad.occ_import import read_cad
        from shapeverify.characteristics.features import model_features

        import test_holes_nist as t

        self.t = t
        model = read_cad(path, isolated=False)
        self.feats = {f.id: f for f in model_features(model)}
        self.prep = sv.prepare(model)
        V, T = t.tessellation(path)
        self.V = V
        self.regions = {h: t._region(V, T, self.feats[h].center, self.feats[h].diameter + 25.0)
                        for h in self.HOLES}

    def run(self, seed):
        from shapeverify.characteristics.holes import position_coverage

        t = self.t
        rng = np.random.default_rng(seed)
        out = []
        for h in self.HOLES:
            f = self.feats[h]
            for kind in ("area", "grid"):
                X = (t.area_scan(self.V, self.regions[h], SPACING, rng) if kind == "area" else
                     t.grid_scan(self.V, self.regions[h], SPACING, f.axis, f.center,
                                 0.5 * f.diameter + 20.0, rng))
                hm = t.measure(self.prep, f, X)
                dd, pos = t.errors(self.prep, f, hm)
                what = "wall" if kind == "area" else "rim only"
                # U as the plan states it (no pose term at the true pose): diameter k u_D,
                # position value 2 |offset| against 2 k_2D u_c
                out.append((f"CTC01 {h} Ø{f.diameter:g} diameter ({what})", dd,
                            2.0 * hm.u_diameter))
                out.append((f"CTC01 {h} Ø{f.diameter:g} position ({what})", 2.0 * pos,
                            2.0 * position_coverage(2.0) * hm.u_center))
        return out, None


def _pose_err(res, T_scan_model):
    """(degrees, mm) between the plan's pose and the true one."""
    from shapeverify.registration.rigid import pose_error

    e = pose_error(res.alignment.T_model_scan, np.linalg.inv(T_scan_model))
    return float(np.degrees(np.linalg.norm(e[:3]))), float(np.linalg.norm(e[3:]))


def min_coverage_count(runs: int, p: float = 0.95, alpha: float = 0.01) -> int:
    """Fewest covering runs of ``runs`` a check accepts: the ``alpha`` lower quantile of the
    binomial number of covering runs when U covers with probability ``p`` (so a right U
    fails the check with probability below ``alpha``; a U that covers far less is caught)."""
    from scipy.stats import binom

    return int(binom.ppf(alpha, runs, p))
