"""What this machine's cores give: a numba ``prange`` loop on 1 and 2 threads (issue 18 item 4).

The ceiling against which the closest-point speed-up on two cores (bench_closest.py
--threads-only) is read: pure arithmetic, and random gathers from an array larger than the
caches (the access pattern of tree queries).  Best of 7 runs each, wall clock; run it on an
idle machine.

    .venv/bin/python benchmarks/bench_cores.py
"""

from __future__ import annotations

import os
import time

import numba
import numpy as np
from numba import njit, prange


@njit(parallel=True, nogil=True)
def _arithmetic(n, reps, out):
    for i in prange(n):
        x = i * 1e-6
        s = 0.0
        for k in range(reps):
            s += np.sqrt(x * x + k)
        out[i] = s


@njit(parallel=True, nogil=True)
def _gather(idx, data, out):
    for i in prange(idx.size):
        j = idx[i]
        out[i] = data[j, 0] * data[j, 1] + data[j, 2]


def _best(fn, args, threads, repeat=7):
    numba.set_num_threads(threads)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(*args)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    rng = np.random.default_rng(0)
    data = rng.random((2_000_000, 3))
    idx = rng.integers(0, data.shape[0], 4_000_000)
    cases = {"arithmetic (2M x 200 sqrt)": (_arithmetic, (2_000_000, 200, np.empty(2_000_000))),
             "random gathers (4M rows of a 48 MB array)": (_gather, (idx, data, np.empty(idx.size)))}
    print(f"load average {os.getloadavg()[0]:.1f} at the start, numba {numba.__version__}")
    print("| loop | 1 thread s | 2 threads s | speed-up |\n|---|---:|---:|---:|")
    for name, (fn, args) in cases.items():
        fn(*args)                                     # compile
        one, two = _best(fn, args, 1), _best(fn, args, 2)
        print(f"| {name} | {one:.4f} | {two:.4f} | {one / two:.2f}x |")
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
