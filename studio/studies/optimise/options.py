"""The options of ``brush-studio study optimise``: one pydantic model, each field declared once
with its default, bounds, help text (``description``) and unit (``json_schema_extra``).

The command-line parser (``studio.studies.options.add_model_arguments``), the studio's form and the HTTP schema
(``Options.model_json_schema()``) come from this declaration.
"""
from __future__ import annotations

from typing import Literal, Optional

from pydantic import Field

from ..detumble_analysis import DEFAULT_ISP
from ..options import StudyOptions


class Options(StudyOptions):
    """``brush-studio study optimise``: which brush serves a set of spinning targets best."""

    preset: str = Field("spin_cube_40", description="the design to start from: a preset "
                        "(or scene file) with one brush; its brush is the design, the targets "
                        "come from --cubes-mm, --spin-rates ... (the spin-cube test rig, seed 4.3)",
                        json_schema_extra={"scene": True, "design": True})
    variables: list[str] = Field(
        default_factory=lambda: ["bending_stiffness=2e-6:2e-4:log"],
        description="design variables, each PATH=LOW:HIGH[:log][:step=S]; PATH is a field of "
                    "the scene (brushes.0.root_radius, brushes.0.bristle_length, "
                    "brushes.0.material.youngs_modulus, brushes.0.pitch.0, brushes.0.rows, "
                    "controllers.0.release_below ...) or bending_stiffness (E d^4 of the bristle "
                    "root, Pa m^4; see --stiffness-via); SI units as in the scene file")
    stiffness_via: Literal["youngs_modulus", "diameter"] = Field(
        "youngs_modulus", description="how a bending_stiffness value E d^4 is put into the "
                                      "scene: through E (geometry kept) or through the "
                                      "bristle diameter (E and the taper ratio kept)")
    objectives: list[str] = Field(
        default_factory=lambda: ["abs_spin_left:worst"],
        description="objectives to minimise, each METRIC[:AGG], AGG = mean | worst | pNN "
                    "(a percentile over the scenarios); metrics: docs/design.md "
                    "(abs_spin_left, spin_left, delta_omega, peak_force, peak_torque, "
                    "peak_stress_ratio, brush_mass, contact_duration, rest_time, "
                    "chaser_delta_v, wheel_momentum, peak_chaser_torque, "
                    "peak_contact_pressure)")
    constraints: list[str] = Field(
        default_factory=list,
        description="constraints, each METRIC[:AGG]<=LIMIT (SI units), e.g. "
                    "peak_stress_ratio:worst<=1 or peak_force:worst<=5")
    cubes_mm: list[float] = Field(default_factory=lambda: [40.0],
                                  description="edges of the target cubes",
                                  json_schema_extra={"unit": "mm"})
    spin_rates: list[float] = Field(default_factory=lambda: [10.0],
                                    description="initial spin rates of the targets",
                                    json_schema_extra={"unit": "rad/s"})
    configs: list[int] = Field(default_factory=lambda: [1],
                               description="brush placements (contact offsets) of the spin "
                                           "study, 1-6: 1 face-on at the axis, 2 halfway to "
                                           "the edge, 3/4 at the top face, 5/6 vertical brush")
    tumbling: bool = Field(False, description="add a tumbling target per cube: a free "
                           "a x 1.25a x 1.5a box spinning about a non-principal axis")
    density: float = Field(700.0, gt=0, description="target density",
                           json_schema_extra={"unit": "kg/m^3"})
    material_draws: int = Field(0, ge=0, le=100, description="uncertain brush material per "
                                "scenario: this many draws of E (+-20 %) and friction "
                                "(+-20 %), uniform, as montecarlo draws them; 0: nominal")
    seed: int = Field(1, ge=0, description="seed of the material draws (every design sees "
                                           "the same draws)")
    chaser_mass_kg: Optional[float] = Field(
        None, gt=0, description="mass of the chaser a fixed brush would be on (the spin "
                                "rig's brush is fixed): chaser_delta_v is its load's impulse "
                                "over this; refused for a brush mounted on a body (its own "
                                "mass counts)", json_schema_extra={"unit": "kg"})
    stress_limit_mpa: float = Field(5.0, gt=0, description="bristle material's allowed "
                                    "bending stress (peak_stress_ratio = peak stress / this)",
                                    json_schema_extra={"unit": "MPa"})
    trials: int = Field(20, ge=1, le=100_000, description="designs to try in all (a "
                        "resumed search counts the finished ones; raise it to extend)")
    cpu_budget_s: Optional[float] = Field(None, gt=0, description="stop asking for new "
                                          "designs once the runs used this much CPU",
                                          json_schema_extra={"unit": "s"})
    sampler: Literal["auto", "tpe", "nsga2", "random"] = Field(
        "auto", description="Optuna sampler: auto = TPE for one objective, NSGA-II for "
                            "several")
    nodes: Optional[int] = Field(None, ge=2, le=64, description="nodes per bristle of the "
                                 "search runs (default 3; --fidelity reduced: the preset's, "
                                 "for the law fits)")
    duration_s: Optional[float] = Field(
        None, gt=0, description="simulated time per scenario at most (default 0.4 s: a run "
                                "ends when its first contact is over, unless rest_time is "
                                "asked for; --fidelity reduced: 3600 s, or until detumbled)",
        json_schema_extra={"unit": "s"})
    fidelity: Literal["dem", "reduced"] = Field(
        "dem", description="dem: the spin rig's short DEM runs (--cubes-mm ...); reduced: "
                           "hour-long detumbles of a detumble preset (--preset "
                           "detumble_upper_stage) over --sizes, --spins-deg, --tilts-deg, "
                           "--tumbles, --offsets-m, each design's brush replaced by a law "
                           "fitted by study reduce into OUTPUT/laws/DESIGN/ (docs/design.md)")
    sizes: list[float] = Field(default_factory=lambda: [1.0],
                               description="--fidelity reduced: target scale factors of the "
                                           "detumble preset")
    spins_deg: list[float] = Field(default_factory=list,
                                   description="--fidelity reduced: initial spin rates "
                                               "(default: the preset's)",
                                   json_schema_extra={"unit": "deg/s"})
    tilts_deg: list[float] = Field(default_factory=lambda: [0.0],
                                   description="--fidelity reduced: spin-axis tilts toward "
                                               "the brush normal",
                                   json_schema_extra={"unit": "deg"})
    tumbles: list[float] = Field(default_factory=lambda: [0.0],
                                 description="--fidelity reduced: a transverse spin "
                                             "component, a fraction of |omega| (tumbling)")
    offsets_m: list[float] = Field(default_factory=lambda: [0.0],
                                   description="--fidelity reduced: the hold point moved "
                                               "across the surface's motion",
                                   json_schema_extra={"unit": "m"})
    spot_check_s: float = Field(5.0, ge=0, description="--fidelity reduced: the winner's "
                                "DEM spot check, the first seconds of each scenario with "
                                "the DEM brush against its reduced run (0: none)",
                                json_schema_extra={"unit": "s"})
    isp: float = Field(DEFAULT_ISP, gt=0, description="--fidelity reduced: specific impulse "
                       "of the chaser's thrusters, for the propellant_mass metric",
                       json_schema_extra={"unit": "s"})
    refine: bool = Field(True, description="re-run the winner with twice the nodes and half "
                                           "the time step and report whether it holds")
    search_seed: int = Field(0, ge=0, description="seed of the Optuna sampler")
