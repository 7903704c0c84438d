"""Issue 28, "How good": the plan generated from a NIST AP242 file's semantic PMI, run on an
independent scan of the part -- a perfect part, one hole moved 0.3 mm, one face tilted 0.2 deg.

The scan is made without the project's sampler (``tests/independent_scans.py``):
OpenCASCADE's tessellation (``BRepMesh_IncrementalMesh``, deflection 0.001 mm), points uniform
by triangle area (one per ``spacing^2``), 0.02 mm Gaussian noise along the triangle normal,
random order, then a random rigid pose.  The defects are put on the scan points by the face
each point was drawn on (OpenCASCADE's face index = the model's ``face:i``):

* **moved hole**: every point of one hole's faces (a feature of a position tolerance, not a
  datum feature; the holes with the smallest zone first; a part with no hole position: the
  faces of a width a planes-zone position locates, moved along their normal) translated
  0.3 mm across the hole's axis (the hole moved; its rim's intersection with the surrounding
  face is off by 0.3 mm, nothing else changes);
* **tilted face**: every point of one planar face (else: a cylinder, its axis tilted about a
  line across it through its centroid) that carries an orientation tolerance
  (parallelism / perpendicularity / angularity; a datum feature only when no other face has
  one) rotated 0.2 deg about the face's centroid, about the in-plane axis ``n x a`` (``a`` the
  primary datum's direction: the tilt changes the angle to the datum -- a wall perpendicular
  to A turned about A's normal is still perpendicular to A; a face parallel to its datum:
  about its shorter in-plane principal direction), so the orientation error is ``L tan 0.2
  deg`` with ``L`` the face's extent across that axis; the face picked is the one where that
  is largest against its zone.

Each characteristic that does not pass is listed with its relation to the defect:
'expected' (its zone is smaller than the defect), 'defect faces' (it measures the moved
faces), 'datum moved' (its DRF uses them), 'other' (it should not have noticed).

The scan is inspected as ``shapeverify inspect --plan`` inspects it (:func:`shapeverify.inspect`
with ``plan=``: a free registration from any pose, then the plan's datum alignment, then every
characteristic).  With ``--init`` the true pose is given instead (faster; the registration is
then not part of the check).

Command (one heavy case at a time; CTC 02 at 1 mm is ~2.5 M points)::

    PYTHONPATH=src .venv/bin/python benchmarks/check_nist_plans.py            # all, 1 mm
    PYTHONPATH=src .venv/bin/python benchmarks/check_nist_plans.py --quick    # FTC 08 + CTC 01, 2 mm (1 on small faces)
    PYTHONPATH=src .venv/bin/python benchmarks/check_nist_plans.py --files nist_ctc_02_asme1_ap242-e1.stp --spacing 1.5

Writes a Markdown table per file (stdout, and ``--out``) and the raw results as JSON
(``--json``).  The pose error is given against the true pose (rotation, translation) and off the
part's symmetries (how far the estimated pose moves 20,000 scan points off the CAD surface
against the true pose: a ring turned about its own axis is 0).  ``--files`` takes absolute paths
too (the bundled ``tests/data/nist_extra/*.stp.gz``, gunzipped).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

DATA = Path("/work/shared/data/cad/nist")
FILES = ("nist_ftc_08_asme1_ap242-e1.stp", "nist_ctc_01_asme1_ap242-e1.stp",
         "nist_ftc_06_asme1_ap242-e1.stp", "nist_ctc_02_asme1_ap242-e1.stp")
QUICK = FILES[:2]
ORIENTATION = ("parallelism", "perpendicularity", "angularity")
MOVE = 0.3                  # mm
TILT = 0.2                  # degrees
NOISE = 0.02                # mm
#: chord error of the tessellation (mm): at 0.01 a 5 mm hole's points lie ~0.007 mm inside
#: its wall (a diameter 0.013 small, the size of a hole's U): too coarse for a perfect part
DEFLECTION = 0.001
#: faces smaller than this (mm^2) get the ``--fine`` spacing
SMALL_FACE = 300.0


# ----------------------------------------------------------------------------- the part
def face_ids(items) -> list[int]:
    """``[i, ...]`` of ``['face:i', ...]`` (nested lists flattened)."""
    out = []
    for x in items or ():
        if isinstance(x, (list, tuple)):
            out += face_ids(x)
        elif isinstance(x, str) and x.startswith("face:"):
            out.append(int(x.split(":")[1]))
    return out


def datum_faces(data) -> set[int]:
    """Faces of every datum feature of the plan (its ``datums`` table and its alignment)."""
    out = set()
    for d in (data.get("datums") or {}).values():
        out |= set(face_ids(d.get("faces")))
        for t in d.get("targets") or ():
            out |= set(face_ids(t.get("faces") if isinstance(t, dict) else ()))
    a = data.get("alignment") or {}
    for k in ("primary", "secondary", "tertiary"):
        out |= set(face_ids([a.get(k)] if isinstance(a.get(k), str) else a.get(k)))
    return out


def char_faces(c, feats) -> set[int]:
    """Every face a characteristic measures (hole features: their walls)."""
    byid = {f.id: f for f in feats}
    out = set(face_ids(c.get("faces"))) | set(face_ids(c.get("features")))
    if isinstance(c.get("feature"), str):
        f = byid.get(c["feature"])
        if f is not None:
            out |= set(getattr(f, "walls", ()) or ()) | ({f.face} if f.kind != "hole" else set())
    return out


def position_tol(c) -> float | None:
    if c["type"] in ("position", "position_zone"):
        return float(c["tol"])
    if c["type"] == "hole" and c.get("position") is not None:
        return float(c["position"]["tol"])
    return None


def hole_groups(data, feats) -> list[tuple[str, list[int], np.ndarray]]:
    """``(characteristic, faces, motion direction)`` of every hole (or pin) a position tolerance locates
    and no datum uses; the holes with the smallest position zone first (a 0.3 mm move, a
    0.6 mm diameter zone, must fail it)."""
    byid = {f.id: f for f in feats}
    dat = datum_faces(data)
    out = []
    for c in data["characteristics"]:
        groups = []
        if c["type"] == "position":
            groups = [face_ids(g if isinstance(g, list) else [g]) for g in c.get("features") or ()]
            if not groups and c.get("faces"):
                groups = [face_ids(c["faces"])]
        elif c["type"] == "hole" and c.get("position") is not None:
            f = byid.get(c.get("feature"))
            if f is not None and getattr(f, "walls", ()):
                groups = [list(f.walls)]
        elif c["type"] == "position_zone" and c.get("zone") == "planes":
            # a width (slot, tab) located by a planes zone: it moves along its faces' normal
            g = face_ids(c.get("faces"))
            pl = [byid.get(f"face:{i}") for i in g]
            if g and all(f is not None and f.kind == "plane" for f in pl) and not set(g) & dat:
                n = np.asarray(pl[0].axis, float)
                out.append((c["name"], g, n))        # the motion: along the normal
            continue
        for g in groups:
            cyl = [byid.get(f"face:{i}") for i in g]
            cyl = [f for f in cyl if f is not None and f.kind == "cylinder"]
            if not g or not cyl or set(g) & dat:
                continue
            out.append((c["name"], g, tangent(np.asarray(cyl[0].axis, float))))  # across
    tol = {c["name"]: position_tol(c) for c in data["characteristics"]}

    def smallest(h):
        t = [tol[c["name"]] for c in data["characteristics"]
             if tol[c["name"]] is not None and set(h[1]) <= char_faces(c, feats)]
        return min(t, default=np.inf)
    return sorted(out, key=smallest)


def datum_direction(data, c, byid):
    """The direction of the characteristic's primary datum (a plane's normal, an axis's
    direction) from its faces' CAD features, or None."""
    used = c.get("datums") or []
    if isinstance(used, str):
        used = [used]
    for u in used[:1]:
        for i in face_ids(((data.get("datums") or {}).get(u) or {}).get("faces")):
            f = byid.get(f"face:{i}")
            if f is not None and f.axis is not None and f.kind in ("plane", "cylinder"):
                return np.asarray(f.axis, float)
    return None


def tilt_candidates(data, feats, V, T, F):
    """``(characteristic, face, centroid, normal, rotation axis, L tan(tilt) / tol, L)`` of
    every planar or cylindrical face an orientation tolerance controls (a cylinder: its axis
    tilted, ``L`` its length): faces no datum uses first, then the
    best ratio."""
    byid = {f.id: f for f in feats}
    dat = datum_faces(data)
    out = []
    for c in data["characteristics"]:
        if c["type"] not in ORIENTATION:
            continue
        for i in face_ids(c.get("faces")):
            f = byid.get(f"face:{i}")
            if f is None or f.kind not in ("plane", "cylinder"):
                continue
            X = V[np.unique(T[F == i])]
            if len(X) < 3:
                continue
            n = np.asarray(f.axis, float)
            c0 = X.mean(axis=0)
            Y = X - c0
            if f.kind == "cylinder":        # an axis tilted: about a line across it
                a = datum_direction(data, c, byid)
                axis = np.cross(n, a) if a is not None and np.linalg.norm(
                    np.cross(n, a)) > 0.1 else tangent(n)
                L = float(np.ptp(Y @ n))
                out.append((c["name"], i, c0, n, axis / np.linalg.norm(axis),
                            L * np.tan(np.radians(TILT)) / float(c["tol"]), L))
                continue
            Y -= np.outer(Y @ n, n)
            a = datum_direction(data, c, byid)
            if a is not None and np.linalg.norm(np.cross(n, a)) > 0.1:
                # the tilt must change the angle to the datum (a wall perpendicular to A turned
                # about A's normal is still perpendicular to A): about n x a
                axis = np.cross(n, a)
                axis /= np.linalg.norm(axis)
                L = float(np.ptp(Y @ np.cross(axis, n)))
            else:                                   # parallel to it: across the long side
                w, E = np.linalg.eigh(Y.T @ Y)
                long_dir = E[:, 2]
                L = float(np.ptp(Y @ long_dir))
                axis = np.cross(n, long_dir)
            tol = float(c["tol"])
            out.append((c["name"], i, c0, n, axis / np.linalg.norm(axis),
                        L * np.tan(np.radians(TILT)) / tol, L))
    # a face no datum uses first (a datum face tilted moves the frames of its datum's
    # characteristics too: the fallback when the orientation tolerance is on a datum face)
    out.sort(key=lambda r: (r[1] in dat, -r[5]))
    return out


def tangent(n) -> np.ndarray:
    """A unit vector perpendicular to ``n``."""
    d = np.cross(n, [1.0, 0.0, 0.0])
    if np.linalg.norm(d) < 0.5:
        d = np.cross(n, [0.0, 1.0, 0.0])
    return d / np.linalg.norm(d)


def rotate_about(P, centre, axis, deg):
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(np.radians(deg) * axis).as_matrix()
    return (P - centre) @ R.T + centre


# ----------------------------------------------------------------------------- one run
def verdict_rows(res, data=None, feats=None, defect=None) -> dict:
    """Each characteristic's verdict, limits, U; ``relation`` to the defect: 'expected' (a
    position / orientation tolerance of the defect's faces whose zone the defect exceeds),
    'defect faces' (another characteristic of those faces), else 'other'."""
    chars = {c["name"]: c for c in (data or {}).get("characteristics", ())}
    rows = {}
    for c in res.characteristics:
        d = c.to_dict()
        rows[c.name] = {k: d[k] for k in ("type", "measured", "lower", "upper", "uncertainty",
                                          "verdict")}
        rows[c.name]["reason"] = (c.details or {}).get("reason")
        rel = "other"
        if defect and c.name in chars:
            cf = char_faces(chars[c.name], feats)
            g = set(defect.get("faces") or [defect.get("face")])
            dats = (data or {}).get("datums") or {}
            used = chars[c.name].get("datums") or []
            if isinstance(used, str):
                used = [used]
            if any(g & set(face_ids((dats.get(u) or {}).get("faces"))) for u in used):
                rel = "datum moved"
            if g & cf:
                rel = "defect faces"
                pt = position_tol(chars[c.name])
                # a located zone reads twice the move; a composite's lower segment floats:
                # over a pattern the best place splits the move (it reads MOVE), one feature
                # alone reads no location at all
                spread = 2 * MOVE
                if chars[c.name].get("composite") == "lower":
                    spread = MOVE if len(chars[c.name].get("features") or []) > 1 else 0.0
                if defect["kind"] == "hole" and pt is not None and spread > pt and g <= cf:
                    rel = "expected"
                if (defect["kind"] == "tilt" and c.type in ORIENTATION
                        and defect["length"] * np.tan(np.radians(TILT)) > chars[c.name]["tol"]):
                    rel = "expected"
        rows[c.name]["relation"] = rel
    return rows


def inspect_case(prep, plan, P, rng, given_pose: bool, data=None, feats=None, defect=None):
    """The scan in a random pose, inspected with the plan: ``(rows, seconds, alignment)``."""
    import shapeverify as sv
    from scipy.spatial.transform import Rotation

    R = Rotation.random(random_state=rng).as_matrix()
    t = rng.uniform(-200, 200, 3)
    X = (P @ R.T + t)[rng.permutation(len(P))]
    T_ms = np.eye(4)
    T_ms[:3, :3], T_ms[:3, 3] = R.T, -R.T @ t
    t0 = time.process_time()
    res = sv.inspect(prep, X, plan=plan, init=T_ms if given_pose else None)
    sec = time.process_time() - t0
    pr = res.plan
    from shapeverify.registration.rigid import pose_error

    e = pose_error(pr.alignment.T_model_scan, T_ms)
    # the pose error off the part's symmetries: how far the estimated pose moves the points
    # off the CAD surface where the true pose puts them (a ring turned about its own axis: 0)
    T_rel = np.asarray(pr.alignment.T_model_scan, float) @ np.linalg.inv(T_ms)
    sub = P[np.random.default_rng(0).permutation(len(P))[:20000]]
    d0 = np.asarray(prep.closest(sub, exact=True).distances)
    d1 = np.asarray(prep.closest(sub @ T_rel[:3, :3].T + T_rel[:3, 3], exact=True).distances)
    al = {"kind": pr.alignment.kind, "rot_deg": float(np.degrees(np.linalg.norm(e[:3]))),
          "trans_mm": float(np.linalg.norm(e[3:])),
          "surface_mm": float(np.abs(d1 - d0).max()),
          "converged": pr.alignment.details.get("converged", True)}
    return verdict_rows(pr, data, feats, defect), sec, al


def run_file(name, spacing, seed, given_pose, only=None, fine=None, cached=False):
    """The cases of one file.  ``cached`` (the tests): the PMI, the model's features and the
    tessellation from tests/model_cache.py (bitwise what read_pmi, model_features and
    tessellate give, computed once per code version), so ``plan_cpu_s`` is not the plan's."""
    from independent_scans import file_tessellation, random_points, read_shape, tessellate
    from model_cache import cached_pmi, cached_prepared

    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.plan import load_plan
    from shapeverify.characteristics.pmi_plan import pmi_plan

    path = DATA / name
    t0 = time.process_time()
    prep = cached_prepared(path, features=cached)
    r = pmi_plan(path, model=prep.model, pmi=cached_pmi(path) if cached else None)
    data = r.data
    plan = load_plan(data)
    feats = model_features(prep.model)
    t_plan = time.process_time() - t0
    V, T, F = (file_tessellation(path, DEFLECTION) if cached
               else tessellate(read_shape(path), DEFLECTION))
    rng = np.random.default_rng(seed)
    P, N, t = random_points(V, T, spacing, rng, with_triangles=True)
    if fine is not None and fine < spacing:
        # small faces (holes' walls, narrow steps) at the density of ``fine``: the points a
        # spacing of ``fine`` adds there, uniform by area too
        a = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]), axis=1)
        small = np.flatnonzero(np.bincount(F, weights=a) < SMALL_FACE)
        tris = np.flatnonzero(np.isin(F, small))
        if tris.size:
            extra = 1.0 / np.sqrt(1.0 / fine ** 2 - 1.0 / spacing ** 2)
            P2, N2, t2 = random_points(V, T, extra, rng, tris=tris, with_triangles=True)
            P, N, t = np.vstack([P, P2]), np.vstack([N, N2]), np.concatenate([t, t2])
    face = F[t]
    P = P + rng.normal(0.0, NOISE, len(P))[:, None] * N
    out = {"file": name, "points": int(len(P)), "noise": NOISE, "seed": seed,
           "deflection": DEFLECTION,
           "spacing": spacing if fine is None else f"{spacing} ({fine} on faces < {SMALL_FACE:g} mm2)",
           "plan_cpu_s": t_plan,
           "characteristics": len(data["characteristics"]),
           "unsupported": len(data.get("unsupported") or ()), "cases": {}}
    cases = [("perfect", P, None)]
    holes = hole_groups(data, feats)
    if holes:
        cname, g, d = holes[0]              # across the hole's axis (a width: its normal)
        Q = P.copy()
        sel = np.isin(face, g)
        Q[sel] += MOVE * d
        cases.append(("hole", Q, {"kind": "hole", "characteristic": cname, "faces": g, "direction": d.tolist(),
                                  "points_moved": int(sel.sum())}))
    tilts = tilt_candidates(data, feats, V, T, F)
    if tilts:
        cname, i, c0, n, axis, ratio, L = tilts[0]
        Q = P.copy()
        sel = face == i
        Q[sel] = rotate_about(P[sel], c0, axis, TILT)
        cases.append(("tilt", Q, {"kind": "tilt", "characteristic": cname, "face": i, "length": L,
                                  "expected_over_tol": ratio, "points_moved": int(sel.sum())}))
    for case, Q, what in cases:
        if only and case not in only:
            continue
        rows, sec, al = inspect_case(prep, plan, Q, np.random.default_rng(seed + 1), given_pose,
                                     data, feats, what)
        out["cases"][case] = {"defect": what, "cpu_s": sec, "alignment": al, "rows": rows}
        print(f"{name} {case}: {sec:.0f} s CPU, {summary(rows)}", file=sys.stderr, flush=True)
        for k, v in rows.items():       # what did not pass, at once (a run may be cut short)
            if v["verdict"] != "pass":
                print(f"  {k} {v['type']} {_num(v['measured'])} in {_num(v['lower'])} .. "
                      f"{_num(v['upper'])} U {_num(v['uncertainty'])} {v['verdict']} "
                      f"{v['relation']} {(v['reason'] or '')[:100]}", file=sys.stderr, flush=True)
    return out


def summary(rows) -> str:
    v = [r["verdict"] for r in rows.values()]
    s = f"pass {v.count('pass')}, fail {v.count('fail')}, undecided {v.count('undecided')}"
    exp = [r for r in rows.values() if r.get("relation") == "expected"]
    other = [r for r in rows.values() if r.get("relation") == "other" and r["verdict"] == "fail"]
    if exp or any(r.get("relation") for r in rows.values()):
        s += (f"; expected to fail: {sum(r['verdict'] == 'fail' for r in exp)} of {len(exp)} "
              f"fail; fails unrelated to the defect's faces: {len(other)}")
    return s


# ----------------------------------------------------------------------------- report
def _num(x):
    if x is None:
        return "-"
    if isinstance(x, dict):
        return ", ".join(f"{k} {_num(v)}" for k, v in x.items() if not isinstance(v, list))
    if isinstance(x, list):
        return "[" + ", ".join(_num(v) for v in x) + "]"
    return f"{x:.4g}" if isinstance(x, float) else str(x)


def markdown(res) -> str:
    lines = [f"### {res['file']}", "",
             f"{res['points']:,} points at {res['spacing']} mm, noise {res.get('noise')} mm, seed "
             f"{res.get('seed')}, deflection {res.get('deflection')} mm; {res['characteristics']} "
             f"characteristics, {res['unsupported']} PMI items unsupported; plan + model "
             f"{res['plan_cpu_s']:.0f} s CPU.", ""]
    for case, c in res["cases"].items():
        al = c["alignment"]
        lines.append(f"**{case}** ({c['cpu_s']:.0f} s CPU; alignment {al['kind']}, "
                     f"{al['rot_deg']:.4f} deg / {al['trans_mm']:.4f} mm from the true pose, "
                     f"{al.get('surface_mm', float('nan')):.4f} mm off the surface): "
                     f"{summary(c['rows'])}" + (f"; defect: {_num(c['defect'])}"
                                                 if c["defect"] else ""))
        lines.append("")
        bad = {k: v for k, v in c["rows"].items()
               if v["verdict"] != "pass" or v.get("relation") == "expected"}
        if bad:
            lines += ["| characteristic | type | measured | limits | U (k=2) | verdict | defect? | reason |",
                      "|---|---|---|---|---|---|---|---|"]
            for k, v in bad.items():
                lines.append(f"| {k} | {v['type']} | {_num(v['measured'])} | "
                             f"{_num(v['lower'])} .. {_num(v['upper'])} | "
                             f"{_num(v['uncertainty'])} | {v['verdict']} | {v.get('relation', '')} | "
                             f"{(v['reason'] or '')[:120]} |")
            lines.append("")
    return "\n".join(lines)


def main(argv=None):
    global NOISE, DEFLECTION
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="FTC 08 and CTC 01 at 2 mm (1 mm on small faces), true pose")
    ap.add_argument("--files", nargs="*", help="file names in /work/shared/data/cad/nist")
    ap.add_argument("--spacing", type=float, default=None, help="mm between scan points (1)")
    ap.add_argument("--fine", type=float, default=None,
                    help=f"mm between scan points on faces under {SMALL_FACE:g} mm2")
    ap.add_argument("--cases", nargs="*", choices=("perfect", "hole", "tilt"))
    ap.add_argument("--init", action="store_true", help="give the true pose (no registration)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--noise", type=float, default=NOISE, help=f"mm, sigma along the normal ({NOISE})")
    ap.add_argument("--deflection", type=float, default=DEFLECTION,
                    help=f"mm, the tessellation's chord error ({DEFLECTION})")
    ap.add_argument("--out", help="Markdown file to write")
    ap.add_argument("--json", help="JSON file to write")
    a = ap.parse_args(argv)
    NOISE, DEFLECTION = a.noise, a.deflection
    files = a.files or (QUICK if a.quick else FILES)
    spacing = a.spacing or (2.0 if a.quick else 1.0)
    allres, md = [], []
    for name in files:
        r = run_file(name, spacing, a.seed, a.init or a.quick, a.cases,
                     a.fine or (1.0 if a.quick else None))
        allres.append(r)
        md.append(markdown(r))
        print(md[-1], flush=True)
        if a.json:
            Path(a.json).write_text(json.dumps(allres, indent=1))
        if a.out:
            Path(a.out).write_text("\n\n".join(md) + "\n")


if __name__ == "__main__":
    main()
