"""Every preset records what the studio's playback needs (issue 14, defect 4): the node
positions of its bristles, at a frame rate that keeps the result file small enough to
download and scrub."""
from __future__ import annotations

import pytest

import engine
from studio import presets

# the bytes one node adds to one frame of the ``nodes`` channel: nodes/positions, (N, 3)
# float64 (docs/results.md), counted here independently of engine.estimate
NODE_FRAME_BYTES = 3 * 8
# one preset's result file may be at most this big (the engine's estimate, within 30 % of a
# written file: tests/engine/test_estimate_file_size.py): the largest presets (wedge_*,
# spin_cube_*) need ~19 MiB; 32 MiB still downloads in seconds and scrubs from a laptop disk
MAX_RESULT_MIB = 32


@pytest.mark.parametrize("name", presets.preset_names())
def test_every_preset_with_bristles_records_node_positions(name):
    scene = presets.load_preset_or_file(name)
    n_nodes = sum(b.rows * b.columns * b.n_nodes for b in scene.brushes)
    if n_nodes == 0:
        # nothing to animate but bodies: those must be recorded instead
        assert "bodies" in scene.run.channels, f"{name}: a brushless preset records bodies"
        return
    assert "nodes" in scene.run.channels, (
        f"{name}: {n_nodes} bristle nodes but no 'nodes' channel: playback would show "
        f"straight bristles")


@pytest.mark.parametrize("name", presets.preset_names())
def test_every_preset_result_file_stays_small(name):
    scene = presets.load_preset_or_file(name)
    n_nodes = sum(b.rows * b.columns * b.n_nodes for b in scene.brushes)
    frames = int(scene.run.duration / scene.run.record_interval) + 1
    node_bytes = frames * n_nodes * NODE_FRAME_BYTES if "nodes" in scene.run.channels else 0
    assert node_bytes <= MAX_RESULT_MIB * 2**20, (
        f"{name}: {frames} frames x {n_nodes} nodes = {node_bytes / 2**20:.0f} MiB of node "
        f"positions; record less often")
    # the engine's own estimate (all channels, what the Run tab shows before Start) counts
    # at least these bytes and stays within the budget too
    cost = engine.estimate(scene)
    assert cost.frames == frames
    assert node_bytes <= cost.result_bytes <= MAX_RESULT_MIB * 2**20
