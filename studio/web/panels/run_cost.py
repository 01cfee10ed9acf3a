"""What a design will cost before Start (issue 14, defects 5 and 6), as text for the page:
the timestep and what limits it, steps, nodes, the wall time and the result file, and a
warning when a given dt exceeds the stability limit. No viser in here.

Everything comes from the engine's own cost model (``engine.estimate``: the build's
Gershgorin bound on one bristle per brush, frames and bytes per channel); the wall time is
its node-steps divided by a rate of node-steps per second: the rate the latest finished run
of this studio measured (the machine as it is now), else ``DEFAULT_NODE_STEPS_PER_S``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

from studio.web.panels.common import _fmt_rate, _fmt_s, _md_escape

# node-steps per second of one worker when no run has been measured yet: the lowest of the
# presets' CPU-time rates in static_presets/README.md (wedge_75, a full brush pressed deep:
# 8.36e5 steps x 680 nodes / 650 CPU-s = 0.87e6; spin_cube_20 3.1e6, gripper 1.7e6),
# rounded down, so that the first estimate errs on the long side
DEFAULT_NODE_STEPS_PER_S = 0.8e6
# a run whose estimated wall time is above this asks for confirmation before it starts
CONFIRM_ABOVE_S = 300.0
# the channels the Run settings offer, in the order shown, with what each is for
CHANNEL_HINTS = {
    "nodes": "bristle node positions: playback moves the bristles; colour by deflection",
    "bending": "bending moment per bond: colour by bending moment",
    "bodies": "body poses, velocities, contact forces: playback moves the bodies",
    "root_force": "force and torque at the bristle roots per brush",
    "energy": "energy balance",
    "contacts": "contact counts",
    "node_velocities": "node velocities and spins (doubles the nodes' share of the file)",
}


@dataclass(frozen=True)
class RunCost:
    """The engine's estimate of a design and the wall time at ``rate`` node-steps/s."""

    cost: object            # engine.Cost
    rate: float             # node-steps per second
    rate_source: str        # where the rate comes from, in words
    wall_s: float

    @property
    def needs_confirmation(self) -> bool:
        return self.wall_s > CONFIRM_ABOVE_S

    @property
    def dt_unstable(self) -> bool:
        c = self.cost
        return c.dt_given and c.dt > c.dt_bound


def measured_rate(jobs) -> Optional[tuple[float, str]]:
    """(node-steps/s, job id) of the latest finished run of ``jobs`` that measured one."""
    if jobs is None:
        return None
    try:
        listed = jobs.list(limit=50, kind="run")
    except Exception:
        return None
    for j in listed:  # newest first
        rate = (j.summary or {}).get("node_steps_per_s")
        if j.status == "completed" and isinstance(rate, (int, float)) and rate > 0:
            return float(rate), j.id
    return None


def run_cost(scene, measured: Optional[tuple[float, str]] = None) -> RunCost:
    """The cost of a design: the studio's validated ``engine.Scene`` (no second parse), or
    a scene dict (parsed; raises ``engine.SceneError`` if it is invalid)."""
    import engine

    if isinstance(scene, dict):
        scene = engine.parse_scene(scene)
    cost = engine.estimate(scene)
    if measured is not None:
        rate, source = measured[0], f"measured by run `{measured[1]}`"
    else:
        rate, source = DEFAULT_NODE_STEPS_PER_S, "typical rate, no run measured yet"
    wall = cost.node_steps / rate if math.isfinite(cost.node_steps) else math.inf
    return RunCost(cost=cost, rate=rate, rate_source=source, wall_s=wall)


def _fmt_us(seconds: float) -> str:
    return f"{seconds * 1e6:.4g} µs"


def _fmt_bytes(n: float) -> str:
    if n >= 2**30:
        return f"{n / 2**30:.1f} GiB"
    if n >= 2**20:
        return f"{n / 2**20:.0f} MiB"
    return f"{n / 2**10:.0f} KiB"


def dt_warning(rc: RunCost) -> str:
    """The warning under the dt field ('' when dt is automatic or below the limit)."""
    c = rc.cost
    if not rc.dt_unstable:
        return ""
    return (f"⚠ dt = {_fmt_us(c.dt)} is {c.dt / c.dt_bound:.3g} × the stability limit "
            f"{_fmt_us(c.dt_bound)} (set by {_md_escape(c.dt_limited_by)}): the run will blow "
            f"up. Use 0 (automatic) or less than {_fmt_us(c.dt_bound)}.")


def cost_line(rc: RunCost) -> str:
    """The line beside Start: dt and what limits it, steps, nodes, wall time, file size."""
    c = rc.cost
    if c.dt_given:
        dt = f"dt **{_fmt_us(c.dt)}** (given; limit {_fmt_us(c.dt_bound)})"
    elif math.isfinite(c.dt_bound):
        dt = f"dt **~{_fmt_us(c.dt)}** (automatic, limited by {_md_escape(c.dt_limited_by)})"
    else:  # (the estimate leaves bodies out: without bristles the build's bodies set dt)
        dt = "dt set at build by the bodies' contacts (no bristles to estimate it from)"
    wall = (f"~{_fmt_s(rc.wall_s)}" if c.n_nodes else "seconds (no bristles)")
    steps = f"**{c.steps:,.0f}** steps · " if math.isfinite(c.dt_bound) or c.dt_given else ""
    text = (f"**Before Start:** {dt} · {steps}**{c.n_nodes:,}** nodes · "
            f"wall **{wall}** (at {_fmt_rate(rc.rate)} node-steps/s, {rc.rate_source}) · "
            f"result file **~{_fmt_bytes(c.result_bytes)}** ({c.frames:,.0f} frames)")
    if rc.dt_unstable:
        text += ("  \n<span style='color:#d00'>⚠ dt is above the stability limit: see "
                 "Design → Run settings</span>")
    if rc.needs_confirmation:
        text += (f"  \n<span style='color:#b60'>Over {_fmt_s(CONFIRM_ABOVE_S)}: Start asks "
                 f"to confirm</span>")
    return text
