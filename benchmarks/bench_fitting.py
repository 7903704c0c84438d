"""Benchmark: orthogonal-distance NURBS fitting (Papers VI-VII) against scipy and geomdl.

Problems (one run each, seeded):

* curve A: 2,000 noisy points of a 3-D spiral (about 200 mm long, sigma = 0.05 mm per
  coordinate), cubic, 40 control points;
* curve B: 20,000 points of the same spiral, 100 control points;
* surface: 10,000 scattered noisy points of a free-form height field over 100 x 100 mm
  (sigma = 0.05 mm), bicubic, 20 x 20 control points.

Every solver starts from the same point: the fixed-parameter least-squares fit (chord-length /
plane parameters, NURBS Book knots), with the foot points projected onto it.

* shapeverify ``method="odr"`` (Levenberg-Marquardt, foot points eliminated per point, Paper VI)
  and ``method="varpro"`` (variable projection, Paper VII) with the library defaults: the
  orthogonal distances plus the sliding prior (``slide_stiffness=100``, fitting/_slide.py: the
  control points' drift along the shape has a prior standard deviation of a tenth of their
  spacing, scaled by the noise);
* shapeverify ``odr`` on the plain objective (``slide_stiffness=0``), to show why the prior is
  the default: the plain problem is ill-posed on noisy data (control points slide together and
  the shape folds to follow the noise), so it creeps to the 300-iteration cap while its distance
  from the true shape grows;
* ``scipy.optimize.least_squares`` (method "trf", bounds on the parameters, ``jac_sparsity``
  with finite differences, default tolerances) on the same unknowns (control points + foot
  points) and the same objective as the defaults (the prior as extra residuals).  It converges
  slowly, so it is stopped after a capped number of function evaluations (shown in the table)
  and its RMS and objective at that point are reported;
* geomdl ``fitting.approximate_curve/approximate_surface`` (fixed parameters: the baseline the
  ODR improves on; the surface needs a grid, so it gets a 100 x 100 grid of the same field).

RMS is always the orthogonal one: the points are projected onto each final shape with the same
routine.  The objective is the sum of squared distances plus the prior.  The last column is the
distance of the fitted shape from the true, noise-free one (the spiral; the height field inside
[1, 99]^2), which the fit is for.  CPU time (this process, one thread) and wall time are reported.

Run:  .venv/bin/python benchmarks/bench_fitting.py [--out benchmarks/results_fitting.md] [--quick]
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core for everybody

import argparse  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.optimize  # noqa: E402
import scipy.sparse  # noqa: E402

from shapeverify import fitting  # noqa: E402
from shapeverify.cad.nurbs import NurbsCurve, NurbsSurface  # noqa: E402
from shapeverify.fitting import _slide, curves  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

SIGMA = 0.05


def spiral(n, rng):
    t = np.sort(rng.uniform(0, 1, n))
    x = 50 * np.column_stack([np.cos(4 * t) * (1 + t), np.sin(4 * t) * (1 + t), 0.3 * t])
    return x + rng.normal(scale=SIGMA, size=x.shape)


def height(xy):
    x, y = xy[..., 0], xy[..., 1]
    return 8 * np.sin(x / 15) * np.cos(y / 22) + 0.002 * (x - 50) ** 2


def field_points(n, rng):
    xy = rng.uniform(0, 100, (n, 2))
    p = np.column_stack([xy, height(xy)])
    return p + rng.normal(scale=SIGMA, size=p.shape)


class Timer:
    def __enter__(self):
        self.c, self.w = time.process_time(), time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.cpu = time.process_time() - self.c
        self.wall = time.perf_counter() - self.w


def orth_rms_curve(curve, x, t0):
    _, d = fitting.project_to_curve(curve, x, t0, iterations=30)
    return float(np.sqrt(np.mean(d ** 2)))


def orth_rms_surface(surf, x, uv0):
    _, d = fitting.project_to_surface(surf, x, uv0, iterations=30)
    return float(np.sqrt(np.mean(d ** 2)))


# ------------------------------------------------------------------------------ scipy peer
def prior_of(fixed, shape, stiffness):
    """The sliding prior fit_curve / fit_surface put on this problem (see fitting/_slide.py):
    sqrt(mu) * frames, anchor control points (n, d)."""
    P0 = shape.control
    mu = stiffness * fixed.rms ** 2 / _slide.mean_spacing(P0) ** 2
    frames = _slide.curve_frames(shape) if P0.ndim == 2 else _slide.surface_frames(shape)
    return np.sqrt(mu) * frames, P0.reshape(-1, P0.shape[-1])


def scipy_curve(x, fixed, max_nfev, margin=2, stiffness=fitting.curves.SLIDE_STIFFNESS):
    """least_squares on (control points, foot points) with a finite-difference sparse Jacobian,
    on the objective fit_curve minimises (distances + the sliding prior)."""
    curve = fixed.curve
    n, d = curve.control.shape
    F, P0 = prior_of(fixed, curve, stiffness)
    k = F.shape[2]
    p, U = curve.degree, curve.knots
    N = len(x)
    t0 = fixed.params
    spans, _ = curves._basis(p, U, n, t0, 0)
    rows, cols = [], []
    for i in range(N):
        lo, hi = max(spans[i] - p - margin, 0), min(spans[i] + margin, n - 1)
        for j in range(lo, hi + 1):
            for e in range(d):
                rows.append(i * d + e)
                cols.append(j * d + e)
        for e in range(d):
            rows.append(i * d + e)
            cols.append(n * d + i)
    for j in range(n):                       # prior rows: control point j's coordinates
        for a in range(k):
            for e in range(d):
                rows.append(N * d + j * k + a)
                cols.append(j * d + e)
    S = scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)),
                                shape=(N * d + n * k, n * d + N)).tocsr()

    def fun(z):
        P = z[:n * d].reshape(n, d)
        c = NurbsCurve(p, U, P)
        prior = np.einsum("jek,je->jk", F, P - P0).ravel()
        return np.concatenate([(c.evaluate(np.clip(z[n * d:], 0, 1)) - x).ravel(), prior])

    z0 = np.concatenate([curve.control.ravel(), t0])
    lb = np.concatenate([np.full(n * d, -np.inf), np.zeros(N)])
    ub = np.concatenate([np.full(n * d, np.inf), np.ones(N)])
    res = scipy.optimize.least_squares(fun, z0, jac_sparsity=S, bounds=(lb, ub), method="trf",
                                       max_nfev=max_nfev)
    c = NurbsCurve(p, U, res.x[:n * d].reshape(n, d))
    return c, res


def scipy_surface(x, fixed, max_nfev, margin=1, stiffness=fitting.surfaces.SLIDE_STIFFNESS):
    surf = fixed.surface
    nu, nv, _ = surf.control.shape
    F, P0 = prior_of(fixed, surf, stiffness)
    p, q = surf.degree_u, surf.degree_v
    U, V = surf.knots_u, surf.knots_v
    N = len(x)
    uv0 = fixed.params
    su, _ = curves._basis(p, U, nu, np.ascontiguousarray(uv0[:, 0]), 0)
    sv, _ = curves._basis(q, V, nv, np.ascontiguousarray(uv0[:, 1]), 0)
    M = nu * nv * 3
    rows, cols = [], []
    for i in range(N):
        for a in range(max(su[i] - p - margin, 0), min(su[i] + margin, nu - 1) + 1):
            for b in range(max(sv[i] - q - margin, 0), min(sv[i] + margin, nv - 1) + 1):
                for e in range(3):
                    rows.append(3 * i + e)
                    cols.append((a * nv + b) * 3 + e)
        for e in range(3):
            rows += [3 * i + e, 3 * i + e]
            cols += [M + 2 * i, M + 2 * i + 1]
    for j in range(nu * nv):                 # prior rows: control point j's coordinates
        for a in range(2):
            for e in range(3):
                rows.append(3 * N + 2 * j + a)
                cols.append(3 * j + e)
    S = scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)),
                                shape=(3 * N + 2 * nu * nv, M + 2 * N)).tocsr()

    def fun(z):
        P = z[:M].reshape(-1, 3)
        s = NurbsSurface(p, q, U, V, P.reshape(nu, nv, 3))
        uv = np.clip(z[M:].reshape(N, 2), 0, 1)
        prior = np.einsum("jek,je->jk", F, P - P0).ravel()
        return np.concatenate([(s.evaluate(uv[:, 0], uv[:, 1]) - x).ravel(), prior])

    z0 = np.concatenate([surf.control.ravel(), uv0.ravel()])
    lb = np.concatenate([np.full(M, -np.inf), np.zeros(2 * N)])
    ub = np.concatenate([np.full(M, np.inf), np.ones(2 * N)])
    res = scipy.optimize.least_squares(fun, z0, jac_sparsity=S, bounds=(lb, ub), method="trf",
                                       max_nfev=max_nfev)
    return NurbsSurface(p, q, U, V, res.x[:M].reshape(nu, nv, 3)), res


# ------------------------------------------------------------------------------ geomdl peer
def geomdl_curve(x, n_ctrl):
    from geomdl import fitting as gf
    with Timer() as tm:
        c = gf.approximate_curve([list(map(float, r)) for r in x], 3, ctrlpts_size=n_ctrl)
    ours = NurbsCurve(3, np.asarray(c.knotvector), np.asarray(c.ctrlpts))
    return ours, tm


def geomdl_surface(n_grid, n_ctrl):
    from geomdl import fitting as gf
    g = np.linspace(0, 100, n_grid)
    X, Y = np.meshgrid(g, g, indexing="ij")
    rng = np.random.default_rng(11)
    P = np.stack([X, Y, height(np.stack([X, Y], -1))], -1) + rng.normal(scale=SIGMA, size=X.shape + (3,))
    pts = [list(map(float, r)) for r in P.reshape(-1, 3)]
    with Timer() as tm:
        s = gf.approximate_surface(pts, n_grid, n_grid, 3, 3, ctrlpts_size_u=n_ctrl, ctrlpts_size_v=n_ctrl)
    ctrl = np.asarray(s.ctrlpts).reshape(n_ctrl, n_ctrl, 3)
    ours = NurbsSurface(3, 3, np.asarray(s.knotvector_u), np.asarray(s.knotvector_v), ctrl)
    return ours, tm, P


# ------------------------------------------------------------------------------------ main
def spiral_truth():
    tt = np.linspace(0, 1, 2_000_001)
    return cKDTree(50 * np.column_stack([np.cos(4 * tt) * (1 + tt), np.sin(4 * tt) * (1 + tt), 0.3 * tt]))


def truth_error_curve(curve, kd):
    """RMS distance of the fitted curve (50,000 samples) from the true spiral (mm)."""
    P = curve.evaluate(np.linspace(curve.knots[0], curve.knots[-1], 50000))
    return float(np.sqrt(np.mean(kd.query(P)[0] ** 2)))


def truth_error_surface(surf):
    """RMS height error of the fitted surface against the true field inside [1, 99]^2 (mm)."""
    g = np.linspace(0, 1, 150)
    U, V = np.meshgrid(surf.knots_u[0] + g * (surf.knots_u[-1] - surf.knots_u[0]),
                       surf.knots_v[0] + g * (surf.knots_v[-1] - surf.knots_v[0]))
    P = surf.evaluate(U.ravel(), V.ravel())
    m = (P[:, 0] > 1) & (P[:, 0] < 99) & (P[:, 1] > 1) & (P[:, 1] < 99)
    return float(np.sqrt(np.mean((P[m, 2] - height(P[m, :2])) ** 2)))


def _ours(name, rows, fit_fn, truth, label, **kw):
    with Timer() as tm:
        fit = fit_fn(**kw)
    shape = fit.curve if hasattr(fit, "curve") else fit.surface
    rows.append((name, label, tm.cpu, tm.wall, fit.rms, fit.iterations, fit.converged, truth(shape),
                 fit.history[-1]))
    return fit


def run_problem(name, x, fit_fn, truth, n_ctrl_kw, rows, scipy_fn, max_it, max_nfev, geomdl_fn=None):
    with Timer() as tf:
        fixed = fit_fn(x, **n_ctrl_kw, method="fixed")
    rows.append((name, "shapeverify fixed (A9.7 knots)", tf.cpu, tf.wall, fixed.rms, "-", "-",
                 truth(fixed.curve if hasattr(fixed, "curve") else fixed.surface), "-"))
    for method in ("odr", "varpro"):
        _ours(name, rows, fit_fn, truth, f"shapeverify {method} (defaults)", points=x, **n_ctrl_kw,
              method=method, max_iterations=max_it)
    _ours(name, rows, fit_fn, truth, "shapeverify odr, plain objective (slide_stiffness=0)",
          points=x, **n_ctrl_kw, method="odr", max_iterations=max_it, slide_stiffness=0.0)
    if scipy_fn is not None:
        with Timer() as ts:
            shape, rms, res = scipy_fn(x, fixed, max_nfev)
        rows.append((name, "scipy least_squares trf + jac_sparsity (same objective as the defaults)",
                     ts.cpu, ts.wall, rms, f"{res.nfev} nfev (cap {max_nfev})", res.status > 0,
                     truth(shape), 2 * res.cost))
    if geomdl_fn is not None:
        try:
            geomdl_fn(rows)
        except ImportError:
            pass


def run_curve(name, n_pts, n_ctrl, rng, rows, kd, with_scipy=True, max_it=300, max_nfev=400):
    x = spiral(n_pts, rng)
    truth = lambda c: truth_error_curve(c, kd)  # noqa: E731

    def sp(x, fixed, nfev):
        c, res = scipy_curve(x, fixed, nfev)
        return c, orth_rms_curve(c, x, np.clip(res.x[-n_pts:], 0, 1)), res

    def gd(rows):
        c, tg = geomdl_curve(x, n_ctrl)
        rows.append((name, "geomdl approximate_curve (fixed parameters)", tg.cpu, tg.wall,
                     orth_rms_curve(c, x, fitting.chord_length_params(x)), "-", "-", truth(c), "-"))

    run_problem(name, x, fitting.fit_curve, truth, {"n_ctrl": n_ctrl}, rows,
                sp if with_scipy else None, max_it, max_nfev, gd)


def run_surface(name, n_pts, n_ctrl, rng, rows, with_scipy=True, max_it=300, max_nfev=30):
    x = field_points(n_pts, rng)

    def sp(x, fixed, nfev):
        s, res = scipy_surface(x, fixed, nfev)
        M = n_ctrl * n_ctrl * 3
        return s, orth_rms_surface(s, x, np.clip(res.x[M:].reshape(-1, 2), 0, 1)), res

    def gd(rows):
        s, tg, grid = geomdl_surface(100, n_ctrl)
        uv0 = fitting.surface_params(grid)          # grid parameters, same orientation as geomdl
        rows.append((name + " (geomdl: 100 x 100 grid)", "geomdl approximate_surface (fixed parameters)",
                     tg.cpu, tg.wall, orth_rms_surface(s, grid.reshape(-1, 3), uv0), "-", "-",
                     truth_error_surface(s), "-"))

    run_problem(name, x, fitting.fit_surface, truth_error_surface, {"n_ctrl": (n_ctrl, n_ctrl)}, rows,
                sp if with_scipy else None, max_it, max_nfev, gd)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="benchmarks/results_fitting.md")
    ap.add_argument("--quick", action="store_true", help="skip the slow scipy runs of the large problems")
    args = ap.parse_args()
    load0 = os.getloadavg()
    # warm up numba (compile or load from cache)
    fitting.fit_curve(spiral(200, np.random.default_rng(0)), n_ctrl=10,
                      solver=fitting.FitSolver(max_iterations=3))
    fitting.fit_surface(field_points(500, np.random.default_rng(0)), n_ctrl=(5, 5),
                        solver=fitting.FitSolver(max_iterations=3))
    rows = []
    rng = np.random.default_rng(2011)
    kd = spiral_truth()
    run_curve("curve A: 2,000 pts, 40 ctrl", 2000, 40, rng, rows, kd)
    run_curve("curve B: 20,000 pts, 100 ctrl", 20000, 100, rng, rows, kd, with_scipy=not args.quick,
              max_nfev=60)
    run_surface("surface: 10,000 pts, 20 x 20 ctrl", 10000, 20, rng, rows, with_scipy=not args.quick)
    load1 = os.getloadavg()
    lines = ["# Fitting benchmark (orthogonal-distance NURBS fitting, Papers VI-VII)", "",
             "Command: `cd /work/main && .venv/bin/python benchmarks/bench_fitting.py"
             f"{' --quick' if args.quick else ''}`", "",
             __doc__.split("Run:")[0].strip().split("\n\n", 1)[1], "",
             "| problem | solver | CPU s | wall s | orthogonal RMS (mm) | objective (mm^2) | iterations "
             "| converged | RMS distance from the true shape (mm) |",
             "|---|---|---:|---:|---:|---:|---:|---|---:|"]
    for r in rows:
        obj = r[8] if isinstance(r[8], str) else f"{r[8]:.4f}"
        lines.append(f"| {r[0]} | {r[1]} | {r[2]:.2f} | {r[3]:.2f} | {r[4]:.5f} | {obj} | {r[5]} | {r[6]} "
                     f"| {r[7]:.5f} |")
    lines += ["", "Iterations are capped at 300; the library's tolerance is the default (1e-10: stop when "
              "an iteration lowers the objective by less than this fraction).", "",
              "Ratios (scipy time / shapeverify time, CPU; scipy stopped at its cap):"]
    for prob in dict.fromkeys(r[0] for r in rows):
        sub = {r[1]: r for r in rows if r[0] == prob}
        sp = sub.get("scipy least_squares trf + jac_sparsity (same objective as the defaults)")
        ours = [k for k in sub if k.endswith("(defaults)")]
        for m in ours:
            if sp:
                lines.append(f"- {prob}: {m} is {sp[2] / sub[m][2]:.1f} x faster than scipy, RMS "
                             f"{sub[m][4]:.5f} vs {sp[4]:.5f} mm, objective {sub[m][8]:.4f} vs "
                             f"{sp[8]:.4f} mm^2")
    lines += ["", f"Noise: sigma = {SIGMA} mm per coordinate, so the orthogonal noise is about "
              f"{SIGMA * np.sqrt(2):.3f} mm for the curves and {SIGMA:.3f} mm for the surface.", "",
              f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores shared with "
              f"other jobs (load average {load0[0]:.2f} before, {load1[0]:.2f} after), "
              f"Python {platform.python_version()}, "
              f"numpy {np.__version__}, scipy {scipy.__version__}; one thread for everybody; "
              f"{datetime.date.today().isoformat()}."]
    text = "\n".join(lines) + "\n"
    with open(args.out, "w") as fh:
        fh.write(text)
    print(text)


if __name__ == "__main__":
    main()
