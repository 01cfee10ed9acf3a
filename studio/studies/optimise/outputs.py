"""What a design search writes: ``trials.csv``, ``pareto.csv``, ``best.json``,
``refinement.csv``, the plots and ``report.md`` (the files are described in docs/design.md)."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Optional

import numpy as np

from .groups import groups
from .search import Problem, counted, design_key


def finished_trials(study) -> list:
    return [t for t in study.get_trials(deepcopy=False) if counted(t)]


def feasible(trial) -> bool:
    return all(c <= 0 for c in trial.user_attrs.get("constraints", []))


def ranked(study) -> list:
    """Complete trials, feasible first, by their first objective."""
    import optuna

    done = [t for t in finished_trials(study) if t.state == optuna.trial.TrialState.COMPLETE]
    return sorted(done, key=lambda t: (not feasible(t), t.values[0]))


def pareto(study) -> list:
    """The feasible non-dominated complete trials (Optuna's best_trials: it keeps feasible
    ones first when constraints are given)."""
    return [t for t in study.best_trials if feasible(t)]


def write_trials_csv(path: Path, study, problem: Problem) -> int:
    """One row per design x scenario: the design, every metric, the aggregated objectives
    and constraint values of the design. Returns the number of rows."""
    var_names = [v.path for v in problem.variables]
    obj_names = [f"objective.{m}:{a}" for m, a in problem.objectives]
    con_names = [f"constraint.{m}:{a}<={v:g}" for m, a, v in problem.constraints]
    metric_keys = problem.run_keys
    scen = {s.scenario_id: s for s in problem.scenarios}
    columns = type(problem.scenarios[0]).COLUMNS
    header = (["trial", "state", "feasible", "design_key"] + var_names + obj_names + con_names
              + ["scenario"] + list(columns) + ["status"] + list(metric_keys)
              + ["stiffness_group", "length_ratio", "mass_ratio", "error"])
    n = 0
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for t in finished_trials(study):
            values = list(t.values) if t.values else [None] * len(obj_names)
            cons = t.user_attrs.get("constraints") or [None] * len(con_names)
            design = {p: t.params.get(p) for p in var_names}
            for row in t.user_attrs.get("scenarios", []):
                s = scen.get(row.get("scenario"))
                g = groups(problem.scene(design, s)) if s is not None and None not in \
                    design.values() and not problem.reduced else {}
                w.writerow([t.number, t.state.name, feasible(t) and t.values is not None,
                            t.user_attrs.get("design_key", "")]
                           + [design[p] for p in var_names] + values + list(cons)
                           + [row.get("scenario")]
                           + [getattr(s, c) if s else None for c in columns]
                           + [row.get("status")]
                           + [row.get(k) for k in metric_keys]
                           + [g.get("stiffness_group"), g.get("length_ratio"),
                              g.get("mass_ratio"), row.get("error")])
                n += 1
    return n


def write_pareto_csv(path: Path, study, problem: Problem) -> list:
    front = pareto(study)
    var_names = [v.path for v in problem.variables]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["trial"] + var_names + [f"{m}:{a}" for m, a in problem.objectives]
                   + [f"{m}:{a}<={v:g} (value - limit)" for m, a, v in problem.constraints])
        for t in sorted(front, key=lambda t: t.values[0]):
            w.writerow([t.number] + [t.params[p] for p in var_names] + list(t.values)
                       + list(t.user_attrs.get("constraints", [])))
    return front


def worst_scenario(trial, problem: Problem) -> tuple[str, float]:
    """The scenario with the worst value of the first objective's metric for ``trial``."""
    metric = problem.objectives[0][0]
    rows = trial.user_attrs.get("scenarios", [])
    row = max(rows, key=lambda r: -math.inf if r.get(metric) is None else r[metric])
    return row["scenario"], float(row[metric])


def write_best(path: Path, trial, problem: Problem) -> dict:
    """``best.json``: the winner against its worst scenario, a valid scene file (the
    studio and ``engine.load_scene`` read it), recorded for playback."""
    import engine

    design = dict(trial.params)
    name, _ = worst_scenario(trial, problem)
    s = next(x for x in problem.scenarios if x.scenario_id == name)
    scene = problem.scene(design, s)
    if problem.reduced:   # what ran: the brush as its law (law.json in laws/<key>/)
        from engine.model.reduced_law import load_law

        from ..detumble import REDUCED_RECORD_INTERVAL, reduced_scene
        from .reduced import LAWS_DIR

        law = load_law(Path(path).parent / LAWS_DIR / trial.user_attrs["design_key"]
                       / "law.json")
        scene = reduced_scene(scene, law)
        scene["run"]["record_interval"] = REDUCED_RECORD_INTERVAL
    else:
        scene["run"]["channels"] = ["nodes", "bodies", "contacts", "energy"]
        scene["run"]["record_interval"] = 2e-3
    scene["name"] = f"optimise_best_trial{trial.number}"
    scene["description"] = (f"Study 'optimise': trial {trial.number}, the winner "
                            f"({json.dumps(design)}), against its worst scenario {name}.")
    parsed = engine.parse_scene(scene)  # refuses an invalid one
    Path(path).write_text(parsed.to_json())
    return scene


def plots(out: Path, study, problem: Problem, winner) -> list[Path]:
    """objective_vs_<variable>.png per variable and objective (feasible and infeasible
    marked, the winner circled), pareto.png with two objectives or more."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import optuna

    done = [t for t in finished_trials(study) if t.state == optuna.trial.TrialState.COMPLETE]
    files = []
    worst = worst_scenario(winner, problem)[0] if winner is not None else None
    for k, (metric, agg) in enumerate(problem.objectives):
        for v in problem.variables:
            fig, ax = plt.subplots(figsize=(7, 4.5))
            for ok, style, label in ((True, dict(marker="o", color="C0"), "feasible"),
                                     (False, dict(marker="x", color="C3"), "infeasible")):
                pts = [(t.params[v.path], t.values[k]) for t in done if feasible(t) == ok]
                if pts:
                    x, y = zip(*pts)
                    ax.scatter(x, y, label=label, **style)
            if winner is not None:
                ax.scatter([winner.params[v.path]], [winner.values[k]], s=200,
                           facecolors="none", edgecolors="k",
                           label=f"winner (trial {winner.number}; worst scenario {worst})")
            if v.log:
                from matplotlib.ticker import NullFormatter

                ax.set_xscale("log")
                ax.xaxis.set_minor_formatter(NullFormatter())  # minor labels overlap
            ax.set_xlabel(v.path)
            ax.set_ylabel(f"{metric} ({agg} over {len(problem.scenarios)} scenarios)")
            ax.legend(fontsize=8)
            ax.grid(alpha=0.3)
            fig.tight_layout()
            name = f"{metric}_vs_{v.path.replace('.', '_')}.png"
            fig.savefig(out / name, dpi=110)
            plt.close(fig)
            files.append(out / name)
    if len(problem.objectives) >= 2:
        fig, ax = plt.subplots(figsize=(7, 5))
        xs = [t.values[0] for t in done]
        ys = [t.values[1] for t in done]
        ax.scatter(xs, ys, color="0.6", label="trials")
        front = sorted(pareto(study), key=lambda t: t.values[0])
        if front:
            ax.plot([t.values[0] for t in front], [t.values[1] for t in front], "o-",
                    color="C1", label="Pareto front (feasible)")
        (m0, a0), (m1, a1) = problem.objectives[:2]
        ax.set_xlabel(f"{m0} ({a0})")
        ax.set_ylabel(f"{m1} ({a1})")
        ax.legend()
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(out / "pareto.png", dpi=110)
        plt.close(fig)
        files.append(out / "pareto.png")
    return files


def margin(study, winner, k: int = 0) -> Optional[float]:
    """The winner's margin in objective ``k``: the gap to the best other design (another
    design key) that is feasible; None with no other design."""
    others = [t.values[k] for t in ranked(study)
              if feasible(t) and t.user_attrs.get("design_key")
              != winner.user_attrs.get("design_key")]
    return float(min(others) - winner.values[k]) if others else None


def refinement_check(problem: Problem, winner, fine_outcomes: list[dict], gap) -> dict:
    """Objectives and constraints of the winner re-run finer against the search's values;
    ``resolved`` when no objective moved by more than its margin and no constraint changed
    side."""
    fine = problem.evaluate(fine_outcomes)
    if fine["failed"]:
        return {"resolved": False, "why": "refined runs failed: " + "; ".join(fine["failed"]),
                "fine": None}
    moves = [abs(f - c) for f, c in zip(fine["values"], winner.values)]
    coarse_c = winner.user_attrs.get("constraints", [])
    flips = [i for i, (a, b) in enumerate(zip(coarse_c, fine["constraints"]))
             if (a <= 0) != (b <= 0)]
    resolved = (gap is None or moves[0] <= gap) and not flips
    why = []
    if gap is not None and moves[0] > gap:
        why.append(f"objective 1 moved by {moves[0]:.3g}, more than its margin {gap:.3g}")
    if flips:
        why.append("constraints changed side: " + ", ".join(
            f"{problem.constraints[i][0]}" for i in flips))
    return {"resolved": resolved, "why": "; ".join(why) or "within its margin",
            "coarse": list(winner.values), "fine": fine["values"], "moves": moves,
            "fine_constraints": fine["constraints"], "rows": fine["rows"]}


def _fmt(value, spec: str) -> str:
    """A metric for the report; n/a where the run did not give it."""
    return "n/a" if value is None else format(float(value), spec)


def write_report(path: Path, problem: Problem, study, winner, log, refinement, gap,
                 command: str) -> None:
    lines = ["# Design search report", "", f"Command: `{command}`", ""]
    n_done = len(finished_trials(study))
    lines += [f"Trials finished: {n_done} (this call: {log.trials_run}; scenario runs "
              f"simulated {log.runs_run}, reused {log.runs_reused}; interrupted trials "
              f"asked again: {log.requeued}); stopped: {log.stopped_by}.",
              f"Scenarios ({len(problem.scenarios)}): "
              + ", ".join(s.scenario_id for s in problem.scenarios) + ".", ""]
    if winner is None:
        lines += ["**No feasible design was found** (every complete trial breaks a "
                  "constraint, or none completed)."]
        Path(path).write_text("\n".join(lines) + "\n")
        return
    lines += ["## Winner", "", f"Trial {winner.number} (feasible: {feasible(winner)}):", ""]
    for v in problem.variables:
        lines.append(f"- `{v.path}` = {winner.params[v.path]:.6g}")
    for (m, a), val in zip(problem.objectives, winner.values):
        lines.append(f"- objective `{m}` ({a}) = {val:.4g}")
    for (m, a, lim), c in zip(problem.constraints, winner.user_attrs.get("constraints", [])):
        lines.append(f"- constraint `{m}` ({a}) <= {lim:g}: value {c + lim:.4g}, margin "
                     f"{-c:.4g}")
    name, val = worst_scenario(winner, problem)
    lines += ["", f"Worst scenario: **{name}** ({problem.objectives[0][0]} = {val:.4g}).",
              f"Margin to the next design in objective 1: "
              f"{'n/a' if gap is None else f'{gap:.3g}'}.", "",
              "## Per scenario (winner)", ""]
    if problem.reduced:
        lines += _reduced_rows(winner)
        lines += ["", "## DEM spot check", ""] + _spot_lines(refinement)
        Path(path).write_text("\n".join(lines) + "\n")
        return
    lines += ["| scenario | spin_left | peak force N | peak stress ratio | stiffness group "
              "N k (a/2)^2/(I w0^2) | L/a |", "|---|---|---|---|---|---|"]
    design = dict(winner.params)
    for row, s in zip(winner.user_attrs.get("scenarios", []), problem.scenarios):
        g = groups(problem.scene(design, s))
        lines.append(f"| {row['scenario']} | {_fmt(row.get('spin_left'), '.4g')} | "
                     f"{_fmt(row.get('peak_force'), '.4g')} | "
                     f"{_fmt(row.get('peak_stress_ratio'), '.3g')} | "
                     f"{g['stiffness_group']:.4g} | {g['length_ratio']:.3g} |")
    lines += ["", "## Refinement check", ""]
    if refinement is None:
        lines.append("Not run (--refine off).")
    else:
        lines.append(f"Re-run with {2 * problem.nodes - 1} nodes per bristle (search: "
                     f"{problem.nodes}) and half the time-step safety factor: "
                     f"**{'resolved' if refinement['resolved'] else 'UNRESOLVED'}** "
                     f"({refinement['why']}).")
        if refinement.get("fine"):
            for (m, a), c, f in zip(problem.objectives, refinement["coarse"],
                                    refinement["fine"]):
                lines.append(f"- `{m}` ({a}): search {c:.4g}, refined {f:.4g}")
    Path(path).write_text("\n".join(lines) + "\n")


def _reduced_rows(winner) -> list[str]:
    """The winner's hour-long detumbles (``--fidelity reduced``), a row per scenario."""
    lines = ["| scenario | spin left | detumbled at s | in contact s | peak force N | "
             "chaser dv m/s | propellant kg | wheel N m s | peak chaser torque N m | "
             "thrust sat. |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in winner.user_attrs.get("scenarios", []):
        rest = None if r.get("rest_time") is None else float(r["rest_time"])  # "inf" kept
        lines.append(
            f"| {r['scenario']} | {_fmt(r.get('spin_left'), '.3g')} | "
            f"{'not within the run' if rest is None or math.isinf(rest) else f'{rest:.0f}'}"
            f" | {_fmt(r.get('contact_duration'), '.0f')} | {_fmt(r.get('peak_force'), '.3g')}"
            f" | {_fmt(r.get('chaser_delta_v'), '.3g')} | "
            f"{_fmt(r.get('propellant_mass'), '.3g')} | {_fmt(r.get('wheel_momentum'), '.3g')}"
            f" | {_fmt(r.get('peak_chaser_torque'), '.3g')} | "
            f"{_fmt(r.get('thrust_saturation'), '.0%')} |")
    return lines


def _spot_lines(spot: Optional[dict]) -> list[str]:
    """The winner's DEM spot check (``--fidelity reduced``'s refinement) for the report."""
    if spot is None:
        return ["Not run (--no-refine or --spot-check-s 0)."]
    pct = lambda v: "n/a" if v is None else f"{100 * v:+.1f} %"  # noqa: E731
    lines = [f"The first {spot['spot_check_s']:g} s of each scenario with the DEM brush, "
             f"against the reduced run (relative error of the reduced run): "
             f"**{'resolved' if spot['resolved'] else 'UNRESOLVED'}** ({spot['why']}). "
             f"The law leaves the first touch out (docs/mission.md), so the errors after it "
             f"are the ones bounded.", "",
             "| scenario | first touch s | delta-omega, whole | peak force, whole | "
             "delta-omega, after touch | peak force, after touch |",
             "|---|---|---|---|---|---|"]
    for r in spot.get("rows", []):
        a = r.get("after_touch") or {}
        lines.append(f"| {r['scenario']} | {_fmt(r.get('first_contact'), '.2f')} | "
                     f"{pct(r['whole'].get('delta_omega'))} | "
                     f"{pct(r['whole'].get('peak_force'))} | {pct(a.get('delta_omega'))} | "
                     f"{pct(a.get('peak_force'))} |")
    return lines
