"""``brush-studio study spin``: the brush dynamic test of seed 4.3 (scenes, analysis and the
run's task in :mod:`studio.studies.spin`): every cube x brush configuration, and one of them
with random bristle tips. Every run is one Dask task (``studio.studies.runner.run_many``).

Outputs (``-o DIR``): ``spin_summary.csv`` (one row per run: rest time, contacts...),
``contacts.csv`` (one row per contact), ``omega.csv`` (omega(t) of every run), ``spin.h5``
(the same arrays), ``omega_<size>mm.png``, ``delta_omega_vs_duration.png``,
``randomness.png``, ``rest_times.png``, ``outcomes.json``; ``runs/`` one result file per run
(:mod:`studio.studies.spin_outputs`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

from . import api
from .api import ExecutionOptions
from .spin import CONFIGS, CUBES_MM, SEED_TIP_VARIANCE, config_label, spin_scene
from .spin_outputs import write_outputs


# ----------------------------------------------------------------------------- study
def build_specs(cubes: Sequence[int], configs: Sequence[int], *, n_nodes=None, omega0=None,
                duration=None, grid=None, random_seeds: int = 0, random_cube: int = 60,
                random_config: int = 5, tip_variance: float = SEED_TIP_VARIANCE,
                record_interval=None):
    """RunSpecs: every cube x configuration with a perfect brush, plus ``random_seeds`` runs
    of (``random_cube``, ``random_config``) with random tips (and its perfect-brush run)."""
    from .runner import RunSpec

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
            task="studio.studies.spin:spin_task"))
    for s in range(1, random_seeds + 1):
        specs.append(RunSpec(
            run_id=f"cube{random_cube}_config{random_config}_random{s}",
            scene=spin_scene(random_cube, random_config, tip_variance=tip_variance, seed=s,
                             **common),
            params={"cube_mm": random_cube, "config": random_config,
                    "tip_variance": tip_variance, "seed": s},
            task="studio.studies.spin:spin_task"))
    return specs


# ----------------------------------------------------------------------------- CLI
def _ints(text: str, what: str) -> list[int]:
    from .study_command import number_list

    return number_list(text, int, f"{what} {text!r}: expected comma-separated integers")


@dataclass
class Options(ExecutionOptions):
    """``brush-studio study spin`` (``None``: the presets' value)."""

    cubes: str = "20,40,60"          # cube edges, mm
    preset: list = field(default_factory=list)  # spin_cube_<edge> presets (instead of cubes)
    configs: str = "1,2,3,4,5,6"     # brush configurations
    n_nodes: Optional[int] = None    # nodes per bristle
    omega0: Optional[float] = None   # initial spin, rad/s
    duration: Optional[float] = None  # simulated time per run at most, s
    grid: Optional[str] = None       # "LONG,SHORT" bristles
    random_seeds: int = 5            # runs with random bristle tips
    random_cube: int = 60
    random_config: int = 5
    tip_variance: float = SEED_TIP_VARIANCE  # m^2
    record_interval: Optional[float] = None


def add_parser(study_subparsers) -> None:
    from .preset_option import add_preset_option
    from .study_command import set_command

    p = study_subparsers.add_parser(
        "spin", help="brush dynamic test (seed 4.3): spinning cubes against the brush",
        description="A cube on a hinge spins into the 17 x 5 silicone brush: omega(t) for "
                    "each cube size and brush configuration, contacts from the contact force, "
                    "delta omega per contact against its duration (seed fig. 4.40), time to "
                    "rest, and the effect of random bristle tips (fig. 4.41). Configurations: "
                    + "; ".join(config_label(c) for c in CONFIGS) + ".")
    p.add_argument("--cubes", default="20,40,60", help="cube edges, mm (default 20,40,60)")
    add_preset_option(p, "spin", [f"spin_cube_{c}" for c in CUBES_MM], "the cubes (--cubes)")
    p.add_argument("--configs", default="1,2,3,4,5,6",
                   help="brush configurations (default all six)")
    p.add_argument("--nodes", "--n-nodes", dest="n_nodes", type=int, default=None,
                   metavar="N", help="nodes per bristle (default: the presets', 6; --n-nodes is the "
                        "older spelling, deprecated)")
    p.add_argument("--omega0", type=float, default=None, metavar="RAD_PER_S",
                   help="initial spin (default: the presets', 10 rad/s)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated time per run, at most (default: the presets', 3 s; a run "
                        "ends earlier once the cube is at rest)")
    p.add_argument("--grid", default=None, metavar="LONG,SHORT",
                   help="bristles along the brush's long and short sides (default 17,5)")
    p.add_argument("--random-seeds", type=int, default=5,
                   help="runs with random bristle tips (default 5; 0: none)")
    p.add_argument("--random-cube", type=int, default=60, help="cube for them (default 60)")
    p.add_argument("--random-config", type=int, default=5,
                   help="configuration for them (default 5: vertical brush touching the face, "
                        "as seed fig. 4.39)")
    p.add_argument("--tip-variance", type=float, default=SEED_TIP_VARIANCE, metavar="M2",
                   help=f"variance of the random tips (default {SEED_TIP_VARIANCE:g} m^2)")
    p.add_argument("--record-interval", type=float, default=None, metavar="S")
    set_command(p, run, Options, default_output="study-spin")


def _run_study(options: Options, out: Path) -> int:
    from .preset_option import chosen
    from .study_command import check_common_options, first_problem, report_failures, run_study

    problem = check_common_options(options)
    try:
        cubes = _ints(options.cubes, "--cubes")
        cubes = chosen("spin", options.preset, {f"spin_cube_{c}": c for c in CUBES_MM},
                       options.cubes, Options.cubes, "--cubes") or cubes
        configs = _ints(options.configs, "--configs")
        grid = tuple(_ints(options.grid, "--grid")) if options.grid else None
    except ValueError as exc:  # PresetChoiceError included
        problem = problem or str(exc)
        cubes, configs, grid = [], [], None
    checks = [
        (all(c in CUBES_MM for c in cubes) and cubes, f"--cubes: each one of {CUBES_MM}"),
        (all(c in CONFIGS for c in configs) and configs, "--configs: each one of 1-6"),
        (grid is None or (len(grid) == 2 and min(grid) >= 1), "--grid: two integers >= 1"),
        (options.n_nodes is None or options.n_nodes >= 2, "--nodes must be >= 2"),
        (options.duration is None or options.duration > 0, "--duration must be > 0"),
        (options.random_seeds >= 0, "--random-seeds must be >= 0"),
        (options.random_cube in CUBES_MM, f"--random-cube: one of {CUBES_MM}"),
        (options.random_config in CONFIGS, "--random-config: one of 1-6"),
        (options.tip_variance > 0, "--tip-variance must be > 0"),
        (options.record_interval is None or options.record_interval > 0,
         "--record-interval must be > 0")]
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
