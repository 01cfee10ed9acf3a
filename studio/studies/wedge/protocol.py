"""The hold-until-steady protocol of the wedge-based studies (seed 4.2; the run itself is
:func:`studio.studies.wedge.wedge_cycle`): its defaults and methods, the protocol of a scene
(:func:`make_protocol`), and the options that set it (:class:`ProtocolOptions`) (shared by the wedge,
refinement, sensitivity and Monte Carlo commands)."""
from __future__ import annotations

import math
from typing import Literal, Optional

from pydantic import Field

from studio.studies.options import StudyOptions
from studio.studies.wedge.scenes import StudyInputError, find_body

PROTOCOL_DEFAULTS = {
    "method": "quasi_static",  # or "dynamic": the seed's hold-until-steady windows
    "window": 0.05,            # s, one hold window (dynamic)
    "frames_per_window": 10,   # force samples per window (dynamic)
    "threshold": 2e-5,         # N, absolute tolerance (std, or out-of-balance force)
    "rel_threshold": 0.005,    # fraction of the current force change
    "max_hold": 1.0,           # s, longest hold after one step
    # quasi-static only (docs/studies.md): numerical settings that leave equilibria unchanged
    "qs_local_damping": 0.5,
    "qs_inertia_scaling": "equalize",
    "qs_kinetic_damping": True,   # stop every node when the kinetic energy has peaked
    "qs_dt_safety": 0.95,         # run.dt_safety (fraction of the stability bound)
    "qs_checks_per_period": 100,  # balance checks per period of the slowest bristle
    "qs_max_acceleration": 4.0,  # m/s^2, a_m of each increment's parabolic move
    "qs_increments": 1,          # increments per step, each settled and its slip committed
    # m, standard deviation of a seeded scatter of the tips in the base plane given to every
    # brush that has none (tip_variance 0), both methods: a perfectly straight brush under a
    # symmetric wedge otherwise sits on an unstable symmetric equilibrium (docs/studies.md)
    "tip_scatter": 1e-6,
}
METHODS = ("quasi_static", "dynamic")
METHOD_NOTES = {
    "quasi_static": "slip committed per increment (frozen Coulomb trial within it), fast "
                    "moves, local and kinetic damping, equalized inertia, dt at 0.95 of the "
                    "bound; holds end on the out-of-balance force and kinetic energy. On the "
                    "60 deg wedge (5 nodes, 0-10 mm) it matches the dynamic method at a_m "
                    "0.1 m/s^2 within 1.1 % from 2 mm on, closer than the dynamic method at "
                    "a_m 0.4 is to it (docs/studies.md; "
                    "tests/studies/test_wedge_quasistatic.py)",
    "dynamic": "the seed's protocol in physical time under the scene's damping; its curve "
               "depends on a_m (docs/studies.md)"}


def make_protocol(scene: dict, *, body: str = "wedge", brush: Optional[str] = None,
                  depth: Optional[float] = None, step: Optional[float] = None,
                  max_acceleration: Optional[float] = None, unload: bool = True,
                  **overrides) -> dict:
    """The hold-until-steady protocol for ``scene``: step, a_m, direction and number of steps
    from the wedge's stepped_parabolic profile (full depth = n_steps * step) unless given;
    window, thresholds and maximum hold from :data:`PROTOCOL_DEFAULTS` unless given."""
    b = find_body(scene, body)
    if b.get("motion", {}).get("type") != "kinematic":
        raise StudyInputError(f"body {body!r} must be kinematic (it is "
                              f"{b.get('motion', {}).get('type', 'fixed')})")
    prof = b["motion"].get("profile", {})
    sp = prof if prof.get("kind") == "stepped_parabolic" else {}
    step = float(step if step is not None else sp.get("step", 0.001))
    a_m = float(max_acceleration if max_acceleration is not None
                else sp.get("max_acceleration", 0.4))
    if depth is None:
        if not sp:
            raise StudyInputError("give the depth: the wedge's profile is not "
                                  "stepped_parabolic")
        depth = sp["n_steps"] * step
    n_steps = int(round(depth / step))
    if n_steps < 1 or abs(n_steps * step - depth) > 1e-9:
        raise StudyInputError(f"depth {depth:g} m is not a whole number (>= 1) of "
                              f"{step:g} m steps")
    if not (a_m > 0 and step > 0):
        raise StudyInputError("step and max_acceleration must be > 0")
    direction = [float(x) for x in sp.get("direction", [0.0, 0.0, -1.0])]
    norm = math.sqrt(sum(x * x for x in direction))
    brushes = [x["name"] for x in scene.get("brushes", [])]
    if brush is None:
        if not brushes:
            raise StudyInputError("the scene has no brush")
        brush = brushes[0]
    elif brush not in brushes:
        raise StudyInputError(f"the scene has no brush {brush!r} (brushes: {brushes})")
    proto = dict(PROTOCOL_DEFAULTS)
    unknown = set(overrides) - set(PROTOCOL_DEFAULTS)
    if unknown:
        raise StudyInputError(f"unknown protocol settings {sorted(unknown)}")
    proto.update({k: v for k, v in overrides.items() if v is not None})
    if proto["method"] not in METHODS:
        raise StudyInputError(f"method = {proto['method']!r}: one of {', '.join(METHODS)}")
    for k in ("window", "threshold", "max_hold", "qs_checks_per_period",
              "qs_max_acceleration", "qs_increments"):
        if not proto[k] > 0:
            raise StudyInputError(f"{k} = {proto[k]}: must be > 0")
    if not 0 <= proto["qs_local_damping"] < 1:
        raise StudyInputError(f"qs_local_damping = {proto['qs_local_damping']}: in [0, 1)")
    if not proto["tip_scatter"] >= 0:
        raise StudyInputError(f"tip_scatter = {proto['tip_scatter']}: must be >= 0")
    if not 0 < proto["qs_dt_safety"] <= 1:
        raise StudyInputError(f"qs_dt_safety = {proto['qs_dt_safety']}: in (0, 1]")
    if proto["qs_inertia_scaling"] not in ("none", "equalize"):
        raise StudyInputError("qs_inertia_scaling must be 'none' or 'equalize'")
    if int(proto["qs_increments"]) != proto["qs_increments"]:
        raise StudyInputError("qs_increments must be a whole number")
    if proto["frames_per_window"] < 3:
        raise StudyInputError("frames_per_window must be >= 3 (a standard deviation)")
    proto.update(body=body, brush=brush, step=step, max_acceleration=a_m,
                 n_steps=n_steps, direction=[x / norm for x in direction],
                 unload=bool(unload))
    return proto


def step_duration(step: float, max_acceleration: float) -> float:
    """t_d = sqrt(6 s / a_m), seed eq. 4.3."""
    return math.sqrt(6.0 * step / max_acceleration)


# ----------------------------------------------------------------------------- options
PROTOCOL_GROUP = "protocol (defaults: the scene's wedge profile; docs/studies.md)"


def _protocol(description: str, unit: Optional[str] = None, metavar: Optional[str] = None,
              **bounds):
    """A protocol option: ``None`` by default (the scene's profile, or
    :data:`PROTOCOL_DEFAULTS`), in the protocol group of the command's help."""
    extra = {"group": PROTOCOL_GROUP}
    if unit:
        extra["unit"] = unit
    if metavar:
        extra["metavar"] = metavar
    return Field(None, description=description, json_schema_extra=extra, **bounds)


class ProtocolOptions(StudyOptions):
    """The hold-until-steady protocol of the wedge-based studies (``None``: the scene's
    wedge profile, or :data:`PROTOCOL_DEFAULTS`)."""

    depth_mm: Optional[float] = _protocol(
        "full depth in mm (default: n_steps x step of the wedge's profile)", "mm", "MM",
        gt=0, le=1000)
    nodes: Optional[int] = _protocol("nodes per bristle (default: the scene's)", None, "N",
                                     ge=2, le=4096)
    max_acceleration: Optional[float] = _protocol(
        "a_m of each step, m/s^2 (default: the profile's)", "m/s^2", "A", gt=0)
    window: Optional[float] = _protocol(
        f"hold window, s (default {PROTOCOL_DEFAULTS['window']})", "s", "S", gt=0)
    threshold: Optional[float] = _protocol(
        f"std of the root force that counts as steady, N (default "
        f"{PROTOCOL_DEFAULTS['threshold']:g}; or --rel-threshold times the force, whichever "
        f"is larger)", "N", "N", gt=0)
    rel_threshold: Optional[float] = _protocol(
        f"fraction of the force that counts as steady (default "
        f"{PROTOCOL_DEFAULTS['rel_threshold']:g})", None, "F", ge=0, lt=1)
    max_hold: Optional[float] = _protocol(
        f"longest hold after a step, s (default {PROTOCOL_DEFAULTS['max_hold']})", "s", "S",
        gt=0)
    no_unload: bool = Field(False, description="loading only",
                            json_schema_extra={"group": PROTOCOL_GROUP})
    method: Optional[Literal["quasi-static", "dynamic"]] = _protocol(
        "quasi-static (default): each hold ends when the out-of-balance force and kinetic "
        "energy are below the tolerance, with strong local damping and scaled rotational "
        "inertia; dynamic: the seed's protocol, windows of the scene's own dynamics until the "
        "force's spread is small")
    qs_max_acceleration: Optional[float] = _protocol(
        f"quasi-static: a_m of each increment's move, m/s^2 (default "
        f"{PROTOCOL_DEFAULTS['qs_max_acceleration']:g})", "m/s^2", "A", gt=0)
    qs_increments: Optional[int] = _protocol(
        f"quasi-static: increments per step, each settled and its slip committed (default "
        f"{PROTOCOL_DEFAULTS['qs_increments']})", None, "N", ge=1, le=1000)


def protocol_from_options(scene: dict, options: "ProtocolOptions") -> dict:
    """The protocol of ``scene`` for the options of a wedge-based study."""
    o = options
    return make_protocol(scene, depth=None if o.depth_mm is None else o.depth_mm * 1e-3,
                         max_acceleration=o.max_acceleration, unload=not o.no_unload,
                         window=o.window, threshold=o.threshold,
                         rel_threshold=o.rel_threshold, max_hold=o.max_hold,
                         method=None if o.method is None else o.method.replace("-", "_"),
                         qs_max_acceleration=o.qs_max_acceleration,
                         qs_increments=o.qs_increments)
