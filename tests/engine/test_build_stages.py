"""Only what a scene needs is assembled, bad runs stop loudly, cancels keep their frames."""
import threading

import numpy as np
import pytest

import engine

SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0}


def scene(**over):
    d = {"materials": {"silicone": SILICONE, "pla": {"youngs_modulus": 3.5e9,
                                                     "density": 1240.0}},
         "brushes": [{"name": "b", "material": "silicone", "rows": 1, "columns": 1,
                      "bristle_length": 0.02, "root_radius": 0.001, "tip_radius": 0.0008,
                      "n_nodes": 4}],
         "run": {"duration": 0.002, "record_interval": 0.001}}
    d.update(over)
    return engine.parse_scene(d)


def test_single_bristle_without_body_assembles_only_bonds():
    s = engine.build(scene(run={"duration": 0.002, "record_interval": 0.001,
                                "channels": ["nodes"]}))
    assert s.stages == ["bonds"]
    assert not s.flags.bristle_bristle and not s.flags.bristle_body
    assert not s.flags.gravity and not s.flags.track_energy


def test_distant_bristles_get_no_bristle_bristle_stage():
    far = scene(brushes=[{"name": "b", "material": "silicone", "rows": 1, "columns": 2,
                          "pitch": [0.1, 0.1], "bristle_length": 0.02,
                          "root_radius": 0.001, "tip_radius": 0.0008, "n_nodes": 4}])
    near = scene(brushes=[{"name": "b", "material": "silicone", "rows": 1, "columns": 2,
                           "pitch": [0.003, 0.003], "bristle_length": 0.02,
                           "root_radius": 0.001, "tip_radius": 0.0008, "n_nodes": 4}])
    assert "bristle_bristle_contacts" not in engine.build(far).stages
    assert "bristle_bristle_contacts" in engine.build(near).stages


def test_friction_gravity_and_bodies_switch_their_stages():
    base = dict(brushes=[{"name": "b", "material": "silicone", "rows": 2, "columns": 2,
                          "pitch": [0.003, 0.003], "bristle_length": 0.02,
                          "root_radius": 0.001, "tip_radius": 0.0008, "n_nodes": 4}])
    s = engine.build(scene(**base))
    assert "tangential_history" not in s.stages and s.pairs.ft.shape[0] == 0  # no history
    assert "gravity" not in s.stages and "bristle_body_contacts" not in s.stages
    s = engine.build(scene(**base, contact_pairs=[{"materials": ["silicone", "silicone"],
                                                   "friction_angle": 0.5}],
                           environment={"gravity": [0, 0, -9.81]},
                           bodies=[{"name": "box", "material": "pla",
                                    "shape": {"type": "box", "size": [0.01, 0.01, 0.01]},
                                    "pose": {"position": [0, 0, 0.03]}}]))
    assert {"tangential_history", "gravity", "bristle_body_contacts"} <= set(s.stages)


def test_only_requested_channels_are_recorded(tmp_path):
    s = engine.build(scene(run={"duration": 0.002, "record_interval": 0.001,
                                "channels": ["energy"]}))
    with engine.run(s, output=tmp_path / "r.h5").open() as res:
        assert not any(c.startswith("nodes/") for c in res.channels())
        assert "energy/total" in res.channels()
        summary = res.summary
    assert set(summary["assembled"]) == {"bonds", "energy_tracking"}
    assert summary["dt_limited_by"] and summary["node_steps_per_s"] > 0


def test_too_large_dt_stops_with_a_clear_error_and_keeps_frames(tmp_path):
    s0 = engine.build(scene())
    bad = scene(loads=[{"brush": "b", "node": -1, "force": [0.01, 0, 0]}],
                run={"duration": 0.05, "record_interval": 5 * s0.dt_stable,
                     "dt": 3 * s0.dt_stable})
    s = engine.build(bad)
    assert any("exceeds the estimated stability limit" in w for w in s.warnings)
    with pytest.raises(engine.InstabilityError) as err:
        engine.run(s, output=tmp_path / "bad.h5")
    e = err.value
    # where it shows first: at a node of the bristle, or (its forces now applied from t = 0)
    # in the energy balance of the whole scene; either way the advice names run.dt
    assert ("bristle 0" in e.where or e.quantity == "energy balance") and "dt" in e.advice
    assert e.time > 0
    with engine.open_result(tmp_path / "bad.h5") as res:
        assert res.status == "failed"
        assert res.n_frames >= 1
        assert np.all(np.isfinite(res.series("nodes/positions")))


def _bullet(**run):
    return scene(bodies=[{"name": "bullet", "material": "pla",
                          "shape": {"type": "sphere", "radius": 0.002},
                          "mass_properties": {"density": 1240}, "motion": {"type": "free"},
                          "pose": {"position": [0.0, 0.0, 0.05]},
                          "velocity": [0.0, 0.0, -5000.0]}], **run)


def test_the_automatic_dt_keeps_a_fast_body_from_tunnelling():
    s = engine.build(_bullet())
    assert "speed of body 'bullet'" in s.dt_limited_by
    r_min = float(s.nodes.rad.min())
    # the step loop stops a body moving over 0.25 r_min per step; automatic dt keeps half
    assert 5000.0 * s.dt <= 0.5 * 0.25 * r_min * (1 + 1e-12)


def test_a_body_too_fast_for_a_given_dt_is_refused(tmp_path):
    dt = engine.build(_bullet()).dt_stable
    fast = _bullet(run={"duration": 0.01, "record_interval": 1e-3, "dt": 0.5 * dt})
    s = engine.build(fast)
    assert any("tunnelling" in w for w in s.warnings)
    with pytest.raises(engine.InstabilityError) as err:
        engine.run(s, output=tmp_path / "f.h5")
    assert err.value.quantity == "body displacement per step"
    assert "bullet" in err.value.where


def test_cancel_stops_the_run_and_keeps_a_readable_file(tmp_path):
    s = engine.build(scene(run={"duration": 1.0, "record_interval": 0.0005}))
    stop = threading.Event()
    result = engine.run(s, output=tmp_path / "c.h5", cancel=stop, progress_interval=0.0,
                        on_progress=lambda p: stop.set())
    assert result.status == "cancelled"
    with result.open() as res:
        assert res.status == "cancelled" and res.n_frames >= 1
        assert res.time[-1] < 1.0


# ---- one stage vocabulary (engine.state.STAGE_TABLE)
def test_stage_table_is_the_documented_one():
    """docs/api.md's table of stages is engine.state.stages_markdown(): catches a stage added
    to the engine (or renamed) without the page saying what it is."""
    from pathlib import Path

    from engine.state import stages_markdown

    page = (Path(__file__).resolve().parents[2] / "docs" / "api.md").read_text()
    start = page.index("<!-- stages table: engine.state.stages_markdown() -->\n")
    end = page.index("<!-- end stages table -->")
    assert page[start:end].split("\n", 1)[1].strip() == stages_markdown()


def test_every_switch_of_the_step_loop_names_a_stage():
    """Each boolean Flags field switches at least one named stage, and turning it alone on
    assembles exactly the stages that need it: catches a new branch of the step loop that
    the summary and the timings would not know about."""
    from engine.state import STAGE_TABLE, Flags, assembled_stages

    counters = {"check_every", "time_every"}
    off = Flags(**{f: (1 if f in counters else False) for f in Flags._fields})
    assert assembled_stages(off) == []
    for field in Flags._fields:
        if field in counters:
            continue
        on = assembled_stages(off._replace(**{field: True}))
        assert on, f"Flags.{field} switches no stage"
        assert on == [st.name for st in STAGE_TABLE if st.needed(off._replace(**{field: True}))]


def test_summary_times_exactly_the_slots_of_the_assembled_stages(tmp_path):
    """A bristle alone: the summary times its bonds and the always-run slots, not the
    contact slots it never runs (which would show as zero-cost stages)."""
    s = engine.build(scene(run={"duration": 0.002, "record_interval": 0.001,
                                "channels": ["nodes"]}))
    summary = engine.run(s, output=tmp_path / "r.h5").summary
    assert set(summary["stages"]) == {"integrate", "bonds", "external_forces", "checks",
                                      "recording"}


def test_mesh_mesh_stage_only_for_mesh_pairs():
    """A free sphere body against a fixed box runs body-body contacts but not the mesh-mesh
    kernel (its own flag): catches the mesh-mesh kernel switched by the body-body flag."""
    d = dict(bodies=[{"name": "ball", "material": "pla", "motion": {"type": "free"},
                      "mass_properties": {"density": 1240.0},
                      "shape": {"type": "sphere", "radius": 0.005},
                      "pose": {"position": [0, 0, 0.05]}},
                     {"name": "box", "material": "pla",
                      "shape": {"type": "box", "size": [0.02, 0.02, 0.02]},
                      "pose": {"position": [0, 0.1, 0.05]}}])
    s = engine.build(scene(**d))
    assert "body_body_contacts" in s.stages and "mesh_mesh_contacts" not in s.stages
    assert s.flags.body_body and not s.flags.mesh_mesh


def test_a_tangential_spring_only_where_a_pair_has_friction():
    # silicone-silicone with friction; silicone-pla with a tangential ratio but no friction:
    # a mode taken from the tangential ratio, or from any pair, would give the body contacts
    # a slip mode and a history (engine.state.friction_mode, the rule's one home)
    from engine.state import Friction, tangential_ratio

    s = engine.build(scene(
        brushes=[{"name": "b", "material": "silicone", "rows": 2, "columns": 2,
                  "pitch": [0.003, 0.003], "bristle_length": 0.02, "root_radius": 0.001,
                  "tip_radius": 0.0008, "n_nodes": 4}],
        contact_pairs=[{"materials": ["silicone", "silicone"], "friction_angle": 0.5},
                       {"materials": ["silicone", "pla"], "friction_angle": 0.0,
                        "tangential_ratio": 0.9}],
        bodies=[{"name": "box", "material": "pla",
                 "shape": {"type": "box", "size": [0.01, 0.01, 0.01]},
                 "pose": {"position": [0, 0, 0.03]}}]))
    assert s.flags.bristle_bristle and s.flags.bristle_body
    assert s.flags.friction_bristle == Friction.SLIP_EACH_STEP
    assert s.flags.friction_body == Friction.NONE and s.body_pairs.ft.shape[0] == 0
    assert type(s.flags.friction_body) is int  # numba would compile an IntEnum Flags anew
    assert tangential_ratio(0.9, 0.0) == 0.0 and tangential_ratio(0.9, 0.1) == 0.9
