"""The scene model's bodies: shapes, mass properties, motions (fixed, free, hinge, kinematic
with its profiles) and ``Body``. Documented in docs/scene.md ("Bodies")."""
from __future__ import annotations

import math
from typing import Annotated, Literal, Optional, Union

from pydantic import Field, model_validator

from engine.model.spec_common import (FiniteFloat, NonNegativeFloat, NonZeroVector3, Pose, PositiveFloat,
                          Vector3, _Model)


# --------------------------------------------------------------------------- bodies
class BoxShape(_Model):
    type: Literal["box"] = "box"
    size: tuple[PositiveFloat, PositiveFloat, PositiveFloat]


class SphereShape(_Model):
    """Sphere: contacts and mass properties (from a density) use the exact sphere; the mesh
    (icosphere) is for display."""

    type: Literal["sphere"] = "sphere"
    radius: PositiveFloat
    subdivisions: int = Field(3, ge=1, le=6)


class CylinderShape(_Model):
    """Cylinder along local z, centred on the origin."""

    type: Literal["cylinder"] = "cylinder"
    radius: PositiveFloat
    height: PositiveFloat
    sections: int = Field(32, ge=3, le=1024)


class WedgeShape(_Model):
    """A triangular prism: its edge (apex) lies on the local x axis from -length/2 to
    length/2 at the origin, pointing down (-z); its two faces open upwards at ``angle``
    (the included angle) to a flat top at z = height."""

    type: Literal["wedge"] = "wedge"
    angle: float = Field(gt=0.0, lt=math.pi, allow_inf_nan=False, description="rad")
    height: PositiveFloat
    length: PositiveFloat


class MeshFileShape(_Model):
    """A triangle mesh file (STL, OBJ, PLY), in metres after ``scale``."""

    type: Literal["mesh"] = "mesh"
    file: str
    scale: PositiveFloat = 1.0


Shape = Annotated[Union[BoxShape, SphereShape, CylinderShape, WedgeShape, MeshFileShape],
                  Field(discriminator="type")]


class MassProperties(_Model):
    """Either ``density`` (mass, centre of mass and inertia from the closed mesh) or ``mass`` and
    ``inertia`` (about the centre of mass, in the body frame) given directly."""

    density: Optional[PositiveFloat] = None
    mass: Optional[PositiveFloat] = None
    inertia: Optional[tuple[Vector3, Vector3, Vector3]] = None
    center_of_mass: Optional[Vector3] = Field(
        None, description="in the mesh frame; default: the mesh's own (density) or its origin")

    @model_validator(mode="after")
    def _one_way(self):
        if self.density is None and self.mass is None:
            raise ValueError("give either density, or mass and inertia")
        if self.density is not None and (self.mass is not None or self.inertia is not None):
            raise ValueError("give either density, or mass and inertia, not both")
        if self.mass is not None and self.inertia is None:
            raise ValueError("mass needs inertia (3x3, kg m^2, about the centre of mass)")
        if self.inertia is not None:
            i = self.inertia
            if any(abs(i[a][b] - i[b][a]) > 1e-9 * max(1e-300, abs(i[a][b]) + abs(i[b][a]))
                   for a in range(3) for b in range(3)):
                raise ValueError("inertia must be symmetric")
        return self


class FixedMotion(_Model):
    type: Literal["fixed"] = "fixed"


class FreeMotion(_Model):
    """Free 6-DOF rigid body (torque-free tumbling unless touched)."""

    type: Literal["free"] = "free"


class HingeMotion(_Model):
    """Rotation about one axis fixed in the world through ``point``, with the external
    dissipation of seed eq. 4.6: d(omega)/dt = -k1 omega - k2 sign(omega)."""

    type: Literal["hinge"] = "hinge"
    axis: NonZeroVector3
    point: Optional[Vector3] = Field(None, description="default: the body's centre of mass")
    k1: NonNegativeFloat = Field(0.0, description="1/s")
    k2: NonNegativeFloat = Field(0.0, description="rad/s^2")


class ConstantProfile(_Model):
    kind: Literal["constant"] = "constant"
    velocity: Vector3 = (0.0, 0.0, 0.0)
    angular_velocity: Vector3 = (0.0, 0.0, 0.0)
    duration: Optional[PositiveFloat] = Field(None, description="default: the whole run")


class SteppedParabolicProfile(_Model):
    """The wedge test's motion (seed 4.2): ``n_steps`` steps of length ``step`` along
    ``direction``, each with v(t) = k t (t_d - t), k = a_m / t_d, t_d = sqrt(6 step / a_m);
    ``dwell`` seconds at rest after each step; then, if ``unload``, the same steps back."""

    kind: Literal["stepped_parabolic"] = "stepped_parabolic"
    direction: NonZeroVector3 = (0.0, 0.0, -1.0)
    step: PositiveFloat = 0.001
    max_acceleration: PositiveFloat
    n_steps: int = Field(ge=1, le=100_000)
    dwell: NonNegativeFloat = 0.0
    unload: bool = False
    start_delay: NonNegativeFloat = 0.0


class WaypointsProfile(_Model):
    """Follow poses at given times: position by piecewise-cubic Hermite (Catmull-Rom
    velocities, zero at both ends), orientation by slerp (constant angular velocity per
    interval). Before the first time the body holds the first pose."""

    kind: Literal["waypoints"] = "waypoints"
    times: list[FiniteFloat] = Field(min_length=2)
    positions: list[Vector3]
    orientations: Optional[list[tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat]]] = None

    @model_validator(mode="after")
    def _consistent(self):
        if any(b <= a for a, b in zip(self.times, self.times[1:])):
            raise ValueError("times must increase strictly")
        if self.times[0] < 0:
            raise ValueError("times must be >= 0")
        if len(self.positions) != len(self.times):
            raise ValueError(f"positions has {len(self.positions)} entries, times "
                             f"{len(self.times)}: they must match")
        if self.orientations is not None:
            if len(self.orientations) != len(self.times):
                raise ValueError("orientations must have one entry per time")
            for q in self.orientations:
                if abs(math.sqrt(sum(c * c for c in q)) - 1.0) > 1e-6:
                    raise ValueError("orientations must be unit quaternions [w, x, y, z]")
        return self


Profile = Annotated[Union[ConstantProfile, SteppedParabolicProfile, WaypointsProfile],
                    Field(discriminator="kind")]


class KinematicMotion(_Model):
    """Prescribed motion; ``after`` says what the body does when the profile ends:
    ``hold`` (stays where it is) or ``free`` (released as a free body with its last velocity;
    needs mass properties)."""

    type: Literal["kinematic"] = "kinematic"
    profile: Profile
    after: Literal["hold", "free"] = "hold"


Motion = Annotated[Union[FixedMotion, FreeMotion, HingeMotion, KinematicMotion],
                   Field(discriminator="type")]


class Patch(_Model):
    """A reduced brush on the body (issue 25, ``engine.kernels.patch``): a compliant
    rectangle, its tip plane, that touches every other colliding closed mesh with a fitted
    reduced law (``engine.model.reduced_law``, written by ``brush-studio study reduce``). Placed
    like a mounted brush's base: ``pose`` in the body's pose frame, the patch normal (its
    outward side, toward what it touches) along local +z, the tip plane through its origin,
    the rectangle's sides along local x (``size[0]``) and y (``size[1]``)."""

    name: str
    law: Union[str, dict] = Field(
        description="a law file (JSON, relative to the scene file) or the law itself")
    pose: Pose = Pose()
    size: Optional[tuple[PositiveFloat, PositiveFloat]] = Field(
        None, description="m, the footprint a x b (default: the law's patch.size); the "
                          "normal force is the law's force per unit area over it")
    grid: Optional[tuple[Annotated[int, Field(ge=1, le=256)],
                         Annotated[int, Field(ge=1, le=256)]]] = Field(
        None, description="sample points along x and y (default: about square cells, 4 "
                          "along the shorter side, at most 64 along the longer)")

    @model_validator(mode="after")
    def _law_ok(self):
        if isinstance(self.law, dict):
            from engine.model.reduced_law import check_law
            check_law(self.law)
        return self


class Body(_Model):
    name: str
    material: str
    shape: Shape
    mass_properties: Optional[MassProperties] = Field(
        None, description="needed for free, hinge and kinematic-then-free bodies")
    pose: Pose = Pose()
    motion: Motion = FixedMotion()
    velocity: Vector3 = (0.0, 0.0, 0.0)
    angular_velocity: Vector3 = Field((0.0, 0.0, 0.0), description="world frame, rad/s")
    collide: bool = Field(True, description="False: a body that only carries brushes")
    no_contact_with: list[str] = Field(
        default_factory=list, description="names of other bodies this body never touches "
                                          "(e.g. a chaser and a fixture it is docked to)")
    contact_spacing: Optional[PositiveFloat] = Field(
        None, description="m; mesh-mesh contact tests the mesh's vertices, and with a "
                          "spacing also points along its edges and inside its faces at most "
                          "this far apart (needed where a face meets another body away from "
                          "its vertices, e.g. a cylinder's side)")
    external_force: Vector3 = Field(
        (0.0, 0.0, 0.0), description="constant force on a free body's centre of mass, world "
                                     "(Hill) axes, N: a disturbance such as a thruster bias")
    external_torque: Vector3 = Field(
        (0.0, 0.0, 0.0), description="constant torque on a free body, world axes, N m")
    patches: list[Patch] = Field(
        default_factory=list, description="reduced brushes carried by the body: compliant "
                                          "patches with a fitted law (engine.kernels.patch)")
