"""The parallel kernels' ``prange`` loops (thresholds in ``engine.kernels.bonds``): steps on
two threads give the same bits as the same steps on one. A race between items (a shared
scratch row, a force written by two candidates) would change the bits; the scene crosses the
node, bond and bristle-body thresholds, so each of those kernels runs its ``prange``."""
from __future__ import annotations

import copy

import numba
import numpy as np
import pytest

import engine
from engine.kernels.bonds import PARALLEL_MIN, PARALLEL_MIN_BONDS, PARALLEL_MIN_CANDIDATES
from test_state_snapshot import _observed


@pytest.fixture
def pressed_brush(tiny_scene):
    # 24 x 24 bristles of 8 nodes (4608 nodes, 576 tips) pressed by a box that moves into
    # the tips and holds: every node, bond and tip candidate kernel is above its threshold
    scene = copy.deepcopy(tiny_scene(duration=0.004))
    brush = scene["brushes"][0]
    brush.update(rows=24, columns=24, n_nodes=8)
    scene["bodies"][0]["shape"]["size"] = [0.08, 0.08, 0.002]
    return engine.parse_scene(scene)


def test_two_threads_give_the_one_thread_bits(pressed_brush):
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here (NUMBA_NUM_THREADS=1)")
    system = engine.build(pressed_brush)
    assert system.n_nodes >= max(PARALLEL_MIN, PARALLEL_MIN_BONDS)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        engine.run(system, until=0.0012, output=False)
        n_cand = int(system.body_pairs.n[0])
        assert n_cand >= PARALLEL_MIN_CANDIDATES  # the box is on the tips
        snap = system.save_state()
        end = system.time + 100 * system.dt
        engine.run(system, until=end, output=False)
        serial = _observed(system)
        system.restore_state(snap)
        numba.set_num_threads(2)
        engine.run(system, until=end, output=False)
        threaded = _observed(system)
    finally:
        numba.set_num_threads(before)
    assert serial["acc"][0] == threaded["acc"][0]  # the same steps
    for key, value in serial.items():
        assert np.array_equal(threaded[key], value), key

