"""A user dt above the stability limit is named as the cause of the blow-up (issue 14,
defect 5: spin_cube_40 at dt = 1000 us used to fail advising to reduce ``tip_variance``,
which is 0), and the estimate gives the same limit before anything is built."""
from __future__ import annotations

import pytest

import engine
from engine.assembly.estimate import stability_bound
from studio import presets


def _scene(dt=None):
    data = presets.load_preset("spin_cube_40").model_dump(mode="json")
    data["run"]["dt"] = dt
    return engine.parse_scene(data)


def test_the_estimated_stability_limit_is_the_builds():
    scene = _scene()
    bound, limited_by = stability_bound(scene)
    system = engine.build(scene)
    # the same Gershgorin bound on the same bristle (a bristle sets it here): equal to rounding
    assert bound == pytest.approx(system.dt_stable, rel=1e-9)
    assert "brush" in limited_by
    # and it does not depend on a given dt (the studio warns against the bound, not the dt)
    assert stability_bound(_scene(dt=1e-3))[0] == pytest.approx(bound, rel=1e-12)


def test_an_unstable_user_dt_is_named_as_the_cause():
    scene = _scene(dt=1e-3)   # ~70 x the limit, as in the issue
    system = engine.build(scene)
    assert system.dt == pytest.approx(1e-3)
    assert system.dt_stable < 1e-4
    with pytest.raises(engine.InstabilityError) as info:
        engine.run_steps(system, 200)  # 0.2 s: the run failed at 3 ms
    message = str(info.value)
    assert "run.dt = 0.001 s" in message
    assert f"stability limit {system.dt_stable:.3g} s" in message
    assert "tip_variance" not in message and "dt_safety (now" not in message


def test_a_stable_dt_keeps_the_specific_advice():
    """With no dt given there is no dt to blame: the advice is the failure's own."""
    from engine.stepping.diagnosis import dt_cause

    system = engine.build(_scene())
    assert dt_cause(system) is None
    system = engine.build(_scene(dt=0.5 * engine.build(_scene()).dt_stable))
    assert dt_cause(system) is None
