"""How the engine compiles the functions its contact loops call once per pair or candidate.

:data:`item_kernel` is numba's ``njit(cache=True)`` without reference counting (numba's
internal ``_nrt=False`` option). Such a function takes some thirty arrays; with reference
counting, numba increments and decrements every array argument's count on each call (two
atomic operations per array), and on the wedge scene that took three quarters of the
bristle-bristle kernel's time and half of each step. Without it the function must not
allocate: numba refuses to compile one that does, so a mistake fails loudly at import.
The arrays it is given are owned by the caller, which keeps them alive.
"""
from __future__ import annotations

from numba import njit

item_kernel = njit(cache=True, _nrt=False)
