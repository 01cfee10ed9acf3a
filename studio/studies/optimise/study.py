"""``brush-studio study optimise``: the body of the study (options -> search -> outputs)."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from .. import api
from ...exit_codes import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_FAILED, EXIT_OK
from .errors import StudyInputError
from .options import Options


def _command(options: Options, out: Path) -> str:
    """The command line that makes (and resumes) this search."""
    words = ["brush-studio", "study", "optimise"]
    for name, field in Options.model_fields.items():
        value = getattr(options, name)
        if value == field.get_default(call_default_factory=True) or value is None:
            continue
        flag = "--" + name.replace("_", "-")
        if isinstance(value, bool):
            words.append(flag)
        elif isinstance(value, list):
            words.append(f"{flag} {','.join(str(v) for v in value)}")
        else:
            words.append(f"{flag} {value}")
    return " ".join(words + ["-o", str(out)])


def _body(options, out: Path) -> int:
    from .outputs import (margin, plots, ranked, refinement_check, write_best,
                          write_pareto_csv, write_report, write_trials_csv, feasible)
    from .search import Problem, search

    session = api.current()
    problem = Problem.from_options(options)     # StudyInputError: bad input, exit 2
    out.mkdir(parents=True, exist_ok=True)
    command = _command(options, out)
    print(f"design search: {len(problem.variables)} variable(s), {len(problem.scenarios)} "
          f"scenario(s), {len(problem.objectives)} objective(s), "
          f"{len(problem.constraints)} constraint(s); up to {options.trials} trials")

    def on_trial(log):
        msg = f"trials {log.trials_done}/{options.trials}"
        best = [t for t in ranked(study_ref[0])][:1] if study_ref else []
        if best:
            msg += f", best {problem.objectives[0][0]} {best[0].values[0]:.4g}"
        session.report(log.trials_done / max(options.trials, 1), msg, force=True)
        if not options.no_progress:
            print(msg, file=sys.stderr)

    study_ref: list = []
    from .executor import Executor
    from .search import open_study
    try:
        study_ref.append(open_study(out, problem, options.sampler, options.search_seed))
    except StudyInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    # one cluster (or this process) for the whole search and the refinement re-run
    executor = Executor(out, options.scheduler, options.workers)
    try:
        study, log = search(problem, out, trials=options.trials,
                            cpu_budget_s=options.cpu_budget_s, sampler=options.sampler,
                            seed=options.search_seed, on_trial=on_trial, executor=executor)
        n_rows = write_trials_csv(out / "trials.csv", study, problem)
        write_pareto_csv(out / "pareto.csv", study, problem)
        order = ranked(study)
        winner = order[0] if order and feasible(order[0]) else None
        refinement, gap = None, None
        if winner is not None:
            write_best(out / "best.json", winner, problem)
            gap = margin(study, winner)
            if options.refine and not (problem.reduced and not problem.spot_check_s):
                session.report(1.0, "DEM spot check of the winner" if problem.reduced
                               else "refinement re-run of the winner", force=True)
                executor.submit(problem.specs(dict(winner.params), refined=True))
                done = []
                while not done:
                    done = executor.wait_any()
                if problem.reduced:
                    refinement = _spot_check(problem, winner, done[0][1], out)
                else:
                    refinement = refinement_check(problem, winner, done[0][1], gap)
                    refinement.pop("rows", None)
    finally:
        executor.close()
    plots(out, study, problem, winner)
    write_report(out / "report.md", problem, study, winner, log, refinement, gap, command)
    summary = {"trials": len([t for t in study.get_trials(deepcopy=False)]),
               "trials_run": log.trials_run, "runs_run": log.runs_run,
               "runs_reused": log.runs_reused, "run_cpu_s": log.run_cpu_s,
               "sim_cpu_s": log.sim_cpu_s, "search_wall_s": log.wall_s,
               "stopped_by": log.stopped_by, "rows": n_rows,
               "winner": None if winner is None else {
                   "trial": winner.number, "design": dict(winner.params),
                   "objectives": list(winner.values),
                   "constraints": winner.user_attrs.get("constraints", [])},
               "margin": gap, "refinement": refinement, "command": command}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    if winner is None:
        print("no feasible design found; see trials.csv and report.md")
    else:
        print(f"winner: trial {winner.number} {json.dumps(dict(winner.params))} "
              f"objectives {[round(v, 6) for v in winner.values]}")
        if refinement is not None:
            print(f"refinement: {'resolved' if refinement['resolved'] else 'UNRESOLVED'} "
                  f"({refinement['why']})")
    print(f"Wrote {out}/trials.csv, pareto.csv, best.json, report.md, summary.json and PNGs")
    failed = [t for t in study.get_trials(deepcopy=False)
              if t.user_attrs.get("failed_runs")]
    if failed:
        print(f"{len(failed)} trial(s) had failed runs (see trials.csv)", file=sys.stderr)
    return EXIT_OK if winner is not None else EXIT_FAILED


def _spot_check(problem, winner, dem_outcomes: list[dict], out: Path) -> dict:
    """``--fidelity reduced``'s refinement: the winner's DEM spot checks against its
    reduced runs (found in ``runs/``), written to ``spot_check.json``."""
    from .executor import cached
    from .reduced import spot_check_report

    reduced_runs = [cached(out.resolve(), spec) or {"status": "missing"}
                    for spec in problem.specs(dict(winner.params))]
    report = spot_check_report(reduced_runs, dem_outcomes,
                               [s.scenario_id for s in problem.scenarios],
                               problem.spot_check_s)
    (out / "spot_check.json").write_text(json.dumps(report, indent=2, default=str))
    report.pop("checks", None)
    return report


def _study(options, out: Path):
    """The body for :func:`studio.studies.api.study_run`: exit code and the summary."""
    code = int(_body(options, out) or 0)
    summary_file = out / "summary.json"
    summary = (json.loads(summary_file.read_text())
               if code == EXIT_OK and summary_file.is_file() else {})
    return code, summary


#: ``run(options, out_dir, *, progress=None, cancel=None) -> StudyResult``: ``summary`` holds
#: the headline figures, ``tables`` the CSVs (trials, pareto), ``figures`` the plots
run = api.study_run("optimise", _study)


def add_parser(study_subparsers) -> None:
    from ..study_command import set_command

    p = study_subparsers.add_parser(
        "optimise", help="design search: which brush serves a set of spinning targets best "
                         "(Optuna on Dask)",
        description="Searches brush designs (variables at their paths in the scene, or the "
                    "bristle bending stiffness E d^4) against a set of spinning targets (the "
                    "seed's spin-cube rig: sizes, spin rates, brush placements, a tumbling "
                    "box, material draws), minimising objectives aggregated over the "
                    "scenarios under constraints. Optuna (TPE / NSGA-II) with its storage in "
                    "the output folder: run the same command again to resume, raise --trials "
                    "to extend. Writes trials.csv, pareto.csv, best.json, report.md and plots. "
                    "See docs/design.md.")
    set_command(p, run, Options, default_output="study-optimise")
