"""How the engine compiles the kernels that allocate nothing: those its contact loops call
once per pair or candidate, and those the step loop calls once per step.

:data:`item_kernel` is numba's ``njit(cache=True)`` without reference counting (numba's
internal ``_nrt=False`` option). A contact function takes some thirty arrays; with reference
counting, numba increments and decrements every array argument's count on each call (two
atomic operations per array), and on the wedge scene that took three quarters of the
bristle-bristle kernel's time and half of each step (a step-loop kernel given the node and
body bundles pays it for every array of both, once per step). Without it the function must not
allocate: numba refuses to compile one that does, so a mistake fails loudly at import.
The arrays it is given are owned by the caller, which keeps them alive.
"""
from __future__ import annotations

from numba import njit

item_kernel = njit(cache=True, _nrt=False)
