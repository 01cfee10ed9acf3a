"""The plots of a run: plotly figures of a result file (forces, against the depth of a pressed
body too, angular velocity and momentum, Delta-v, energies), numpy and plotly only, no viser:
the Results panel shows them, the CLI demo draws its PNG from :func:`press_depth_of`."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from studio.plots.result_frames import ResultFrames

FORCE_COLORS = ("#1f77b4", "#2ca02c", "#9467bd")  # x, y, z components (none is the cursor's)
CURSOR_COLOR = "#d62728"  # the Results panel's time cursor on every plot
MAGNITUDE_COLOR = "#7f7f7f"  # |omega|, |L|
DASHES = ("solid", "dash", "dot", "dashdot")  # one per brush / body on a plot


def _scene_motions(result) -> tuple[dict, dict]:
    """The scene a result file was run from (``{}`` for a file without one) and each body's
    motion type by name."""
    try:
        scene = result.json_attr("scene") or {}
    except Exception:
        scene = {}
    return scene, {b.get("name"): (b.get("motion") or {}).get("type")
                   for b in scene.get("bodies") or []}


def press_depth(res: ResultFrames):
    """For a run whose body is pressed kinematically into the brush: (body name, depth per
    frame in m), the body's displacement from its first recorded position along its overall
    direction of travel; None when no kinematic body moves."""
    return press_depth_of(res.res, res.body_names)


def press_depth_of(result, body_names=None):
    """:func:`press_depth` of an open result file (``engine.open_result``): also for plots
    made without the studio."""
    _, motions = _scene_motions(result)
    if body_names is None:
        body_names = list(result.json_attr("body_names") or [])
    channels = set(result.channels())
    for name in body_names:
        c = f"bodies/{name}/position"
        if motions.get(name) != "kinematic" or c not in channels:
            continue
        x = np.asarray(result.series(c), float)
        if len(x) < 2:
            continue
        d = x - x[0]
        far = int(np.argmax(np.linalg.norm(d, axis=1)))
        span = float(np.linalg.norm(d[far]))
        if span <= 0:
            continue
        return name, d @ (d[far] / span)
    return None


def _components(fig, x, v, name: str, dash: str, axes: str = "xyz") -> None:
    for k, axis in enumerate(axes):
        fig.add_scatter(x=x, y=v[:, k], name=f"{name}{axis}", mode="lines",
                        line=dict(color=FORCE_COLORS[k], dash=dash))


def _magnitude(fig, x, v, name: str, dash: str, color: str = MAGNITUDE_COLOR) -> None:
    fig.add_scatter(x=x, y=np.linalg.norm(v, axis=1), name=name, mode="lines",
                    line=dict(color=color, dash=dash, width=1.5))


#: one colour per body where a plot shows several bodies (none is the cursor's red)
BODY_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2",
               "#17becf", "#bcbd22")
#: above this many component traces a plot shows each body's magnitude instead, in its own
#: colour, with the components one click away in the legend (the gripper's 9 traces in 3
#: colours x 3 dashes could not be told apart, issue 29 item 6)
MAX_COMPONENT_TRACES = 3


def _per_body(fig, x, series: dict, symbol: str, dash_by_name: dict) -> None:
    """Vector series of several bodies on one plot: components when there is one body;
    else each body's magnitude in a colour of its own, and its components hidden in the
    legend (shown by a click)."""
    if 3 * len(series) <= MAX_COMPONENT_TRACES:
        for name, v in series.items():
            _components(fig, x, v, f"{name} {symbol}", dash_by_name[name])
        return
    for n, (name, v) in enumerate(series.items()):
        color = BODY_COLORS[n % len(BODY_COLORS)]
        _magnitude(fig, x, v, f"{name} |{symbol.rstrip('_')}|", "solid", color)
        for k, axis in enumerate("xyz"):
            fig.add_scatter(x=x, y=v[:, k], name=f"{name} {symbol}{axis}", mode="lines",
                            visible="legendonly",
                            line=dict(color=color, dash=DASHES[(k + 1) % len(DASHES)],
                                      width=1))


def contact_and_actuator(result, body_names, key: str) -> tuple[dict, dict, set]:
    """The contact and the actuator series (``key``: ``force`` or ``torque``) of each body,
    from their own channels: ``bodies/<name>/contact_<key>`` and, where the engine records
    it, ``bodies/<name>/actuator_<key>`` (a controller's thrust). Returns (contact, actuator,
    mixed): ``mixed`` names the controlled bodies of a file that has no actuator channel,
    whose contact channel then carries the thrust too (files written before the engine
    separated them)."""
    channels = set(result.channels())
    scene, _ = _scene_motions(result)
    controlled = {c.get("body") for c in scene.get("controllers") or []}
    contact, actuator, mixed = {}, {}, set()
    for name in body_names:
        c, a = f"bodies/{name}/contact_{key}", f"bodies/{name}/actuator_{key}"
        if c in channels:
            contact[name] = np.asarray(result.series(c), float)
        if a in channels:
            actuator[name] = np.asarray(result.series(a), float)
        elif name in controlled and name in contact:
            mixed.add(name)
    return contact, actuator, mixed


def result_figures(res: ResultFrames) -> tuple[dict, dict]:
    """The plots of a run (plotly figures by title, SI but for degrees and millimetres)
    and, for a plot whose x is not the time, its x at each frame (where its cursor goes):

    * root force F_x, F_y, F_z per brush; contact force and contact torque on each body,
      per component (|F| hid F_z, issue 14 item 9), or with several bodies each body's
      magnitude in its own colour (components in the legend); a controller's thrust in
      its own plot (``actuator_force``/``actuator_torque``, where the file records them);
    * root force, and the contact force on the pressed body, against the depth of a
      kinematically pressed body;
    * each moving body's angular velocity, signed components and |omega| [deg/s] (a
      reversal shows as a sign change, not a dip to zero);
    * each free body's spin angular momentum L (inertial, ``ResultFile.
      body_angular_momentum``), components and |L| [N m s];
    * each controller's accumulated Delta-v, the integral of |F|/m [m/s] (docs/mission.md);
    * the energies."""
    import plotly.graph_objects as go

    r, t = res.res, res.time
    channels = set(r.channels())
    scene, motions = _scene_motions(r)
    figs, cursor_x = {}, {}

    f, forces = go.Figure(), {}
    for n, brush in enumerate(res.brush_names):
        c = f"brushes/{brush}/root_force"
        if c in channels:
            forces[brush] = np.asarray(r.series(c), float)
            _components(f, t, forces[brush], f"{brush} F_", DASHES[n % len(DASHES)])
    if forces:
        figs["root force [N]"] = f
    dash_by_name = {name: DASHES[n % len(DASHES)] for n, name in enumerate(res.body_names)}
    for key, unit, symbol in (("force", "N", "F_"), ("torque", "N m", "T_")):
        contact, actuator, mixed = contact_and_actuator(r, res.body_names, key)
        # a body that never touched anything (a chaser whose hull has no contact) is left
        # out, unless none touched
        touched = {n: v for n, v in contact.items() if np.any(v)} or contact
        labelled = {(f"{n} (contact + actuator)" if n in mixed else n): v
                    for n, v in touched.items()}
        dashes = dict(dash_by_name, **{f"{n} (contact + actuator)": dash_by_name[n]
                                       for n in mixed})
        f = go.Figure()
        _per_body(f, t, labelled, symbol, dashes)
        if f.data:
            figs[f"contact {key} on bodies [{unit}]"] = f
        pushing = {n: v for n, v in actuator.items() if np.any(v)}
        if pushing:
            f = go.Figure()
            _per_body(f, t, pushing, symbol, dash_by_name)
            figs[f"actuator {key} on bodies [{unit}]"] = f

    press = press_depth(res)
    if press is not None:
        body, depth = press
        pushed = f"bodies/{body}/contact_force"
        plots = [(f"root force [N] against depth of {body} [mm]", forces, "F_")]
        if pushed in channels:  # what a scale under the press reads (no brush weight)
            plots.append((f"contact force on {body} [N] against its depth [mm]",
                          {body: np.asarray(r.series(pushed), float)}, "F_"))
        for title, series, symbol in plots:
            if not series:
                continue
            f = go.Figure()
            for n, (name, F) in enumerate(series.items()):
                _components(f, depth * 1e3, F, f"{name} {symbol}", DASHES[n % len(DASHES)])
            f.update_layout(xaxis_title=f"depth of {body} [mm]")
            figs[title] = f
            cursor_x[title] = depth * 1e3

    f = go.Figure()
    for n, name in enumerate(res.body_names):
        c = f"bodies/{name}/angular_velocity"
        if c in channels and motions.get(name) != "fixed":
            w = np.degrees(np.asarray(r.series(c), float))
            if not np.any(w):
                continue
            dash = DASHES[n % len(DASHES)]
            _magnitude(f, t, w, f"{name} |ω|", dash)  # (first: the components over it)
            _components(f, t, w, f"{name} ω_", dash)
    if f.data:
        figs["angular velocity [deg/s]"] = f

    f = go.Figure()
    for n, name in enumerate(res.body_names):
        if motions.get(name) != "free" or f"bodies/{name}/angular_velocity" not in channels:
            continue
        try:
            L = np.asarray(r.body_angular_momentum(name), float)
        except Exception:  # (a file without the mass properties it needs)
            continue
        dash = DASHES[n % len(DASHES)]
        _magnitude(f, t, L, f"{name} |L|", dash)
        _components(f, t, L, f"{name} L_", dash)
    if f.data:
        figs["angular momentum [N m s]"] = f

    f = go.Figure()
    for ctl in scene.get("controllers") or []:
        c = f"controllers/{ctl.get('name')}/delta_v"
        if c in channels:
            f.add_scatter(x=t, y=np.asarray(r.series(c), float),
                          name=f"{ctl.get('body')} Δv ({ctl.get('name')})", mode="lines",
                          line=dict(color=FORCE_COLORS[0]))
    if f.data:
        figs["Δv of the controlled body [m/s]"] = f

    f = go.Figure()
    for e in ("kinetic", "bond", "contact", "gravity", "total"):
        c = f"energy/{e}"
        if c in channels:
            f.add_scatter(x=t, y=np.asarray(r.series(c)), name=e, mode="lines")
    if f.data:
        figs["energy [J]"] = f

    for title, fig in figs.items():
        fig.update_layout(title=dict(text=title, font=dict(size=14)),
                          margin=dict(l=50, r=10, t=34, b=40),
                          legend=dict(font=dict(size=11)))
        if title not in cursor_x:
            fig.update_layout(xaxis_title="time [s]")
    return figs, cursor_x
