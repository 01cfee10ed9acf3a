"""The scene model: one validated description of a simulation, JSON in and out.

Everything is SI (metres, kilograms, seconds, radians, pascals). The studio converts to
millimetres and degrees at its own edge. The format is documented in ``docs/scene.md``.

``load_scene`` / ``save_scene`` / ``Scene.model_validate`` are the only ways in; a bad scene
raises :class:`engine.errors.SceneError` naming every bad field, its value and what is allowed.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Literal, Optional, Union

from pydantic import (Field, ValidationError,
                      field_validator, model_validator)

from engine.errors import FieldProblem, SceneError
from engine.model.spec_bodies import Body
from engine.model.spec_common import (FS, SEP, FiniteFloat, NonNegativeFloat, Pose, PositiveFloat, Vector3,
                          _Model)

SCHEMA_VERSION = 1


# --------------------------------------------------------------------------- materials
class Material(_Model):
    youngs_modulus: PositiveFloat = Field(description="E, Pa")
    poisson_ratio: float = Field(0.3, gt=-1.0, lt=0.5, allow_inf_nan=False)
    density: PositiveFloat = Field(description="kg/m^3")
    bond_damping: NonNegativeFloat = Field(
        0.0, le=1.0,
        description="viscous damping of bristle bonds as a fraction of critical damping of "
                    "each bond's axial/shear/bending/twisting spring on its two nodes")


class ContactPair(_Model):
    """Contact law between two materials (order does not matter)."""

    materials: tuple[str, str]
    friction_angle: float = Field(0.0, ge=0.0, lt=math.pi / 2, allow_inf_nan=False,
                                  description="Coulomb friction angle, rad (seed eq. 3.8)")
    restitution: float = Field(1.0, gt=0.0, le=1.0, allow_inf_nan=False,
                               description="normal coefficient of restitution; 1 = no damping")
    tangential_ratio: float = Field(0.25, gt=0.0, le=1.0, allow_inf_nan=False,
                                    description="k_t / k_n of the Cundall-Strack law")
    adhesion_force: float = Field(
        0.0, ge=0.0, le=1e6, allow_inf_nan=False,
        description="pull-off force per contact, N: a cohesive attraction that acts once a "
                    "contact unloads, until it lets go (engine.kernels.contact_law.adhesion; "
                    "docs/scene.md); 0 = no adhesion")


# --------------------------------------------------------------------------- brushes
class Brush(_Model):
    """A grid of bristles clamped to a base. Bristles grow along the base's local +z; the
    grid's rows run along local x (``columns`` bristles per row, ``pitch[0]`` apart) and the
    rows are stacked along local y (``rows`` of them, ``pitch[1]`` apart), centred on the
    base origin. ``staggered`` shifts every odd row by half a pitch along x."""

    name: str = "brush"
    material: str
    rows: int = Field(1, ge=1, le=100_000)
    columns: int = Field(1, ge=1, le=100_000)
    pitch: tuple[PositiveFloat, PositiveFloat] = (0.003, 0.003)
    pattern: Literal["grid", "staggered"] = "grid"
    bristle_length: PositiveFloat
    root_radius: PositiveFloat
    tip_radius: PositiveFloat
    n_nodes: int = Field(8, ge=2, le=4096)
    tip_variance: NonNegativeFloat = Field(
        0.0, description="variance (m^2) of the Gaussian perturbation of each tip in the "
                         "base's x-y plane; the seed used 4e-10")
    seed: int = Field(0, ge=0, description="random seed of the tip perturbation")
    base: Pose = Pose()
    mount: Optional[str] = Field(
        None, description="name of a body the base is rigidly mounted on (its pose is then "
                          "relative to that body's frame); None = base fixed in the world")

    @property
    def n_bristles(self) -> int:
        return self.rows * self.columns


# --------------------------------------------------------------------------- loads
class LoadProfile(_Model):
    """Amplitude a(t) multiplying ``Load.force``: piecewise-linear through (times, values)
    (held constant outside), optionally times sin(2 pi frequency t + phase)."""

    times: list[FiniteFloat] = Field(default_factory=lambda: [0.0])
    values: list[FiniteFloat] = Field(default_factory=lambda: [1.0])
    frequency: NonNegativeFloat = 0.0
    phase: FiniteFloat = 0.0

    @model_validator(mode="after")
    def _consistent(self):
        if len(self.times) != len(self.values) or not self.times:
            raise ValueError("times and values must be non-empty and of equal length")
        if any(b < a for a, b in zip(self.times, self.times[1:])):
            raise ValueError("times must not decrease")
        return self


class Load(_Model):
    """An external force on bristle nodes: ``node`` counts from the root (0) and may be
    negative (-1 = tip); ``bristles`` is a list of bristle indices or "all"."""

    brush: str
    bristles: Union[Literal["all"], list[Annotated[int, Field(ge=0)]]] = "all"
    node: int = -1
    force: Vector3
    profile: LoadProfile = LoadProfile()


# --------------------------------------------------------------------------- environment/run
#: Earth's gravitational parameter (m^3/s^2, WGS-84/EGM-96) and equatorial radius (m), used
#: only to turn an altitude into a mean motion
MU_EARTH = 3.986004418e14
R_EARTH = 6378137.0


def mean_motion_from_altitude(altitude: float) -> float:
    """n = sqrt(mu / a^3) of a circular Earth orbit at ``altitude`` above the equatorial
    radius (rad/s)."""
    a = R_EARTH + altitude
    return math.sqrt(MU_EARTH / a ** 3)


class Orbit(_Model):
    """A circular reference orbit: the scene lives in its Hill frame (x radial outwards,
    y along-track, z orbit normal) and every free node and body follows the
    Clohessy-Wiltshire equations (docs/mission.md). Give ``mean_motion`` or ``altitude``
    (circular Earth orbit; n = sqrt(mu / (R + h)^3), mu = 3.986004418e14 m^3/s^2,
    R = 6378137 m). ``mean_motion`` = 0 is free space."""

    mean_motion: Optional[NonNegativeFloat] = Field(None, description="n, rad/s")
    altitude: Optional[PositiveFloat] = Field(None, description="m above Earth's equatorial "
                                                                "radius")
    gravity_gradient: bool = Field(False, description="gravity-gradient torque on free and "
                                                      "hinge bodies")

    @model_validator(mode="after")
    def _one_way(self):
        if (self.mean_motion is None) == (self.altitude is None):
            raise ValueError("give either mean_motion (rad/s) or altitude (m), not both")
        return self

    @property
    def n(self) -> float:
        """The mean motion, rad/s."""
        if self.mean_motion is not None:
            return float(self.mean_motion)
        return mean_motion_from_altitude(self.altitude)


class Environment(_Model):
    gravity: Vector3 = (0.0, 0.0, 0.0)
    orbit: Optional[Orbit] = Field(None, description="None: an inertial frame (free space, or "
                                                     "the ground with gravity)")
    local_damping: float = Field(
        0.0, ge=0.0, lt=1.0, allow_inf_nan=False,
        description="Cundall's non-viscous local damping of bristle nodes (0 = none); for "
                    "quasi-static loading only")
    inertia_scaling: Literal["none", "equalize"] = Field(
        "none", description="'equalize' (quasi-static loading only): the bristle nodes' mass "
                            "and rotational inertia, as the integrator sees them (not their "
                            "weight), are raised so that no node's stability bound exceeds "
                            "the median node's; a static equilibrium does not depend on "
                            "inertia, and dt grows; the dynamics are then not physical")


Channel = Literal["nodes", "bodies", "root_force", "energy", "contacts", "bending",
                  "node_velocities"]
#: the default: every channel but ``node_velocities`` (it doubles the nodes' share of a file)
ALL_CHANNELS: tuple[str, ...] = ("nodes", "bodies", "root_force", "energy", "contacts",
                                 "bending")


class StopCondition(_Model):
    """Stop before ``duration`` when a quantity stays below ``value`` for ``hold`` seconds
    (checked at every record after ``min_time``): ``kinetic_energy`` (J, whole scene) or
    ``body_angular_speed`` (rad/s, needs ``body``). A hold keeps a body whose angular speed
    passes through zero inside a contact from stopping the run too early."""

    quantity: Literal["kinetic_energy", "body_angular_speed"]
    value: PositiveFloat
    body: Optional[str] = None
    min_time: NonNegativeFloat = 0.0
    hold: NonNegativeFloat = 0.0


class RunSettings(_Model):
    duration: PositiveFloat
    dt: Optional[PositiveFloat] = Field(None, description="None = automatic")
    dt_safety: float = Field(0.5, gt=0.0, le=1.0, allow_inf_nan=False,
                             description="fraction of the stability limit used by automatic dt")
    record_interval: PositiveFloat = Field(description="s between recorded frames")
    channels: list[Channel] = Field(default_factory=lambda: list(ALL_CHANNELS))
    stop: Optional[StopCondition] = None
    verlet_skin: Optional[PositiveFloat] = Field(
        None, description="neighbour-list skin, m; default (build): the smallest node radius "
                          "of any bristle, 1 mm in a scene without bristles (the lists are "
                          "rebuilt when anything may have moved half of it)")

    @field_validator("channels")
    @classmethod
    def _unique(cls, c):
        if len(set(c)) != len(c):
            raise ValueError("channels must not repeat")
        return c


# --------------------------------------------------------------------------- controllers
class Gains(_Model):
    """PID gains of one loop: position loop in N/m, N s/m, N/(m s); attitude loop in
    N m/rad, N m s/rad, N m/(rad s)."""

    proportional: NonNegativeFloat = 0.0
    derivative: NonNegativeFloat = 0.0
    integral: NonNegativeFloat = 0.0


class PoseController(_Model):
    """A sampled PD/PID pose controller acting on a free body (a chaser's thrusters and
    reaction wheels). Every ``sample_interval`` it measures the body's pose and velocity and
    holds, until the next sample, the force F = kp e + kd de/dt + ki sum(e) dt and the torque
    of the same form on the attitude error (rotation vector of q_target q^-1), each expressed
    in the body's own mesh axes and clipped per axis to ``max_force`` / ``max_torque``
    (thrusters fixed on the body). Target: ``position`` in the Hill/world frame, or, with
    ``reference`` (a body name), ``position`` is an offset from that body's centre of mass
    (world axes) and the velocity error is taken relative to that body's centre; the
    attitude target ``orientation`` is the body's mesh axes in the world frame. Inside the
    deadband (|position error| <= ``position_deadband``, |attitude error| <=
    ``attitude_deadband``) that loop commands nothing. Release: with ``release_below``
    (rad/s) and a ``reference``, at the first sample where the reference body's angular
    speed is below ``release_below`` the controller latches "released" and aims from then on
    at ``position`` + ``release_offset`` (m, world axes): the chaser backs off so its brush
    lets go of a target it has detumbled. None (default) never releases.
    ``release_below_fraction`` states the threshold relative to the reference's |omega| at
    the controller's first sample instead (e.g. 0.05: release at 5 % of the initial spin);
    give one of the two. ``anti_windup`` (default off, so that earlier scenes reproduce)
    stops the integral growing while a command it pushes is clipped (conditional
    integration; engine.kernels.control)."""

    name: str = "controller"
    body: str
    reference: Optional[str] = None
    position: Vector3 = (0.0, 0.0, 0.0)
    orientation: tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat] = (1.0, 0.0, 0.0, 0.0)
    position_gains: Gains = Gains()
    attitude_gains: Gains = Gains()
    sample_interval: PositiveFloat = Field(0.1, description="s (zero-order hold)")
    max_force: Optional[tuple[PositiveFloat, PositiveFloat, PositiveFloat]] = Field(
        None, description="N per body axis; None = unlimited")
    max_torque: Optional[tuple[PositiveFloat, PositiveFloat, PositiveFloat]] = Field(
        None, description="N m per body axis; None = unlimited")
    position_deadband: NonNegativeFloat = Field(0.0, description="m")
    attitude_deadband: NonNegativeFloat = Field(0.0, description="rad")
    release_below: Optional[PositiveFloat] = Field(
        None, description="rad/s: release once the reference's |omega| is below; None = never")
    release_offset: Vector3 = Field((0.0, 0.0, 0.0),
                                    description="m, world axes: added to position once released")
    release_below_fraction: Optional[float] = Field(
        None, gt=0.0, lt=1.0,
        description="release once the reference's |omega| is below this fraction of its "
                    "value at the first sample; None = use release_below")
    anti_windup: bool = Field(False, description="conditional integration of the integral "
                                                 "term while the command saturates")

    @field_validator("orientation")
    @classmethod
    def _unit_quaternion(cls, q):
        return Pose._unit_quaternion(q)


# --------------------------------------------------------------------------- scene
class Scene(_Model):
    schema_version: int = SCHEMA_VERSION
    name: str = "scene"
    description: str = ""
    materials: dict[str, Material]
    contact_pairs: list[ContactPair] = Field(default_factory=list)
    brushes: list[Brush] = Field(default_factory=list)
    bodies: list[Body] = Field(default_factory=list)
    loads: list[Load] = Field(default_factory=list)
    controllers: list[PoseController] = Field(default_factory=list)
    environment: Environment = Environment()
    run: RunSettings

    @field_validator("schema_version")
    @classmethod
    def _version(cls, v):
        if v != SCHEMA_VERSION:
            raise ValueError(f"this Brush Studio reads schema_version {SCHEMA_VERSION} only")
        return v

    @model_validator(mode="after")
    def _cross_references(self):
        problems: list[tuple[str, object, str]] = []
        mats = set(self.materials)
        names = [b.name for b in self.brushes]
        if len(set(names)) != len(names):
            problems.append(("brushes", names, "brush names must be unique"))
        bnames = [b.name for b in self.bodies]
        if len(set(bnames)) != len(bnames):
            problems.append(("bodies", bnames, "body names must be unique"))
        for i, b in enumerate(self.brushes):
            if b.material not in mats:
                problems.append((f"brushes.{i}.material", b.material,
                                 f"must be one of the materials {sorted(mats)}"))
            if b.mount is not None and b.mount not in bnames:
                problems.append((f"brushes.{i}.mount", b.mount,
                                 f"must be one of the bodies {bnames}"))
            if 2 * max(b.root_radius, b.tip_radius) >= b.bristle_length:
                problems.append((f"brushes.{i}.bristle_length", b.bristle_length,
                                 "must exceed the bristle's largest diameter"))
        for i, body in enumerate(self.bodies):
            if body.material not in mats:
                problems.append((f"bodies.{i}.material", body.material,
                                 f"must be one of the materials {sorted(mats)}"))
            for other in body.no_contact_with:
                if other not in bnames or other == body.name:
                    problems.append((f"bodies.{i}.no_contact_with", other,
                                     f"must name another body: one of "
                                     f"{[n for n in bnames if n != body.name]}"))
            needs_mass = body.motion.type in ("free", "hinge") or (
                body.motion.type == "kinematic" and body.motion.after == "free")
            if needs_mass and body.mass_properties is None:
                problems.append((f"bodies.{i}.mass_properties", None,
                                 f"a {body.motion.type} body needs density, or mass and "
                                 f"inertia"))
        for i, p in enumerate(self.contact_pairs):
            for m in p.materials:
                if m not in mats:
                    problems.append((f"contact_pairs.{i}.materials", m,
                                     f"must be one of the materials {sorted(mats)}"))
        seen = set()
        for i, p in enumerate(self.contact_pairs):
            key = frozenset(p.materials)
            if key in seen:
                problems.append((f"contact_pairs.{i}.materials", list(p.materials),
                                 "this pair is given twice"))
            seen.add(key)
        for i, load in enumerate(self.loads):
            if load.brush not in names:
                problems.append((f"loads.{i}.brush", load.brush,
                                 f"must be one of the brushes {names}"))
                continue
            brush = self.brushes[names.index(load.brush)]
            if not -brush.n_nodes <= load.node < brush.n_nodes:
                problems.append((f"loads.{i}.node", load.node,
                                 f"must lie in [-{brush.n_nodes}, {brush.n_nodes - 1}]"))
            if load.bristles != "all" and any(k >= brush.n_bristles for k in load.bristles):
                problems.append((f"loads.{i}.bristles", load.bristles,
                                 f"indices must be below {brush.n_bristles}"))
        cnames = [c.name for c in self.controllers]
        if len(set(cnames)) != len(cnames):
            problems.append(("controllers", cnames, "controller names must be unique"))
        for i, c in enumerate(self.controllers):
            if c.body not in bnames:
                problems.append((f"controllers.{i}.body", c.body,
                                 f"must be one of the bodies {bnames}"))
            elif self.bodies[bnames.index(c.body)].motion.type != "free":
                problems.append((f"controllers.{i}.body", c.body,
                                 "must be a free body (motion type 'free')"))
            if c.reference is not None and (c.reference not in bnames or c.reference == c.body):
                problems.append((f"controllers.{i}.reference", c.reference,
                                 f"must be null or one of the other bodies "
                                 f"{[b for b in bnames if b != c.body]}"))
            if c.release_below is not None and c.reference is None:
                problems.append((f"controllers.{i}.release_below", c.release_below,
                                 "needs a reference body (the spin it watches): set "
                                 "reference, or release_below to null"))
            if c.release_below_fraction is not None and c.reference is None:
                problems.append((f"controllers.{i}.release_below_fraction",
                                 c.release_below_fraction,
                                 "needs a reference body (the spin it watches)"))
            if c.release_below_fraction is not None and c.release_below is not None:
                problems.append((f"controllers.{i}.release_below_fraction",
                                 c.release_below_fraction,
                                 "give release_below or release_below_fraction, not both"))
        for i, body in enumerate(self.bodies):
            if (any(body.external_force) or any(body.external_torque)) \
                    and body.motion.type != "free":
                problems.append((f"bodies.{i}.external_force", list(body.external_force),
                                 "external force and torque act on free bodies only"))
        if self.environment.orbit is not None and any(self.environment.gravity):
            problems.append(("environment.gravity", list(self.environment.gravity),
                             "must be zero in orbit: the Hill frame is in free fall"))
        if self.run.stop is not None and self.run.stop.quantity == "body_angular_speed":
            if self.run.stop.body not in bnames:
                problems.append(("run.stop.body", self.run.stop.body,
                                 f"must be one of the bodies {bnames}"))
        if problems:
            raise ValueError(SEP.join(f"{f}{FS}{json.dumps(v, default=repr)}{FS}{m}"
                                       for f, v, m in problems))
        return self

    # ----------------------------------------------------------------- helpers
    def pair(self, a: str, b: str) -> ContactPair:
        """The contact law between materials a and b (frictionless, elastic if not given)."""
        for p in self.contact_pairs:
            if set(p.materials) == {a, b}:
                return p
        return ContactPair(materials=(a, b))

    def to_json(self, indent: int = 2) -> str:
        return self.model_dump_json(indent=indent)


# --------------------------------------------------------------------------- I/O
def _problems_from(err: ValidationError) -> list[FieldProblem]:
    problems = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"])
        msg = e["msg"]
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, "):]
        if e["type"] == "value_error" and FS in msg:
            for part in msg.split(SEP):
                field, value, rest = part.split(FS)
                # a nested model's problems name its own fields: prefix where it is
                problems.append(FieldProblem(f"{loc}.{field}" if loc else field,
                                             json.loads(value), rest))
            continue
        if e["type"] == "missing":  # its "input" is the enclosing object: say what is missing
            problems.append(FieldProblem(loc, None, "required field is missing"))
            continue
        problems.append(FieldProblem(loc or "(scene)", e.get("input"), msg))
    return problems


def _json_error(exc: json.JSONDecodeError, source: Optional[str]) -> SceneError:
    """Invalid JSON, named by where: the file (when known), line and column."""
    where = f"line {exc.lineno}, column {exc.colno}"
    return SceneError.single("(file)", source if source is not None else where,
                             f"not valid JSON at {where}: {exc.msg}")


def parse_scene(data: Union[dict, str, bytes]) -> Scene:
    """Validate a scene given as a dict or JSON text; raise SceneError naming every bad field."""
    try:
        if isinstance(data, (str, bytes)):
            try:
                data = json.loads(data)
            except json.JSONDecodeError as exc:
                raise _json_error(exc, None) from None
        if not isinstance(data, dict):
            raise SceneError.single("(scene)", type(data).__name__, "must be a JSON object")
        return Scene.model_validate(data)
    except ValidationError as err:
        raise SceneError(_problems_from(err)) from None


def load_scene(path: Union[str, Path]) -> Scene:
    """Read and validate a scene JSON file. Relative mesh paths are resolved against the
    file's folder."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError.single("(file)", str(path), f"cannot be read: {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _json_error(exc, str(path)) from None
    scene = parse_scene(data)
    for body in scene.bodies:
        if body.shape.type == "mesh" and not Path(body.shape.file).is_absolute():
            body.shape = body.shape.model_copy(
                update={"file": str((path.parent / body.shape.file).resolve())})
        for patch in body.patches:  # reduced brushes' law files, as mesh files
            if isinstance(patch.law, str) and not Path(patch.law).is_absolute():
                patch.law = str((path.parent / patch.law).resolve())
    return scene


def save_scene(scene: Scene, path: Union[str, Path]) -> None:
    Path(path).write_text(scene.to_json() + "\n")
