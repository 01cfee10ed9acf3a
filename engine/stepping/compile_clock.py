"""The wall time a run spends compiling its numba kernels (or loading them from numba's
cache), so that its speed and stage times can leave it out.

A first run on a cold cache compiles the step loop for minutes; counted in, it made a run's
summary say ``bristle_body 116 s`` where the same run warm spends 29 s. A
:class:`CompileClock` adds up two things in the thread that created it:

* the blocks it times itself (:meth:`CompileClock.block`: the run's warm-up call of the
  step loop with zero steps, which compiles it or loads it from the cache and does nothing
  else);
* numba's own ``numba:compile`` events elsewhere (a kernel first called while recording,
  the neighbour-list growth), outermost ones only: a kernel's callees compile inside it.

Loading a kernel from numba's cache raises no event: only the warm-up block sees those.
"""
from __future__ import annotations

import threading
import time
from contextlib import contextmanager

from numba.core import event


class CompileClock:
    """Seconds this thread spent compiling while the clock was installed (:attr:`seconds`).

    Use as a context manager around the run; inside it, ``with clock.block(): ...`` counts
    all of the block's wall time as compile time (and the compile events inside it once).
    """

    def __init__(self):
        self.seconds = 0.0
        self._depth = 0
        self._t0 = 0.0
        self._thread = threading.get_ident()
        self._listener = _Listener(self)
        self._installed = False

    def _event(self, start: bool) -> None:
        if threading.get_ident() != self._thread:
            return  # another thread's compile (a studio's other run)
        if start:
            self._enter()
        else:
            self._leave()

    def _enter(self) -> None:
        self._depth += 1
        if self._depth == 1:
            self._t0 = time.perf_counter()

    def _leave(self) -> None:
        if self._depth == 0:  # an end whose start came before the clock was installed
            return
        self._depth -= 1
        if self._depth == 0:
            self.seconds += time.perf_counter() - self._t0

    @contextmanager
    def block(self):
        """Count the whole block as compile time."""
        self._enter()
        try:
            yield
        finally:
            self._leave()

    def __enter__(self) -> "CompileClock":
        event.register("numba:compile", self._listener)
        self._installed = True
        return self

    def __exit__(self, *exc) -> bool:
        if self._installed:
            event.unregister("numba:compile", self._listener)
            self._installed = False
        return False


class _Listener(event.Listener):
    """numba's listener interface, forwarding to a :class:`CompileClock`."""

    def __init__(self, clock: CompileClock):
        self.clock = clock

    def on_start(self, ev) -> None:
        self.clock._event(True)

    def on_end(self, ev) -> None:
        self.clock._event(False)
