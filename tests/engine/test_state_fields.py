"""The declaration of the state (engine.state.STATE_FIELDS, STATE_ARRAYS) against what runs
really write: in scenes that between them use every stage with a state (contact history of
both bristle contacts, orbit, controllers, hinges, loads, reduced brushes, a kinematic body
released as free, sphere-mesh and mesh-mesh contacts), every array a run leaves bitwise
unchanged outside the declaration (the model), and every declared field changes in one of
them (no dead entries) but for the exceptions below, each with its reason."""
from __future__ import annotations

import numpy as np
import pytest

import engine
from engine.state import STATE_ARRAYS, STATE_FIELDS
from state_scenes import MAKERS, scene, wedge_press

# declared fields no scene here changes, and why they are state all the same
NOT_SEEN = {
    # written by the per-bond evaluation at a run's start (stepping.loop._refresh_forces):
    # the torques of the straight bristles every scene starts with are zero
    "bonds.ti", "bonds.tj",
    # the neighbour lists are state whole (a growth replaces every array of the list); a
    # rebuild rewrites their entries, which in these short runs stay the ones found at
    # build time, and slot 2/4 edge and crossing contacts (xf) and damped bristle pairs
    # (diss) do not occur here
    "pairs.a", "pairs.b", "pairs.n", "pairs.a2", "pairs.b2", "pairs.ft2", "pairs.xf",
    "pairs.diss", "body_pairs.s", "body_pairs.b", "body_pairs.n", "body_pairs.s2",
    "body_pairs.b2", "body_pairs.ft2", "body_pairs.xf", "body_pairs.deep",
    "body_pairs.deep2",
    # the failure report: written only by a failing run (test_a_failing_run_writes_err)
    "err",
}


def arrays_of(system) -> dict:
    """Every numpy array a system holds: its bundles' fields and its own arrays."""
    out = {}
    for name, value in vars(system).items():
        if isinstance(value, np.ndarray):
            out[name] = value
        elif isinstance(value, tuple) and hasattr(value, "_fields"):
            for f in value._fields:
                a = getattr(value, f)
                if isinstance(a, np.ndarray):
                    out[f"{name}.{f}"] = a
    return out


def _declared() -> set:
    return {f"{n}.{f}" for n, fields in STATE_FIELDS.items() for f in fields} | set(
        STATE_ARRAYS)


def _changed(before: dict, after: dict) -> set:
    return {k for k in before if before[k].shape != after[k].shape
            or not np.array_equal(before[k], after[k], equal_nan=True)}


def test_a_run_writes_the_declared_state_and_nothing_else():
    # a kernel that writes a model array (a stiffness scaled in place, a mesh moved instead
    # of its body) or a new state field left out of the declaration shows as undeclared; a
    # declared field that no run writes (a stale entry) as unseen
    declared = _declared()
    seen = set()
    for make in MAKERS:
        system = engine.build(scene(make))
        before = {k: a.copy() for k, a in arrays_of(system).items()}
        assert set(before) >= declared - {k for k in declared if k.startswith("patches.")}
        engine.run(system, output=False)
        changed = _changed(before, arrays_of(system))
        assert changed <= declared, (make.__name__, sorted(changed - declared))
        seen |= changed
    assert not seen & NOT_SEEN, sorted(seen & NOT_SEEN)  # then it belongs to the check
    assert declared - NOT_SEEN <= seen, sorted(declared - NOT_SEEN - seen)


def test_a_failing_run_writes_err():
    # the step loop's failure report (err) is state: a node thrown at 1 km/s fails the
    # speed check (a step of 2.2 cm against half its 1 mm radius) and fills it
    system = engine.build(scene(wedge_press))
    before = system.err.copy()
    system.nodes.v[-1] = (0.0, 1e3, 0.0)
    with pytest.raises(engine.InstabilityError):
        engine.run(system, output=False)
    assert not np.array_equal(system.err, before)
