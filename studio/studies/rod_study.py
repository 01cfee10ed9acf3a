"""``brush-studio study rod``: bristle dynamics of seed 4.1 and the friction-damped frequency
response of seed fig. 4.6 (the rod, its scenes and run tasks: :mod:`studio.studies.rod`).

Every simulation is one Dask task (``studio.studies.runner.run_many``); outputs in ``-o DIR``:
``peaks.json``; ``tip_<case>.csv`` (time, tip x, y, z); ``spectrum_<case>.csv`` (frequency,
PSD); ``frequency_response.csv``; ``rod.h5`` (all of those arrays); ``tip_trajectories.png``,
``spectra.png``, ``frequency_response.png``; ``outcomes.json``; ``runs/`` (one result file
per simulation); written by :mod:`studio.studies.rod_outputs`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

from . import api
from .api import ExecutionOptions
from .rod import (CASES, DEFAULT_FRICTION_ANGLE_DEG, DEFAULT_RESPONSE_FORCE,
                  DEFAULT_RESPONSE_FREQUENCIES, PRESETS, cantilever_frequencies, case_scene,
                  response_scene)
from .rod_outputs import write_outputs


# ----------------------------------------------------------------------------- study
def build_specs(cases: Sequence[str], *, n_nodes: Optional[int], free_duration: Optional[float],
                record_interval: Optional[float], response_frequencies: Sequence[float],
                response_nodes: int, response_force: float, friction_angle: float,
                settle_periods: float, measure_periods: float, min_time: float):
    """The RunSpecs of the study: one per excitation case, one per drive frequency."""
    from .runner import RunSpec

    specs = []
    for case in cases:
        scene, start = case_scene(case, n_nodes=n_nodes, free_duration=free_duration,
                                  record_interval=record_interval)
        specs.append(RunSpec(run_id=case, scene=scene,
                             params={"case": case, "analysis_start": start},
                             task="studio.studies.rod:excitation_task"))
    for f in response_frequencies:
        scene, start = response_scene(f, n_nodes=response_nodes, force=response_force,
                                      friction_angle=friction_angle,
                                      settle_periods=settle_periods,
                                      measure_periods=measure_periods, min_time=min_time)
        specs.append(RunSpec(run_id=f"response_{f:g}Hz", scene=scene,
                             params={"case": "response", "frequency_hz": float(f),
                                     "measure_start": start, "force": response_force,
                                     "friction_angle": friction_angle},
                             task="studio.studies.rod:response_task"))
    return specs


# ----------------------------------------------------------------------------- CLI
@dataclass
class Options(ExecutionOptions):
    """``brush-studio study rod`` (``None``: the presets' value)."""

    cases: str = ",".join(CASES + ("response",))  # comma-separated subset
    preset: list = field(default_factory=list)     # rod presets (instead of cases)
    n_nodes: Optional[int] = None                  # nodes per rod, excitation cases
    free_duration: Optional[float] = None          # free vibration after the excitation, s
    record_interval: Optional[float] = None        # s
    frequencies: Optional[str] = None              # drive frequencies "F1,F2,...", Hz
    response_nodes: int = 16
    response_force: float = DEFAULT_RESPONSE_FORCE  # tip force amplitude, N
    friction_angle: float = DEFAULT_FRICTION_ANGLE_DEG  # rod-plate, degrees
    settle_periods: float = 6.0
    measure_periods: float = 6.0
    min_time: float = 0.5                          # least settling and measuring time, s


def add_parser(study_subparsers) -> None:
    from .preset_option import add_preset_option
    from .study_command import set_command

    p = study_subparsers.add_parser(
        "rod", help="bristle dynamics (seed 4.1): tip spectra and the friction-damped "
                    "frequency response",
        description="The steel rod of seed 4.1: weight release, tip impulse and root impulse "
                    "(tip trajectory, power spectrum, peaks.json with the spectral peaks "
                    "against the Euler-Bernoulli frequencies), and the frequency response of "
                    "the rod lying on a plate with friction (seed fig. 4.6).")
    p.add_argument("--cases", default=",".join(CASES + ("response",)),
                   help="comma-separated subset of: " + ", ".join(CASES + ("response",)))
    add_preset_option(p, "rod", list(PRESETS.values()), "the excitation cases (--cases)")
    p.add_argument("--nodes", "--n-nodes", dest="n_nodes", type=int, default=None,
                   metavar="N", help="nodes per rod for the excitation cases (default: the presets', 36; "
                        "--n-nodes is the older spelling, deprecated)")
    p.add_argument("--free-duration", type=float, default=None, metavar="S",
                   help="free vibration recorded after the excitation (default: the "
                        "presets', 4.5 s)")
    p.add_argument("--record-interval", type=float, default=None, metavar="S",
                   help="record interval of the excitation cases (default: the presets')")
    p.add_argument("--frequencies", default=None, metavar="F1,F2,...",
                   help="drive frequencies of the response, Hz (default: 24 from 2 to 130)")
    p.add_argument("--response-nodes", type=int, default=16,
                   help="nodes per rod for the response runs (default 16)")
    p.add_argument("--response-force", type=float, default=DEFAULT_RESPONSE_FORCE,
                   metavar="N", help=f"tip force amplitude (default {DEFAULT_RESPONSE_FORCE})")
    p.add_argument("--friction-angle", type=float, default=DEFAULT_FRICTION_ANGLE_DEG,
                   metavar="DEG", help="rod-plate friction angle, degrees (default "
                                       f"{DEFAULT_FRICTION_ANGLE_DEG:g})")
    p.add_argument("--settle-periods", type=float, default=6.0,
                   help="drive periods to settle before measuring (default 6; at least "
                        "--min-time)")
    p.add_argument("--measure-periods", type=float, default=6.0,
                   help="drive periods measured (default 6; at least --min-time)")
    p.add_argument("--min-time", type=float, default=0.5, metavar="S",
                   help="least settling and measuring time, s (default 0.5)")
    set_command(p, run, Options, default_output="study-rod")


def _run_study(options: Options, out: Path) -> int:
    from .study_command import (check_common_options, first_problem, number_list,
                                report_failures, run_study)

    from .preset_option import PresetChoiceError, chosen

    problem = check_common_options(options)
    cases = [c.strip() for c in options.cases.split(",") if c.strip()]
    bad = [c for c in cases if c not in CASES + ("response",)]
    if bad:
        problem = f"--cases: unknown {bad}; choose from {CASES + ('response',)}"
    try:
        cases = chosen("rod", options.preset, {v: k for k, v in PRESETS.items()},
                       options.cases, Options.cases, "--cases") or cases
    except PresetChoiceError as exc:
        problem = problem or str(exc)
    try:
        freqs = (number_list(options.frequencies, float,
                             f"{options.frequencies!r}: expected comma-separated numbers")
                 if options.frequencies else list(DEFAULT_RESPONSE_FREQUENCIES))
    except ValueError as exc:
        problem = f"--frequencies: {exc}"
        freqs = []
    checks = [(options.n_nodes is None or options.n_nodes >= 3, "--nodes must be >= 3"),
              (options.response_nodes >= 3, "--response-nodes must be >= 3"),
              (options.free_duration is None or options.free_duration > 0, "--free-duration must be > 0"),
              (options.record_interval is None or options.record_interval > 0,
               "--record-interval must be > 0"),
              (all(f > 0 for f in freqs), "--frequencies must be > 0"),
              (options.response_force > 0, "--response-force must be > 0"),
              (0 <= options.friction_angle < 90, "--friction-angle must be in [0, 90) degrees"),
              (options.settle_periods > 0 and options.measure_periods >= 1,
               "--settle-periods must be > 0 and --measure-periods >= 1"),
              (options.min_time >= 0, "--min-time must be >= 0")]
    code, outcomes = run_study(
        lambda: build_specs([c for c in cases if c in CASES], n_nodes=options.n_nodes,
                            free_duration=options.free_duration,
                            record_interval=options.record_interval,
                            response_frequencies=freqs if "response" in cases else [],
                            response_nodes=options.response_nodes,
                            response_force=options.response_force,
                            friction_angle=math.radians(options.friction_angle),
                            settle_periods=options.settle_periods,
                            measure_periods=options.measure_periods, min_time=options.min_time),
        out, options, desc="rod runs", problem=first_problem(problem, checks))
    if code is not None:
        return code
    analytic = cantilever_frequencies()
    doc = write_outputs(out, outcomes, analytic)
    print("Euler-Bernoulli: " + ", ".join(f"{f:.3f}" for f in analytic) + " Hz")
    for case, c in doc["cases"].items():
        modes = ", ".join(
            f"{m['measured_hz']:.3f} Hz ({m['rel_error']:+.2%})" if m["measured_hz"] else "-"
            for m in c["modes"])
        print(f"  {case:15s} modes 1-3: {modes}")
    fr = doc.get("frequency_response")
    if fr:
        peaks = ", ".join(f"{f:g}" for f in fr["peaks_hz"]) or "none"
        print(f"  friction response: largest {max(fr['amplitude_m']) * 1e3:.3g} mm; "
              f"response peaks at {peaks} Hz"
              + (f" (high/low peak ratio {fr['high_to_low']:.3f})" if fr.get("high_to_low")
                 is not None else " (no peak above the first mode's region)"))
    print(f"Wrote {out}/peaks.json, CSVs, rod.h5 and PNGs")
    return report_failures(outcomes)


run = api.study_run("rod", _run_study)
