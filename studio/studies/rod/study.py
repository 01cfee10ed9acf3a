"""``brush-studio study rod``: bristle dynamics of seed 4.1 and the friction-damped frequency
response of seed fig. 4.6 (the rod, its scenes and run tasks: :mod:`studio.studies.rod.runs`).

Every simulation is one Dask task (``studio.studies.runner.run_many``); outputs in ``-o DIR``:
``peaks.json``; ``tip_<case>.csv`` (time, tip x, y, z); ``spectrum_<case>.csv`` (frequency,
PSD); ``frequency_response.csv``; ``rod.h5`` (all of those arrays); ``tip_trajectories.png``,
``spectra.png``, ``frequency_response.png``; ``outcomes.json``; ``runs/`` (one result file
per simulation); written by :mod:`studio.studies.rod.outputs`.
"""
from __future__ import annotations

import math
import typing
from pathlib import Path
from typing import Annotated, Literal, Optional, Sequence

from pydantic import Field

from studio.studies import api
from studio.studies.options import StudyOptions
from studio.studies.rod.runs import (CASES, DEFAULT_FRICTION_ANGLE_DEG, DEFAULT_RESPONSE_FORCE,
                  DEFAULT_RESPONSE_FREQUENCIES, PRESETS, cantilever_frequencies, case_scene,
                  response_scene)
from studio.studies.rod.outputs import write_outputs


# ----------------------------------------------------------------------------- study
def build_specs(cases: Sequence[str], *, n_nodes: Optional[int], free_duration: Optional[float],
                record_interval: Optional[float], response_frequencies: Sequence[float],
                response_nodes: int, response_force: float, friction_angle: float,
                settle_periods: float, measure_periods: float, min_time: float):
    """The RunSpecs of the study: one per excitation case, one per drive frequency."""
    from studio.studies.runner import RunSpec

    specs = []
    for case in cases:
        scene, start = case_scene(case, n_nodes=n_nodes, free_duration=free_duration,
                                  record_interval=record_interval)
        specs.append(RunSpec(run_id=case, scene=scene,
                             params={"case": case, "analysis_start": start},
                             task="studio.studies.rod.runs:excitation_task"))
    for f in response_frequencies:
        scene, start = response_scene(f, n_nodes=response_nodes, force=response_force,
                                      friction_angle=friction_angle,
                                      settle_periods=settle_periods,
                                      measure_periods=measure_periods, min_time=min_time)
        specs.append(RunSpec(run_id=f"response_{f:g}Hz", scene=scene,
                             params={"case": "response", "frequency_hz": float(f),
                                     "measure_start": start, "force": response_force,
                                     "friction_angle": friction_angle},
                             task="studio.studies.rod.runs:response_task"))
    return specs


# ----------------------------------------------------------------------------- CLI
Case = Literal["weight_release", "tip_impulse", "root_impulse", "response"]
assert set(typing.get_args(Case)) == set(CASES + ("response",))


class Options(StudyOptions):
    """``brush-studio study rod`` (``None``: the presets' value)."""

    cases: list[Case] = Field(list(CASES + ("response",)), min_length=1,
                              description="comma-separated subset of: "
                                          + ", ".join(CASES + ("response",)))
    preset: list[str] = Field(
        default_factory=list,
        description="a preset the study's runs start from (repeat for several; default all): "
                    + ", ".join(PRESETS.values()) + "; another way to give the excitation "
                                                    "cases (--cases)",
        json_schema_extra={"metavar": "NAME", "scene": True})
    n_nodes: Optional[int] = Field(
        None, ge=3, le=4096,
        description="nodes per rod for the excitation cases (default: the presets', 36; "
                    "--n-nodes is the older spelling, deprecated)",
        json_schema_extra={"flags": ["--nodes", "--n-nodes"], "metavar": "N"})
    free_duration: Optional[float] = Field(
        None, gt=0, description="free vibration recorded after the excitation (default: the "
                                "presets', 4.5 s)",
        json_schema_extra={"metavar": "S", "unit": "s"})
    record_interval: Optional[float] = Field(
        None, gt=0, description="record interval of the excitation cases (default: the "
                                "presets')", json_schema_extra={"metavar": "S", "unit": "s"})
    frequencies: list[Annotated[float, Field(gt=0, allow_inf_nan=False)]] = Field(
        default_factory=list,
        description="drive frequencies of the response, Hz (default: 24 from 2 to 130)",
        json_schema_extra={"metavar": "F1,F2,...", "unit": "Hz"})
    response_nodes: int = Field(16, ge=3, le=4096,
                                description="nodes per rod for the response runs (default 16)")
    response_force: float = Field(DEFAULT_RESPONSE_FORCE, gt=0,
                                  description=f"tip force amplitude (default "
                                              f"{DEFAULT_RESPONSE_FORCE})",
                                  json_schema_extra={"metavar": "N", "unit": "N"})
    friction_angle: float = Field(DEFAULT_FRICTION_ANGLE_DEG, ge=0, lt=90,
                                  description=f"rod-plate friction angle, degrees (default "
                                              f"{DEFAULT_FRICTION_ANGLE_DEG:g})",
                                  json_schema_extra={"metavar": "DEG", "unit": "deg"})
    settle_periods: float = Field(6.0, gt=0,
                                  description="drive periods to settle before measuring "
                                              "(default 6; at least --min-time)")
    measure_periods: float = Field(6.0, ge=1,
                                   description="drive periods measured (default 6; at least "
                                               "--min-time)")
    min_time: float = Field(0.5, ge=0, description="least settling and measuring time, s "
                                                   "(default 0.5)",
                            json_schema_extra={"metavar": "S", "unit": "s"})


def add_parser(study_subparsers) -> None:
    from studio.studies.study_command import set_command

    p = study_subparsers.add_parser(
        "rod", help="bristle dynamics (seed 4.1): tip spectra and the friction-damped "
                    "frequency response",
        description="The steel rod of seed 4.1: weight release, tip impulse and root impulse "
                    "(tip trajectory, power spectrum, peaks.json with the spectral peaks "
                    "against the Euler-Bernoulli frequencies), and the frequency response of "
                    "the rod lying on a plate with friction (seed fig. 4.6).")
    set_command(p, run, Options, default_output="study-rod")


def _run_study(options: Options, out: Path) -> int:
    from studio.studies.study_command import report_failures, run_study

    from studio.studies.preset_option import PresetChoiceError, chosen

    problem = None
    cases = list(dict.fromkeys(options.cases))
    try:
        cases = chosen("rod", options.preset, {v: k for k, v in PRESETS.items()},
                       options.cases, Options.model_fields["cases"].default,
                       "--cases") or cases
    except PresetChoiceError as exc:
        problem = str(exc)
    freqs = list(options.frequencies) or list(DEFAULT_RESPONSE_FREQUENCIES)
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
        out, options, desc="rod runs", problem=problem)
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
