"""Benchmark: NURBS surface points + first derivatives per second (single thread).

A 20 x 20 control-point bicubic rational surface (uniform clamped knots, random control points
and weights), evaluated at random (u, v) together with Su and Sv, by

* shapeverify (numba kernel, one thread): the public call ``surface.derivatives(u, v, 1)``
  (validation + allocation of the (N, 2, 2, 3) result included) and the kernel into a
  preallocated array;
* a plain vectorised numpy implementation (A2.2 basis + derivative formula, gather, einsum);
* OpenCASCADE (OCP) ``Geom_BSplineSurface.D1`` in a Python loop (a subsample, extrapolated);
* splipy ``Surface.evaluate/derivative(..., tensor=False)`` if importable;
* geomdl ``NURBS.Surface.derivatives`` per point if importable (a subsample, extrapolated).

Every peer's answers are checked against ours (max |difference| / max |value|).

Run:  .venv/bin/python benchmarks/bench_nurbs.py [--n 1000000] [--out benchmarks/results_nurbs.md]
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core for everybody (numba kernels are not parallel anyway)

import argparse  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from shapeverify.cad import _kernels  # noqa: E402
from shapeverify.cad.nurbs import NurbsSurface  # noqa: E402
from shapeverify.cad.occ_write import to_occ  # noqa: E402

P_DEG = 3
N_CTRL = 20


def make_surface(rng) -> NurbsSurface:
    inner = np.linspace(0.0, 1.0, N_CTRL - P_DEG + 1)
    knots = np.concatenate([[0.0] * P_DEG, inner, [1.0] * P_DEG])
    x, y = np.meshgrid(np.linspace(0, 100, N_CTRL), np.linspace(0, 100, N_CTRL), indexing="ij")
    ctrl = np.stack([x, y, 10 * rng.normal(size=x.shape)], axis=-1)
    ctrl[..., :2] += rng.normal(scale=1.0, size=x.shape + (2,))
    weights = rng.uniform(0.5, 2.0, x.shape)
    return NurbsSurface(P_DEG, P_DEG, knots, knots, ctrl, weights)


def best_time(fn, repeats: int) -> tuple[float, float]:
    """(best CPU time, best wall time) of fn() over `repeats` runs.

    CPU time (user + system of this process, one thread) is what one core spends; on a machine
    shared with other jobs the wall time also counts the time the process waited for a core.
    """
    cpu, wall = [], []
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - t0)
    return min(cpu), min(wall)


def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


# ------------------------------------------------------------------------- numpy baseline
def _np_basis_d1(U, p, t):
    """Vectorised A2.2 over all t plus the derivative formula (NURBS Book eq. 2.9)."""
    n = len(U) - p - 2
    span = np.clip(np.searchsorted(U, t, side="right") - 1, p, n)
    m = len(t)
    N = np.zeros((m, p + 1))
    N[:, 0] = 1.0
    left = np.empty((m, p + 1))
    right = np.empty((m, p + 1))
    prev = None
    for j in range(1, p + 1):
        if j == p:
            prev = N[:, :p].copy()  # degree p-1 functions N_{span-p+1+r, p-1}
        left[:, j] = t - U[span + 1 - j]
        right[:, j] = U[span + j] - t
        saved = np.zeros(m)
        for r in range(j):
            temp = N[:, r] / (right[:, r + 1] + left[:, j - r])
            N[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        N[:, j] = saved
    dN = np.zeros((m, p + 1))
    for r in range(p + 1):
        i = span - p + r
        if r >= 1:
            den = U[i + p] - U[i]
            dN[:, r] += p * np.divide(prev[:, r - 1], den, out=np.zeros(m), where=den > 0)
        if r <= p - 1:
            den = U[i + p + 1] - U[i + 1]
            dN[:, r] -= p * np.divide(prev[:, r], den, out=np.zeros(m), where=den > 0)
    return span, N, dN


def numpy_derivs(surf: NurbsSurface, u, v, chunk=100_000):
    p, q = surf.degree_u, surf.degree_v
    Pw = surf._pw
    out = np.empty((len(u), 3, 3))
    for a in range(0, len(u), chunk):
        uu, vv = u[a:a + chunk], v[a:a + chunk]
        su, Nu, dNu = _np_basis_d1(surf.knots_u, p, uu)
        sv, Nv, dNv = _np_basis_d1(surf.knots_v, q, vv)
        iu = su[:, None] - p + np.arange(p + 1)
        iv = sv[:, None] - q + np.arange(q + 1)
        G = Pw[iu[:, :, None], iv[:, None, :]]  # (m, p+1, q+1, 4)
        A = np.einsum("ni,nj,nijc->nc", Nu, Nv, G)
        Au = np.einsum("ni,nj,nijc->nc", dNu, Nv, G)
        Av = np.einsum("ni,nj,nijc->nc", Nu, dNv, G)
        S = A[:, :3] / A[:, 3:]
        out[a:a + chunk, 0] = S
        out[a:a + chunk, 1] = (Au[:, :3] - Au[:, 3:] * S) / A[:, 3:]
        out[a:a + chunk, 2] = (Av[:, :3] - Av[:, 3:] * S) / A[:, 3:]
    return out


# ------------------------------------------------------------------------------- peers
def ocp_derivs(occ, u, v):
    from OCP.gp import gp_Pnt, gp_Vec

    P, Du, Dv = gp_Pnt(), gp_Vec(), gp_Vec()
    out = np.empty((len(u), 3, 3))
    for i in range(len(u)):
        occ.D1(u[i], v[i], P, Du, Dv)
        out[i, 0] = P.X(), P.Y(), P.Z()
        out[i, 1] = Du.X(), Du.Y(), Du.Z()
        out[i, 2] = Dv.X(), Dv.Y(), Dv.Z()
    return out


def splipy_surface(surf: NurbsSurface):
    import splipy

    bu = splipy.BSplineBasis(surf.degree_u + 1, surf.knots_u)
    bv = splipy.BSplineBasis(surf.degree_v + 1, surf.knots_v)
    # rational splipy objects hold pre-multiplied (w x, w y, w z, w); raw: keep our (nu, nv, 4)
    return splipy.Surface(bu, bv, np.array(surf._pw), rational=True, raw=True)


def splipy_derivs(sp, u, v, chunk=100_000):
    out = np.empty((len(u), 3, 3))
    for a in range(0, len(u), chunk):
        uu, vv = u[a:a + chunk], v[a:a + chunk]
        out[a:a + chunk, 0] = sp.evaluate(uu, vv, tensor=False)
        out[a:a + chunk, 1] = sp.derivative(uu, vv, d=(1, 0), tensor=False)
        out[a:a + chunk, 2] = sp.derivative(uu, vv, d=(0, 1), tensor=False)
    return out


def geomdl_surface(surf: NurbsSurface):
    from geomdl import NURBS

    s = NURBS.Surface()
    s.degree_u, s.degree_v = surf.degree_u, surf.degree_v
    nu, nv = surf.control.shape[:2]
    s.ctrlpts_size_u, s.ctrlpts_size_v = nu, nv
    s.ctrlptsw = surf._pw.reshape(-1, 4).tolist()  # v index runs fastest, weighted points
    s.knotvector_u = surf.knots_u.tolist()
    s.knotvector_v = surf.knots_v.tolist()
    return s


def geomdl_derivs(gs, u, v):
    out = np.empty((len(u), 3, 3))
    for i in range(len(u)):
        d = gs.derivatives(float(u[i]), float(v[i]), order=1)
        out[i, 0], out[i, 1], out[i, 2] = d[0][0], d[1][0], d[0][1]
    return out


# ---------------------------------------------------------------------------------- main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="number of random (u, v)")
    ap.add_argument("--ocp-n", type=int, default=20_000, help="OCP subsample (extrapolated)")
    ap.add_argument("--geomdl-n", type=int, default=5_000, help="geomdl subsample (extrapolated)")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs of the fast ones (best)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results_nurbs.md"))
    args = ap.parse_args(argv)

    rng = np.random.default_rng(args.seed)
    surf = make_surface(rng)
    N = args.n
    u, v = rng.random(N), rng.random(N)
    load0 = os.getloadavg()

    # warm up numba (compile or load from cache) before any timing
    surf.derivatives(u[:1000], v[:1000], 1)
    buf = np.empty((N, 2, 2, 3))
    args_k = (surf.degree_u, surf.degree_v, surf.knots_u, surf.knots_v, surf._pw, u, v, 1, buf)
    _kernels.surface_derivs(*args_k)
    ours_full = surf.derivatives(u, v, 1)
    ref = np.stack([ours_full[:, 0, 0], ours_full[:, 1, 0], ours_full[:, 0, 1]], axis=1)

    rows = []  # (name, points timed, best s, median s, extrapolated?, rel err vs ours)

    def add(name, n_timed, fn, repeats, check):
        cpu, wall = best_time(fn, repeats)
        err = check() if check is not None else 0.0
        rows.append((name, n_timed, cpu, wall, n_timed < N, err))
        print(f"{name:58s} {n_timed / cpu / 1e6:10.3f} M pts/s per CPU s, "
              f"{n_timed / wall / 1e6:8.3f} per wall s (rel. diff {err:.1e})", flush=True)

    add("shapeverify surface.derivatives(u, v, 1) [public API]", N,
        lambda: surf.derivatives(u, v, 1), args.repeats, None)
    def buf_err():
        got = np.stack([buf[:, 0, 0], buf[:, 1, 0], buf[:, 0, 1]], axis=1)
        return rel_err(got, ref)

    add("shapeverify kernel, any degree, preallocated out", N,
        lambda: _kernels.surface_derivs(*args_k), args.repeats, buf_err)

    res = {}
    add("numpy, plain vectorised (A2.2 + gather + einsum)", N,
        lambda: res.__setitem__("np", numpy_derivs(surf, u, v)), max(1, args.repeats // 2),
        lambda: rel_err(res["np"], ref))

    try:
        occ = to_occ(surf)
        m = min(args.ocp_n, N)
        add(f"OCP Geom_BSplineSurface.D1, Python loop ({m:,} pts)", m,
            lambda: res.__setitem__("occ", ocp_derivs(occ, u[:m], v[:m])), 2,
            lambda: rel_err(res["occ"], ref[:m]))
    except ImportError as e:
        print(f"OCP not importable: {e}")
    try:
        sp = splipy_surface(surf)
        add("splipy Surface.evaluate/derivative(tensor=False)", N,
            lambda: res.__setitem__("sp", splipy_derivs(sp, u, v)), 1,
            lambda: rel_err(res["sp"], ref))
    except ImportError as e:
        print(f"splipy not importable: {e}")
    try:
        gs = geomdl_surface(surf)
        m = min(args.geomdl_n, N)
        add(f"geomdl NURBS.Surface.derivatives, per point ({m:,} pts)", m,
            lambda: res.__setitem__("gd", geomdl_derivs(gs, u[:m], v[:m])), 1,
            lambda: rel_err(res["gd"], ref[:m]))
    except ImportError as e:
        print(f"geomdl not importable: {e}")

    ours_rate = rows[0][1] / rows[0][2]  # public API, CPU time
    lines = ["| implementation | points timed | M points/s (CPU time) | M points/s (wall) "
             "| shapeverify API is x faster (CPU) | max rel. diff vs shapeverify |",
             "|---|---:|---:|---:|---:|---:|"]
    for name, n_t, cpu, wall, extrap, err in rows:
        rate = n_t / cpu
        lines.append(f"| {name} | {n_t:,}{' (extrapolated)' if extrap else ''} | "
                     f"{rate / 1e6:.3f} | {n_t / wall / 1e6:.3f} | {ours_rate / rate:.2f} | "
                     f"{err:.1e} |")
    table = "\n".join(lines)
    print()
    print(table)
    load1 = os.getloadavg()
    cmd = "cd /work/main && .venv/bin/python benchmarks/bench_nurbs.py" + (
        " " + " ".join(sys.argv[1:]) if argv is None and sys.argv[1:] else "")
    md = f"""# NURBS evaluation benchmark (points + first derivatives)

Command: `{cmd}`

Surface: {N_CTRL} x {N_CTRL} control points, bicubic, rational (weights in [0.5, 2]), uniform
clamped knots; {N:,} random (u, v) in [0, 1]^2 (seed {args.seed}). One thread for everybody
(NUMBA_NUM_THREADS = OMP_NUM_THREADS = 1; the numba kernels are not parallel). numba is warmed up
(compiled / loaded from its cache) before timing. Each rate uses the best of {args.repeats} runs
for shapeverify (fewer for the slow peers), timed both as CPU time of the process (what one core
spends: the fair measure on a shared machine) and as wall-clock time (which also counts waiting
for a core while other jobs run). Rows marked "extrapolated" timed a
subsample of the points (a per-point Python loop, so the rate does not depend on N). The last
column checks each peer's points and derivatives against ours.

{table}

Goal (issue 2): >= 10 M points/s for shapeverify.

Machine: {cpu_name()}, {os.cpu_count()} cores shared with other
jobs (load average {load0[0]:.2f} before, {load1[0]:.2f} after the run: wall-clock rates on a
busy machine are pessimistic; CPU-time rates less so, but caches and memory bandwidth are shared),
Python {platform.python_version()}, numpy {np.__version__},
numba {numba.__version__}; {datetime.date.today().isoformat()}.
"""
    with open(args.out, "w") as fh:
        fh.write(md)
    print(f"\nwrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
