"""The scenario set a design must serve, and the scene of one design x scenario.

The test rig is the seed's brush dynamic test (seed 4.3, ``studio.studies.spin.runs``): a target
spins into a fixed brush whose bristles point at it. A scenario fixes the target (a cube of
edge ``a`` and density rho on a hinge through its centre, or, tumbling, a free
``a x 1.25a x 1.5a`` box spinning about a non-principal axis), its spin rate, the brush
placement (the spin study's configurations 1-6: the contact offset) and, optionally, a draw of
the uncertain brush material (E and the friction angles, each uniform within +-20 %, with
the scenario's own fixed seed, so every design meets the same draws).
"""
from __future__ import annotations

import copy
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from .errors import StudyInputError
from .variables import apply_design

#: direction of a tumbling target's spin in its body frame: off every principal axis, near
#: the intermediate one (y of the 1 : 1.25 : 1.5 box), about which a spin is unstable
TUMBLE_AXIS = (0.25, 1.0, 0.15)
TUMBLE_ASPECT = (1.0, 1.25, 1.5)
MATERIAL_SPREAD = 0.2  # +-20 % on E and on the friction angles (uniform)


@dataclass(frozen=True)
class Scenario:
    """One target situation. ``e_factor``/``friction_factor`` scale the brush's E and the
    friction angles (1: nominal)."""

    scenario_id: str
    cube_mm: float
    spin_rate: float
    config: int = 1
    tumbling: bool = False
    density: float = 700.0
    e_factor: float = 1.0
    friction_factor: float = 1.0
    seed: int = 0

    #: the columns of trials.csv that describe it
    COLUMNS = ("cube_mm", "spin_rate", "config", "tumbling", "e_factor", "friction_factor")

    def to_dict(self) -> dict:
        return asdict(self)


def scenario_set(cubes_mm, spin_rates, configs, *, tumbling: bool = False,
                 density: float = 700.0, material_draws: int = 0, seed: int = 1
                 ) -> list[Scenario]:
    """Every cube x spin rate x configuration (plus a tumbling box per cube and spin rate),
    each with ``material_draws`` material draws (or the nominal material)."""
    from ..spin.runs import CONFIGS

    if not cubes_mm or not spin_rates or not configs:
        raise StudyInputError("the scenario set is empty: give --cubes-mm, --spin-rates and "
                              "--configs")
    for c in configs:
        if c not in CONFIGS:
            raise StudyInputError(f"configs: {c} is not one of {sorted(CONFIGS)}")
    for a in cubes_mm:
        if not 1.0 <= a <= 1000.0:
            raise StudyInputError(f"cubes_mm: {a} mm is outside 1..1000 mm")
    for w in spin_rates:
        if not 0 < w <= 1000:
            raise StudyInputError(f"spin_rates: {w} rad/s is outside (0, 1000]")
    base = [(a, w, c, False) for a in cubes_mm for w in spin_rates for c in configs]
    if tumbling:
        base += [(a, w, 1, True) for a in cubes_mm for w in spin_rates]
    out = []
    for k, (a, w, c, tumble) in enumerate(base):
        name = f"{'box' if tumble else 'cube'}{a:g}mm_w{w:g}_cfg{c}".replace(".", "p")
        if material_draws == 0:
            out.append(Scenario(name, a, w, c, tumble, density))
            continue
        for d in range(material_draws):
            s = seed * 1000 + k * 100 + d  # fixed per scenario: every design sees it
            rng = np.random.default_rng(s)
            e, f = 1 + MATERIAL_SPREAD * (2 * rng.random(2) - 1)
            out.append(Scenario(f"{name}_draw{d}", a, w, c, tumble, density, float(e),
                                float(f), s))
    return out


def base_scene(preset: str) -> dict:
    """The design's starting scene (a dict): a preset name or a scene file."""
    import engine

    path = Path(preset)
    if path.suffix == ".json" and path.is_file():
        scene = engine.load_scene(path)
    else:
        from studio import presets
        try:
            scene = presets.load_preset(preset)
        except KeyError:
            raise StudyInputError(f"preset {preset!r}: not a preset name or scene file"
                                  ) from None
    data = json.loads(scene.to_json())
    if len(data.get("brushes", [])) != 1:
        raise StudyInputError(f"preset {preset!r}: the design search needs a scene with "
                              f"exactly one brush (it has {len(data.get('brushes', []))})")
    return data


def scenario_scene(base: dict, design: dict, scenario: Scenario, *, nodes: int,
                   duration: float, stiffness_via: str = "youngs_modulus",
                   dt_safety: Optional[float] = None, record_interval: float = 5e-4) -> dict:
    """The scene of ``design`` (variables -> values) meeting ``scenario``: the base scene's
    brush with the design's values, placed as the spin study places it for the scenario's
    configuration, and the scenario's target."""
    from ..spin.runs import CONFIGS, Q_Z_TO_MINUS_X, STOP_SPEED  # noqa: F401

    scene = copy.deepcopy(base)
    apply_design(scene, design, stiffness_via=stiffness_via)
    brush = scene["brushes"][0]
    brush["n_nodes"] = int(nodes)
    a = scenario.cube_mm * 1e-3
    orientation, level, position = CONFIGS[scenario.config]
    if orientation == "vertical":
        brush["rows"], brush["columns"] = brush["columns"], brush["rows"]
    tips = a / 2 if position == "P1" else a * (1 + math.sqrt(2)) / 4
    _check_mount(scene, brush)
    brush["base"] = {"position": [tips + brush["bristle_length"] + brush["tip_radius"], 0.0,
                                  0.0 if level == "axis" else a / 2],
                     "orientation": list(Q_Z_TO_MINUS_X)}
    # the uncertain material: the bristles' own copy, scaled
    mat_name = brush["material"]
    mat = dict(scene["materials"][mat_name])
    mat["youngs_modulus"] = float(mat["youngs_modulus"]) * scenario.e_factor
    scene["materials"][mat_name] = mat
    for pair in scene.get("contact_pairs", []):
        pair["friction_angle"] = min(float(pair.get("friction_angle", 0.0))
                                     * scenario.friction_factor, 1.5)
    target = _target(scene)
    size = np.array(TUMBLE_ASPECT if scenario.tumbling else (1.0, 1.0, 1.0)) * a
    target["shape"] = {"type": "box", "size": [float(s) for s in size]}
    target["mass_properties"] = {"density": float(scenario.density)}
    if scenario.tumbling:
        axis = np.array(TUMBLE_AXIS) / np.linalg.norm(TUMBLE_AXIS)
        target["motion"] = {"type": "free"}
        target["angular_velocity"] = [float(v) for v in scenario.spin_rate * axis]
    else:
        motion = target.get("motion") or {}
        if motion.get("type") != "hinge":
            motion = {"type": "hinge", "axis": [0.0, 1.0, 0.0], "point": [0.0, 0.0, 0.0],
                      "k1": 0.1, "k2": 0.5}
        target["motion"] = motion
        target["angular_velocity"] = [0.0, float(scenario.spin_rate), 0.0]
    run = scene.setdefault("run", {})
    run["duration"] = float(duration)
    run["record_interval"] = float(record_interval)
    # root_force: the brush's load on its chaser or mount (chaser_delta_v, wheel_momentum)
    run["channels"] = ["bodies", "bending", "root_force"]
    run["stop"] = None
    if dt_safety is not None:
        run["dt_safety"] = float(dt_safety)
    scene["name"] = f"{scene.get('name', 'design')}_{scenario.scenario_id}"
    return scene


def _target(scene: dict) -> dict:
    bodies = scene.get("bodies", [])
    for b in bodies:
        if b.get("name") == "cube":
            return b
    if len(bodies) == 1:
        return bodies[0]
    raise StudyInputError("the design's scene needs a body named 'cube' (the target) or "
                          "exactly one body")


def _check_mount(scene: dict, brush: dict) -> None:
    """The rig places the brush base in world coordinates; a brush mounted on a chaser is
    placed in the chaser's frame, so that chaser must sit at the origin, unrotated."""
    mount = brush.get("mount")
    if mount is None:
        return
    body = next((b for b in scene.get("bodies", []) if b.get("name") == mount), None)
    pose = (body or {}).get("pose") or {}
    position = [float(v) for v in pose.get("position", (0.0, 0.0, 0.0))]
    orientation = [float(v) for v in pose.get("orientation", (1.0, 0.0, 0.0, 0.0))]
    if position != [0.0, 0.0, 0.0] or orientation != [1.0, 0.0, 0.0, 0.0]:
        raise StudyInputError(
            f"brushes.0.mount: the brush is mounted on {mount!r}, which the design search "
            f"needs at the origin, unrotated (its pose is {position}, {orientation}): the "
            f"rig places the brush base in world coordinates")
