"""Why the parallel kernels keep a serial twin loop (engine.kernels.bonds.PARALLEL_MIN): the
CPU time per call of one half kick over N nodes as a plain loop and as a ``prange`` loop.

    NUMBA_NUM_THREADS=1 python benchmarks/prange_latency.py
    NUMBA_NUM_THREADS=2 python benchmarks/prange_latency.py
"""
import time, numpy as np
from numba import njit, prange
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
for N in (16, 512, 4096, 65536):
    v = np.zeros((N, 3)); f = np.ones((N, 3)); im = np.ones(N)
    res = []
    for fn in (kick_ser, kick_par):
        fn(v, f, im, 1e-6); reps = max(200, 2_000_000 // N)
        t0 = time.process_time()
        for _ in range(reps): fn(v, f, im, 1e-6)
        res.append((time.process_time() - t0) / reps * 1e6)
    print(f"N={N:6d} serial {res[0]:8.2f} us  prange {res[1]:8.2f} us  (CPU per call)")
