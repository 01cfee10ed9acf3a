"""Why the parallel kernels keep a serial twin loop (``engine.kernels.bonds.PARALLEL_MIN``):
the CPU time per call of one half kick over N nodes as a plain loop and as a ``prange``
loop. A ``prange`` pays the thread pool's start and join on every call, which small scenes
feel; a plain loop leaves the second core idle on big ones.

    NUMBA_NUM_THREADS=1 python benchmarks/prange_latency.py
    NUMBA_NUM_THREADS=2 python benchmarks/prange_latency.py
"""
from __future__ import annotations

import time

import numpy as np
from numba import njit, prange

SIZES = (16, 512, 4096, 65536)


@njit(parallel=True)
def kick_par(v, f, im, h):
    for n in prange(v.shape[0]):
        for a in range(3):
            v[n, a] += h * f[n, a] * im[n]


@njit
def kick_ser(v, f, im, h):
    for n in range(v.shape[0]):
        for a in range(3):
            v[n, a] += h * f[n, a] * im[n]


def cpu_us_per_call(fn, n: int) -> float:
    """CPU microseconds of one call of ``fn`` over ``n`` nodes (after a compiling call)."""
    v, f, im = np.zeros((n, 3)), np.ones((n, 3)), np.ones(n)
    fn(v, f, im, 1e-6)
    reps = max(200, 2_000_000 // n)
    t0 = time.process_time()
    for _ in range(reps):
        fn(v, f, im, 1e-6)
    return (time.process_time() - t0) / reps * 1e6


def main() -> None:
    for n in SIZES:
        ser, par = cpu_us_per_call(kick_ser, n), cpu_us_per_call(kick_par, n)
        print(f"N={n:6d} serial {ser:8.2f} us  prange {par:8.2f} us  (CPU per call)")


if __name__ == "__main__":
    main()
