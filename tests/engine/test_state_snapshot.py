"""Snapshots and branches of a system (System.save_state / restore_state / branch, issue 23):
a run continued from a restored state is bit-identical to the uninterrupted one (the right
check for a snapshot: any state array left out of it, or restored wrongly, changes the
continuation); branches share the model and own their state."""
from __future__ import annotations

import numpy as np
import pytest

import engine
from engine.state import PRESCRIBED_FIELDS, STATE_ARRAYS, STATE_FIELDS
from state_scenes import chaser, impacts, patch_press, scene, wedge_press
from test_state_fields import arrays_of


def _observed(system) -> dict:
    """What a study reads of a state: node and body motion, forces, energy books, contacts,
    controller integrators (copies)."""
    nd, bd = system.nodes, system.bodies
    out = {"x": nd.x, "v": nd.v, "q": nd.q, "w": nd.w, "f": nd.f, "t": nd.t,
           "body_pos": bd.pos, "body_q": bd.q, "body_v": bd.v, "body_w": bd.w,
           "body_f": bd.f, "body_tq": bd.tq, "acc": system.acc,
           "pair_force": system.pairs.fc, "body_contact_force": system.body_pairs.fc,
           "controllers": system.mission.ctl_state}
    if system.patches is not None:
        out["patches"] = system.patches.state
    return {k: np.array(v, copy=True) for k, v in out.items()}


@pytest.mark.parametrize("make", [wedge_press, chaser, patch_press, impacts],
                         ids=lambda m: m.__name__)
def test_restored_run_continues_bit_identically(make):
    # wedge_press: contact history of bristle pairs and the wedge; chaser: controller
    # integrators, orbit, hinge, loads; patch_press: the reduced law's state and a profile
    # cursor (the save falls in the first waypoint interval, the carrier is released after
    # the second); impacts: sphere-mesh and mesh-mesh history
    system = engine.build(scene(make))
    end = system.scene.run.duration
    engine.run(system, until=0.4 * end, output=False)
    snap = system.save_state()
    assert snap.steps == system.steps > 0 and snap.time == system.time
    engine.run(system, until=end, output=False)
    straight = _observed(system)
    system.restore_state(snap)
    assert system.steps == snap.steps
    engine.run(system, until=end, output=False)
    again = _observed(system)
    for key, value in straight.items():
        assert np.array_equal(again[key], value), key
    # the snapshot stays valid: a second restore gives the same continuation
    system.restore_state(snap)
    engine.run(system, until=end, output=False)
    assert np.array_equal(system.nodes.x, straight["x"])
    assert np.array_equal(system.bodies.pos, straight["body_pos"])


def test_branches_with_other_inputs_diverge_and_leave_the_parent():
    # two branches of a pressed patch go on at different press speeds: they must differ
    # (the branch really runs its own motion) while the parent keeps its state bit for bit
    parent = engine.build(scene(patch_press))
    engine.run(parent, until=0.02, output=False)
    before = {k: a.copy() for k, a in arrays_of(parent).items()}
    motions = list(parent.prescribed_motions)
    children = []
    for speed in (0.01, 0.03):
        child = parent.branch()
        engine.prescribe_motion(child, "carrier", {
            "kind": "constant", "velocity": [0.0, 0.0, -speed], "duration": 0.03})
        engine.run(child, until=0.05, output=False)
        children.append(child)
    assert children[0].time == children[1].time > parent.time
    assert not np.array_equal(children[0].bodies.pos, children[1].bodies.pos)
    assert not np.array_equal(children[0].patches.state, children[1].patches.state)
    after = arrays_of(parent)
    for key, value in before.items():
        assert np.array_equal(after[key], value), key
    assert parent.prescribed_motions == motions
    # a branch continued without changes is the parent's own continuation
    twin = parent.branch()
    engine.run(twin, until=0.05, output=False)
    engine.run(parent, until=0.05, output=False)
    assert np.array_equal(twin.bodies.pos, parent.bodies.pos)
    assert np.array_equal(twin.patches.state, parent.patches.state)


def test_a_branch_shares_the_model_and_owns_the_state():
    system = engine.build(scene(wedge_press))
    engine.run(system, until=0.0004, output=False)
    child = system.branch()
    owned = ({f"{n}.{f}" for n, fields in STATE_FIELDS.items() for f in fields}
             | {f"{n}.{f}" for n, fields in PRESCRIBED_FIELDS.items() for f in fields}
             | set(STATE_ARRAYS))
    mine, its = arrays_of(system), arrays_of(child)
    assert set(mine) == set(its)
    for key, a in mine.items():
        if key in owned:
            assert its[key] is not a and not np.shares_memory(its[key], a), key
            assert np.array_equal(its[key], a), key
        else:
            assert its[key] is a, key


def test_a_snapshot_of_another_system_is_refused():
    snap = engine.build(scene(impacts)).save_state()
    with pytest.raises(ValueError, match="another system"):
        engine.build(scene(wedge_press)).restore_state(snap)
