"""The Results panel's force against depth (issue 14, item 9): the depth of a kinematic
press is the body's travel along its own direction, from its first recorded position."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from studio.plots.result_plots import press_depth


class _Result:
    def __init__(self, positions, motion):
        self.positions = np.asarray(positions, float)
        self.scene = {"bodies": [{"name": "wedge", "motion": {"type": motion}}]}

    def json_attr(self, name):
        return self.scene

    def channels(self):
        return ["time", "bodies/wedge/position"]

    def series(self, channel):
        return self.positions


def _frames(positions, motion="kinematic"):
    return SimpleNamespace(res=_Result(positions, motion), body_names=["wedge"],
                           n_frames=len(positions))


def test_press_depth_is_travel_along_the_press():
    # pressed 2 mm down along -z from z = 33.5 mm, with a sideways drift of 0.1 mm
    z = np.linspace(0.0335, 0.0315, 5)
    x = np.linspace(0.0, 0.0001, 5)
    body, depth = press_depth(_frames(np.stack([x, 0 * x, z], 1)))
    assert body == "wedge"
    # would catch a depth measured along z only (sign) or from the origin instead of frame 0
    total = np.hypot(0.002, 0.0001)
    assert depth == pytest.approx(np.linspace(0, total, 5), rel=1e-12)


def test_no_depth_for_free_or_still_bodies():
    still = np.zeros((4, 3))
    assert press_depth(_frames(still)) is None
    moving = np.stack([np.zeros(4), np.zeros(4), np.linspace(0, 1, 4)], 1)
    assert press_depth(_frames(moving, motion="free")) is None


class _SpinResult:
    """A free body whose spin about z reverses (+1 rad/s, then -1 rad/s), with its contact
    force and torque, a brush's root force and a controller's Delta-v."""

    def __init__(self):
        self.t = np.linspace(0.0, 1.0, 5)
        wz = np.array([1.0, 0.5, 0.0, -0.5, -1.0])
        self.data = {
            "bodies/disc/angular_velocity": np.stack([0 * wz, 0 * wz, wz], 1),
            "bodies/disc/contact_force": np.tile([0.1, -0.2, 0.3], (5, 1)),
            "bodies/disc/contact_torque": np.tile([0.0, 0.0, -0.4], (5, 1)),
            "brushes/brush/root_force": np.tile([1.0, 2.0, -3.0], (5, 1)),
            "controllers/hold/delta_v": np.linspace(0.0, 0.2, 5),
        }
        self.scene = {"bodies": [{"name": "disc", "motion": {"type": "free"}}],
                      "controllers": [{"name": "hold", "body": "disc"}]}

    def json_attr(self, name):
        return self.scene

    def channels(self):
        return ["time", *self.data]

    def series(self, channel):
        return self.data[channel]

    def body_angular_momentum(self, name):
        return 2.0 * self.data["bodies/disc/angular_velocity"]  # I = 2 kg m^2 about z


def _spin_frames():
    r = _SpinResult()
    return SimpleNamespace(res=r, time=r.t, body_names=["disc"], brush_names=["brush"],
                           n_frames=5)


def test_plots_show_signed_components_of_a_reversing_spin():
    from studio.plots.result_plots import result_figures

    figs, cursor_x = result_figures(_spin_frames())
    traces = {d.name: np.asarray(d.y) for d in figs["angular velocity [deg/s]"].data}
    # a reversal is a sign change of the component, not a dip of |omega| to zero
    assert traces["disc ω_z"] == pytest.approx(np.degrees([1.0, 0.5, 0.0, -0.5, -1.0]))
    assert traces["disc |ω|"] == pytest.approx(np.degrees([1.0, 0.5, 0.0, 0.5, 1.0]))
    L = {d.name: np.asarray(d.y) for d in figs["angular momentum [N m s]"].data}
    assert L["disc L_z"][-1] == pytest.approx(-2.0)
    # forces and torques per component (|F| hid F_z): each component its own trace
    F = {d.name: np.asarray(d.y) for d in figs["root force [N]"].data}
    assert set(F) == {"brush F_x", "brush F_y", "brush F_z"}
    assert F["brush F_z"] == pytest.approx([-3.0] * 5)
    T = {d.name: np.asarray(d.y) for d in figs["contact torque on bodies [N m]"].data}
    # a controlled body in a file without actuator channels: its "contact" channel holds
    # the thrust too, and the label says so (issue 29, item 5)
    assert T["disc (contact + actuator) T_z"] == pytest.approx([-0.4] * 5)
    assert "actuator force on bodies [N]" not in figs
    dv = figs["Δv of the controlled body [m/s]"].data[0]
    assert dv.name.startswith("disc Δv") and dv.y[-1] == pytest.approx(0.2)
    # no trace of the cursor's red, and every plot's x is the time (no press here)
    from studio.plots.result_plots import CURSOR_COLOR
    assert not cursor_x
    assert all(d.line.color != CURSOR_COLOR for f in figs.values() for d in f.data)


def test_contact_and_actuator_series_come_from_their_own_channels():
    """With the engine's actuator channels (issue 22), a controlled body's thrust gets its
    own plot and the contact plot shows the contact channel alone: a plot that read the
    thrust into "contact force" (issue 29, item 5) would fail here."""
    from studio.plots.result_plots import result_figures

    frames = _spin_frames()
    frames.res.data["bodies/disc/actuator_force"] = np.tile([5.0, 0.0, 0.0], (5, 1))
    frames.res.data["bodies/disc/actuator_torque"] = np.zeros((5, 3))
    figs, _ = result_figures(frames)
    contact = {d.name: np.asarray(d.y) for d in figs["contact force on bodies [N]"].data}
    assert set(contact) == {"disc F_x", "disc F_y", "disc F_z"}
    assert contact["disc F_x"] == pytest.approx([0.1] * 5)
    thrust = {d.name: np.asarray(d.y) for d in figs["actuator force on bodies [N]"].data}
    assert thrust["disc F_x"] == pytest.approx([5.0] * 5)
    assert "actuator torque on bodies [N m]" not in figs  # (all zero: nothing to show)


def test_several_bodies_show_one_coloured_magnitude_each():
    """Three bodies (the gripper's fingers and target): one |F| per body, each its own
    colour, the 9 components hidden in the legend (issue 29, item 6)."""
    from studio.plots.result_plots import result_figures

    frames = _spin_frames()
    for name, f in (("a", [3.0, 4.0, 0.0]), ("b", [0.0, 0.0, 2.0])):
        frames.res.data[f"bodies/{name}/contact_force"] = np.tile(f, (5, 1))
    frames.body_names = ["disc", "a", "b"]
    frames.res.scene["controllers"] = []
    figs, _ = result_figures(frames)
    data = figs["contact force on bodies [N]"].data
    shown = [d for d in data if d.visible is not False and d.visible != "legendonly"]
    assert [d.name for d in shown] == ["disc |F|", "a |F|", "b |F|"]
    assert len({d.line.color for d in shown}) == 3
    assert np.asarray(shown[1].y) == pytest.approx([5.0] * 5)  # |(3, 4, 0)|
    assert sum(d.visible == "legendonly" for d in data) == 9


def test_the_time_slider_picks_the_nearest_recorded_frame():
    from studio.web.panels.results import ResultsPanel

    panel = SimpleNamespace(playback=SimpleNamespace(time=np.array([0.0, 0.02, 0.04, 0.05])))

    def frame(t):
        return ResultsPanel.frame_at(panel, t)

    # would catch a floor (0.039 -> 1) or an index read as a time
    assert [frame(t) for t in (-1.0, 0.0, 0.009, 0.011, 0.039, 0.046, 0.05, 7.0)] == \
        [0, 0, 0, 1, 2, 3, 3, 3]
