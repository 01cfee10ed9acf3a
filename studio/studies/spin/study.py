"""``brush-studio study spin``: the brush dynamic test of seed 4.3 (scenes, analysis and the
run's task in :mod:`studio.studies.spin.runs`): every cube x brush configuration, and one of them
with random bristle tips. Every run is one Dask task (``studio.studies.runner.run_many``).

Outputs (``-o DIR``): ``spin_summary.csv`` (one row per run: rest time, contacts...),
``contacts.csv`` (one row per contact), ``omega.csv`` (omega(t) of every run), ``spin.h5``
(the same arrays), ``omega_<size>mm.png``, ``delta_omega_vs_duration.png``,
``randomness.png``, ``rest_times.png``, ``outcomes.json``; ``runs/`` one result file per run
(:mod:`studio.studies.spin.outputs`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal, Optional, Sequence

from pydantic import Field

from studio.studies import api
from studio.studies.options import StudyOptions
from studio.studies.spin.runs import CONFIGS, CUBES_MM, SEED_TIP_VARIANCE, config_label, spin_scene
from studio.studies.spin.outputs import write_outputs


# ----------------------------------------------------------------------------- study
def build_specs(cubes: Sequence[int], configs: Sequence[int], *, n_nodes=None, omega0=None,
                duration=None, grid=None, random_seeds: int = 0, random_cube: int = 60,
                random_config: int = 5, tip_variance: float = SEED_TIP_VARIANCE,
                record_interval=None):
    """RunSpecs: every cube x configuration with a perfect brush, plus ``random_seeds`` runs
    of (``random_cube``, ``random_config``) with random tips (and its perfect-brush run)."""
    from studio.studies.runner import RunSpec

    common = dict(n_nodes=n_nodes, omega0=omega0, duration=duration, grid=grid,
                  record_interval=record_interval)
    specs = []
    pairs = [(c, k) for c in cubes for k in configs]
    if random_seeds and (random_cube, random_config) not in pairs:
        pairs.append((random_cube, random_config))
    for cube, cfg in pairs:
        specs.append(RunSpec(
            run_id=f"cube{cube}_config{cfg}", scene=spin_scene(cube, cfg, **common),
            params={"cube_mm": cube, "config": cfg, "tip_variance": 0.0, "seed": 0},
            task="studio.studies.spin.runs:spin_task"))
    for s in range(1, random_seeds + 1):
        specs.append(RunSpec(
            run_id=f"cube{random_cube}_config{random_config}_random{s}",
            scene=spin_scene(random_cube, random_config, tip_variance=tip_variance, seed=s,
                             **common),
            params={"cube_mm": random_cube, "config": random_config,
                    "tip_variance": tip_variance, "seed": s},
            task="studio.studies.spin.runs:spin_task"))
    return specs


# ----------------------------------------------------------------------------- CLI
Cube = Literal[20, 40, 60]
Config = Literal[1, 2, 3, 4, 5, 6]


class Options(StudyOptions):
    """``brush-studio study spin`` (``None``: the presets' value)."""

    cubes: list[Cube] = Field([20, 40, 60], min_length=1,
                              description="cube edges, mm (default 20,40,60)",
                              json_schema_extra={"unit": "mm"})
    preset: list[str] = Field(
        default_factory=list,
        description="a preset the study's runs start from (repeat for several; default all): "
                    + ", ".join(f"spin_cube_{c}" for c in CUBES_MM)
                    + "; another way to give the cubes (--cubes)",
        json_schema_extra={"metavar": "NAME", "scene": True})
    configs: list[Config] = Field([1, 2, 3, 4, 5, 6], min_length=1,
                                  description="brush configurations (default all six)")
    n_nodes: Optional[int] = Field(
        None, ge=2, le=4096,
        description="nodes per bristle (default: the presets', 6; --n-nodes is the older "
                    "spelling, deprecated)",
        json_schema_extra={"flags": ["--nodes", "--n-nodes"], "metavar": "N"})
    omega0: Optional[float] = Field(None, description="initial spin (default: the presets', "
                                                      "10 rad/s)",
                                    json_schema_extra={"metavar": "RAD_PER_S",
                                                       "unit": "rad/s"})
    duration: Optional[float] = Field(
        None, gt=0, description="simulated time per run, at most (default: the presets', 3 s; "
                                "a run ends earlier once the cube is at rest)",
        json_schema_extra={"metavar": "S", "unit": "s"})
    grid: list[Annotated[int, Field(ge=1)]] = Field(
        default_factory=list, description="bristles along the brush's long and short sides "
                                          "(default 17,5)",
        json_schema_extra={"metavar": "LONG,SHORT"})
    random_seeds: int = Field(5, ge=0,
                              description="runs with random bristle tips (default 5; 0: none)")
    random_cube: Cube = Field(60, description="cube for them (default 60)")
    random_config: Config = Field(5, description="configuration for them (default 5: "
                                                 "vertical brush touching the face, as seed "
                                                 "fig. 4.39)")
    tip_variance: float = Field(SEED_TIP_VARIANCE, gt=0,
                                description=f"variance of the random tips (default "
                                            f"{SEED_TIP_VARIANCE:g} m^2)",
                                json_schema_extra={"metavar": "M2", "unit": "m^2"})
    record_interval: Optional[float] = Field(None, gt=0,
                                             description="time between recorded frames, s",
                                             json_schema_extra={"metavar": "S", "unit": "s"})


def add_parser(study_subparsers) -> None:
    from studio.studies.study_command import set_command

    p = study_subparsers.add_parser(
        "spin", help="brush dynamic test (seed 4.3): spinning cubes against the brush",
        description="A cube on a hinge spins into the 17 x 5 silicone brush: omega(t) for "
                    "each cube size and brush configuration, contacts from the contact force, "
                    "delta omega per contact against its duration (seed fig. 4.40), time to "
                    "rest, and the effect of random bristle tips (fig. 4.41). Configurations: "
                    + "; ".join(config_label(c) for c in CONFIGS) + ".")
    set_command(p, run, Options, default_output="study-spin")


def _run_study(options: Options, out: Path) -> int:
    from studio.studies.preset_option import chosen
    from studio.studies.study_command import first_problem, report_failures, run_study

    problem = None
    cubes = list(options.cubes)
    configs = list(options.configs)
    grid = tuple(options.grid) if options.grid else None
    try:
        cubes = chosen("spin", options.preset, {f"spin_cube_{c}": c for c in CUBES_MM},
                       options.cubes, Options.model_fields["cubes"].default,
                       "--cubes") or cubes
    except ValueError as exc:  # PresetChoiceError
        problem = str(exc)
    checks = [(grid is None or len(grid) == 2, "--grid: two integers >= 1")]
    code, outcomes = run_study(
        lambda: build_specs(cubes, configs, n_nodes=options.n_nodes, omega0=options.omega0,
                            duration=options.duration, grid=grid,
                            random_seeds=options.random_seeds, random_cube=options.random_cube,
                            random_config=options.random_config, tip_variance=options.tip_variance,
                            record_interval=options.record_interval),
        out, options, desc="spin runs", problem=first_problem(problem, checks))
    if code is not None:
        return code
    summary = write_outputs(out, outcomes)
    print(f"{'run':28s} {'rest time':>10s} {'contacts':>8s}  Δω range [rad/s]")
    for r in summary["runs"]:
        rest = f"{r['rest_time']:.3f} s" if r["rest_time"] is not None else "turning"
        print(f"{r['run_id']:28s} {rest:>10s} {r['n_contacts']:8d}  "
              f"{r['delta_omega_spread']:.3g}")
    print(f"Wrote {out}/spin_summary.csv, contacts.csv, omega.csv, spin.h5 and PNGs")
    return report_failures(outcomes)


run = api.study_run("spin", _run_study)
