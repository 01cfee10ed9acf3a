"""The scenes of ``study fur``: the seed's fig. 5.1 impact (``space_fur`` / ``solid_plate``
presets) with the projectile, the impact and the fur changed. SI inside; the study's options
(mm, degrees) are converted by :mod:`studio.studies.fur.study`.

Geometry, as the presets: the plate's top face at z = 0, the fur's roots just above it, the
projectile a steel sphere starting 3 mm above the top (fur tips, or the plate), moving in the
x-z plane at ``angle`` from the plate normal. With fur, the sphere's centre crosses the tip
plane at x = ``AIM_X`` (so a slanted shot travels over the fur, not past its edge); without,
its centre line meets the plate at x = 0.
"""
from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass

#: the sphere's surface starts this far above the fur tips (or the bare plate), m
START_GAP = 0.003
#: where the sphere's centre crosses the fur's tip plane, m (as the space_fur preset)
AIM_X = -0.012
#: root nodes this far above the plate (they do not touch it at rest), m
ROOT_GAP = 0.00005


@dataclass(frozen=True)
class Impact:
    """One impact: speed (m/s), angle from the plate normal (rad), projectile radius (m)."""

    speed: float
    angle: float
    radius: float


@dataclass(frozen=True)
class Fur:
    """The fur: bristle length (m), root radius (m; the tip keeps the preset's 2/3 taper),
    pitch (m, both directions), nodes per bristle."""

    length: float
    root_radius: float
    pitch: float
    n_nodes: int


def scene_dict(ref: str) -> dict:
    """The JSON dict of a preset name or a scene file."""
    from pathlib import Path

    from studio.presets import preset_names, preset_path

    path = preset_path(ref) if ref in preset_names() else Path(ref)
    return json.loads(path.read_text(encoding="utf-8"))


#: the bare plate's hit lasts microseconds: this time-step safety factor and record interval
#: resolve its peak (as the solid_plate preset)
PLATE_DT_SAFETY = 0.1


def sphere_mass(radius: float, density: float) -> tuple[float, float]:
    """Mass (kg) and moment of inertia (kg m^2) of a solid sphere."""
    m = density * 4.0 / 3.0 * math.pi * radius ** 3
    return m, 0.4 * m * radius ** 2


def _set_projectile(scene: dict, impact: Impact, top: float, aim_x: float) -> None:
    body = next(b for b in scene["bodies"] if b["name"] == "sphere")
    density = scene["materials"][body["material"]]["density"]
    m, i = sphere_mass(impact.radius, density)
    body["shape"]["radius"] = impact.radius
    body["mass_properties"] = {"mass": m, "inertia": [[i, 0, 0], [0, i, 0], [0, 0, i]]}
    s, c = math.sin(impact.angle), math.cos(impact.angle)
    z0 = top + START_GAP + impact.radius
    # the centre moves along (sin, 0, -cos): it crosses z = top at x = aim_x
    body["pose"] = {"position": [aim_x - (z0 - top) * s / c, 0.0, z0]}
    body["velocity"] = [impact.speed * s, 0.0, -impact.speed * c]


def fur_scene(impact: Impact, fur: Fur, *, duration: float, record_interval: float,
              preset: str = "space_fur") -> dict:
    """The fur-covered plate (the scene ``preset``: a body ``plate``, a free body ``sphere``
    and one fur brush) hit by ``impact``."""
    scene = copy.deepcopy(scene_dict(preset))
    brush = scene["brushes"][0]
    taper = brush["tip_radius"] / brush["root_radius"]
    brush.update(bristle_length=fur.length, root_radius=fur.root_radius,
                 tip_radius=fur.root_radius * taper, pitch=[fur.pitch, fur.pitch],
                 n_nodes=fur.n_nodes)
    brush["base"] = {"position": [0.0, 0.0, fur.root_radius + ROOT_GAP]}
    top = fur.root_radius + ROOT_GAP + fur.length + fur.root_radius * taper
    _set_projectile(scene, impact, top, AIM_X)
    scene["name"] = "fur_impact"
    scene["description"] = (f"study fur: {describe(impact)} into fur {describe_fur(fur)} "
                            "(from the space_fur preset)")
    scene["run"].update(duration=duration, record_interval=record_interval)
    return scene


def plate_scene(impact: Impact, *, duration: float, record_interval: float,
                preset: str = "space_fur") -> dict:
    """The bare plate hit by ``impact``: the fur scene ``preset`` without its fur (as the
    ``solid_plate`` preset is ``space_fur`` without it), its hit resolved in time."""
    scene = copy.deepcopy(scene_dict(preset))
    scene.pop("brushes", None)
    scene["run"] = {k: v for k, v in scene["run"].items() if k != "stop"}
    scene["run"]["channels"] = ["bodies", "energy", "contacts"]
    scene["run"]["dt_safety"] = PLATE_DT_SAFETY
    _set_projectile(scene, impact, 0.0, 0.0)
    scene["name"] = "bare_plate_impact"
    scene["description"] = f"study fur: {describe(impact)} on the bare plate (solid_plate)"
    scene["run"].update(duration=duration, record_interval=record_interval)
    return scene


def fur_top(fur: Fur, taper: float = 2.0 / 3.0) -> float:
    """Height of the fur's tip plane above the plate, m."""
    return fur.root_radius + ROOT_GAP + fur.length + fur.root_radius * taper


def describe(impact: Impact) -> str:
    return (f"a {impact.radius * 1e3:g} mm steel sphere at {impact.speed:g} m/s, "
            f"{math.degrees(impact.angle):g} deg from the normal")


def describe_fur(fur: Fur) -> str:
    return (f"{fur.length * 1e3:g} mm long, root radius {fur.root_radius * 1e3:g} mm, "
            f"pitch {fur.pitch * 1e3:g} mm, {fur.n_nodes} nodes")
