"""The design search: Optuna's ask/tell loop over designs, every design run on every scenario
(one Dask task per run), its metrics aggregated into objectives and constraints.

- Sampler: TPE for one objective, NSGA-II for several (``--sampler``), both with Optuna's
  constraint handling (``Trial.set_constraint``: a trial's aggregated ``c_j = value -
  limit``, feasible when every ``c_j <= 0``), seeded (``--search-seed``).
- Storage: ``optuna.journal`` in the output folder (Optuna's JournalStorage on a file). A
  search stopped (Ctrl-C, a cancelled job) and started again in the same folder keeps every
  finished trial; a trial that was under way is asked again with the same design (its
  finished scenario runs are found in ``runs/`` and not run again) and the interrupted one is
  marked failed and not counted. Raising ``--trials`` extends a finished search. A folder
  holding a search of other scenarios or objectives is refused.
- Budget: ``--trials`` designs in all (finished ones counted), ``--cpu-budget-s`` CPU seconds
  of this call (the runs' CPU, measured in the tasks, plus this process's).
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from .errors import StudyInputError
from .metrics import (NEEDS_CHASER_MASS, RUN_KEYS, aggregate, parse_constraint,
                      parse_objective)
from .scenarios import Scenario, base_scene, scenario_scene, scenario_set
from .variables import Variable, parse_variable

STUDY_NAME = "optimise"
TASK = "studio.studies.optimise.metrics:run_metrics"
DEM_NODES = 3         # nodes per bristle of a DEM search run (--nodes)
DEM_DURATION = 0.4    # s: a DEM search run at most (--duration-s)
#: the options of each fidelity's scenario set: the other fidelity refuses them unless they
#: keep their defaults
FIDELITY_OPTIONS = {"dem": ("cubes_mm", "spin_rates", "configs", "tumbling", "density",
                            "material_draws", "chaser_mass_kg"),
                    "reduced": ("sizes", "spins_deg", "tilts_deg", "tumbles", "offsets_m",
                                "spot_check_s", "isp")}


@dataclass
class Problem:
    """Everything a search needs, parsed and checked from the options."""

    base: dict
    variables: list[Variable]
    scenarios: list[Scenario]
    objectives: list[tuple[str, str]]
    constraints: list[tuple[str, str, float]]
    nodes: int
    duration: float
    stiffness_via: str
    stress_limit: float
    target: str = "cube"
    full_run: bool = False
    chaser_mass: Optional[float] = None  # kg, of the chaser a fixed brush would be on
    task: str = TASK  # the run's task (tests give a synthetic one with a known optimum)
    #: "dem": the spin rig's short DEM runs; "reduced": hour-long detumbles with each
    #: design's fitted law (:mod:`.reduced`)
    fidelity: str = "dem"
    spot_check_s: float = 0.0       # reduced: the winner's DEM spot check, s
    protocol: Optional[dict] = None  # reduced: study reduce's options for the fits
    isp: Optional[float] = None     # reduced: the thrusters' specific impulse, s
    run_keys: tuple = RUN_KEYS      # what a trial keeps of each scenario run

    @property
    def reduced(self) -> bool:
        return self.fidelity == "reduced"

    @classmethod
    def from_options(cls, options) -> "Problem":
        base = base_scene(options.preset)
        variables = [parse_variable(v, base) for v in options.variables]
        if not variables:
            raise StudyInputError("variables: give at least one PATH=LOW:HIGH")
        names = [v.path for v in variables]
        if len(set(names)) != len(names):
            raise StudyInputError(f"variables: a path is given twice ({names})")
        if options.fidelity == "reduced":
            return cls._reduced(options, base, variables)
        _refuse_other_fidelity(options, "dem")
        objectives = [parse_objective(o) for o in options.objectives]
        if not objectives:
            raise StudyInputError("objectives: give at least one METRIC[:AGG]")
        constraints = [parse_constraint(c) for c in options.constraints]
        scenarios = scenario_set(options.cubes_mm, options.spin_rates, options.configs,
                                 tumbling=options.tumbling, density=options.density,
                                 material_draws=options.material_draws, seed=options.seed)
        used = {m for m, _ in objectives} | {m for m, _, _ in constraints}
        problem = cls(base, variables, scenarios, objectives, constraints,
                      options.nodes or DEM_NODES, options.duration_s or DEM_DURATION,
                      options.stiffness_via,
                      options.stress_limit_mpa * 1e6, full_run="rest_time" in used,
                      chaser_mass=options.chaser_mass_kg)
        _check_chaser(base, used, options.chaser_mass_kg)
        problem._check_corners()
        return problem

    @classmethod
    def _reduced(cls, options, base: dict, variables: list) -> "Problem":
        """``--fidelity reduced``: detumble scenarios of a detumble preset, the metrics of
        :mod:`.reduced`."""
        from .reduced import (DEFAULT_DURATION, METRICS, RUN_KEYS as KEYS, TASK as RTASK,
                              check_base, scenario_set as detumble_scenarios)

        check_base(base, options.preset)
        _refuse_other_fidelity(options, "reduced")
        objectives = [parse_objective(o, METRICS, "--fidelity reduced")
                      for o in options.objectives]
        if not objectives:
            raise StudyInputError("objectives: give at least one METRIC[:AGG]")
        constraints = [parse_constraint(c, METRICS, "--fidelity reduced")
                       for c in options.constraints]
        scenarios = detumble_scenarios(options.sizes, options.spins_deg, options.tilts_deg,
                                       options.tumbles, options.offsets_m)
        problem = cls(base, variables, scenarios, objectives, constraints, options.nodes,
                      options.duration_s or DEFAULT_DURATION, options.stiffness_via,
                      options.stress_limit_mpa * 1e6, target="target", full_run=True,
                      task=RTASK, fidelity="reduced",
                      spot_check_s=options.spot_check_s, isp=options.isp, run_keys=KEYS)
        problem._check_corners()
        return problem

    def _check_corners(self) -> None:
        # every design's scene must be valid: check the corners of the box now
        import engine

        for corner in (0, 1):
            design = {v.path: (v.low if corner == 0 else v.high) for v in self.variables}
            try:
                engine.parse_scene(self.scene(design, self.scenarios[0]))
            except engine.SceneError as exc:
                raise StudyInputError(
                    "a design at the bounds gives an invalid scene: "
                    + "; ".join(str(p) for p in exc.problems)) from None

    def setup_digest(self) -> str:
        """Hash of what makes trials comparable (not the budget): a resumed search must
        have the same."""
        setup = {"base": self.base, "variables": [v.__dict__ for v in self.variables],
                 "scenarios": [s.to_dict() for s in self.scenarios],
                 "objectives": self.objectives, "constraints": self.constraints,
                 "nodes": self.nodes, "duration": self.duration,
                 "via": self.stiffness_via, "stress": self.stress_limit}
        if self.chaser_mass is not None:  # only then: earlier searches keep their digest
            setup["chaser_mass"] = self.chaser_mass
        if self.reduced:
            setup.update(fidelity=self.fidelity, protocol=self.protocol)
        text = json.dumps(setup, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def scene(self, design: dict, scenario, *, refined: bool = False) -> dict:
        """The DEM scene of ``design`` x ``scenario`` (reduced: the detumble scene whose
        brush the task replaces by the design's law)."""
        if self.reduced:
            from .reduced import design_scene

            return design_scene(self.base, design, scenario, stiffness_via=self.stiffness_via,
                                duration=self.duration, nodes=self.nodes)
        nodes = 2 * self.nodes - 1 if refined else self.nodes
        dt_safety = 0.5 * float(self.base.get("run", {}).get("dt_safety", 0.5)) \
            if refined else None
        return scenario_scene(self.base, design, scenario, nodes=nodes,
                              duration=self.duration, stiffness_via=self.stiffness_via,
                              dt_safety=dt_safety)

    def specs(self, design: dict, *, refined: bool = False, prefix: Optional[str] = None):
        from ..runner import RunSpec

        key = prefix or design_key(design)
        if self.reduced:
            return self._reduced_specs(design, key, refined)
        params = {"target": self.target, "stress_limit": self.stress_limit,
                  "full_run": self.full_run}
        if self.chaser_mass is not None:
            params["chaser_mass"] = self.chaser_mass
        return [RunSpec(f"{key}{'_fine' if refined else ''}_{s.scenario_id}",
                        self.scene(design, s, refined=refined),
                        dict(params, scenario=s.scenario_id, design=design), self.task)
                for s in self.scenarios]

    def _reduced_specs(self, design: dict, key: str, spot: bool) -> list:
        """A reduced design's runs (each fits or reuses the law in ``laws/<key>/``), or
        with ``spot`` its DEM spot checks (the first ``spot_check_s`` s of each scenario)."""
        from ..runner import RunSpec
        from ..detumble import spot_scene
        from .reduced import SPOT_TASK

        specs = []
        for s in self.scenarios:
            scene = self.scene(design, s)
            params = {"scenario": s.scenario_id, "design": design}
            if spot:
                specs.append(RunSpec(f"{key}_spot_{s.scenario_id}",
                                     spot_scene(scene, self.spot_check_s),
                                     dict(params, threshold=0.05, fidelity="dem",
                                          stress_limit=self.stress_limit, isp=self.isp),
                                     SPOT_TASK))
            else:
                specs.append(RunSpec(f"{key}_{s.scenario_id}", scene,
                                     dict(params, law_key=key, protocol=self.protocol,
                                          isp=self.isp),
                                     self.task))
        return specs

    def evaluate(self, outcomes: list[dict]) -> dict:
        """Objective and constraint values of one design from its scenario outcomes:
        ``{"rows": [...], "values": [...], "constraints": [...], "failed": [...]}``."""
        rows, failed = [], []
        for s, o in zip(self.scenarios, outcomes):
            summary = o.get("summary") or {}
            if o.get("status") not in ("completed", "stopped"):
                failed.append(f"{s.scenario_id}: {o.get('error') or o.get('status')}")
            rows.append(dict(summary, scenario=s.scenario_id, status=o.get("status"),
                             error=o.get("error")))
        if failed:
            return {"rows": rows, "values": None, "constraints": None, "failed": failed}

        def agg(metric, how):
            return aggregate([r.get(metric, float("nan")) for r in rows], how)

        values = [agg(m, a) for m, a in self.objectives]
        cons = [agg(m, a) - limit for m, a, limit in self.constraints]
        return {"rows": rows, "values": values, "constraints": cons, "failed": []}


def _refuse_other_fidelity(options, fidelity: str) -> None:
    """The options of the other fidelity's scenario set, given here, are refused: they would
    be silently ignored."""
    other = "reduced" if fidelity == "dem" else "dem"
    fields = type(options).model_fields
    given = [name for name in FIDELITY_OPTIONS[other]
             if getattr(options, name) != fields[name].get_default(call_default_factory=True)]
    if given:
        flags = ", ".join("--" + n.replace("_", "-") for n in given)
        raise StudyInputError(f"{flags}: an option of --fidelity {other}'s scenarios, and "
                              f"this search is --fidelity {fidelity}")


def _check_chaser(base: dict, used: set, chaser_mass: Optional[float]) -> None:
    """A fixed brush has no chaser mass of its own: the metrics that need one need
    --chaser-mass-kg; a mounted brush's chaser has its own, so the option is refused."""
    mount = base["brushes"][0].get("mount")
    if mount is None:
        for metric in NEEDS_CHASER_MASS:
            if metric in used and chaser_mass is None:
                raise StudyInputError(
                    f"{metric}: the design's brush is fixed in the world (no mount), so there "
                    f"is no chaser mass to divide its load's impulse by: give "
                    f"--chaser-mass-kg (the chaser it would be on), or mount the brush on a "
                    f"body")
    elif chaser_mass is not None:
        raise StudyInputError(f"chaser_mass_kg: the brush is mounted on body {mount!r}, "
                              f"whose own mass counts; leave --chaser-mass-kg out")


def design_key(design: dict) -> str:
    """A short stable name of a design (it names the design's run files)."""
    text = json.dumps({k: float(v) for k, v in sorted(design.items())}, sort_keys=True)
    return "d" + hashlib.sha256(text.encode()).hexdigest()[:10]


def _sampler(kind: str, n_objectives: int, has_constraints: bool, seed: int):
    import optuna

    # the constraints reach the samplers through each trial's ``set_constraint`` (Optuna 5)
    if kind == "auto":
        kind = "tpe" if n_objectives == 1 else "nsga2"
    if kind == "tpe":
        return optuna.samplers.TPESampler(seed=seed, n_startup_trials=5, multivariate=True)
    if kind == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=seed, population_size=max(4, min(20, 2 * n_objectives
                                                                         + 6)))
    return optuna.samplers.RandomSampler(seed=seed)


def open_study(out_dir: Path, problem: Problem, sampler: str, seed: int):
    """The Optuna study of ``out_dir`` (created, or loaded to resume or extend)."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = JournalStorage(JournalFileBackend(str(Path(out_dir) / "optuna.journal")))
    study = optuna.create_study(
        storage=storage, study_name=STUDY_NAME, load_if_exists=True,
        directions=["minimize"] * len(problem.objectives),
        sampler=_sampler(sampler, len(problem.objectives), bool(problem.constraints), seed))
    n_old = len(study.get_trials(deepcopy=False))
    if n_old:
        # a resumed search: seeded afresh past its trials, or it would draw its first
        # (random start-up) designs again
        study.sampler = _sampler(sampler, len(problem.objectives), bool(problem.constraints),
                                 seed + 7919 * n_old)
    digest = problem.setup_digest()
    old = study.user_attrs.get("setup")
    if old is None:
        study.set_user_attr("setup", digest)
        study.set_user_attr("objectives", [f"{m}:{a}" for m, a in problem.objectives])
        study.set_user_attr("constraints", [f"{m}:{a}<={v:g}"
                                            for m, a, v in problem.constraints])
    elif old != digest:
        raise StudyInputError(
            f"{out_dir} holds a search of other designs, scenarios or objectives (only "
            f"--trials, --cpu-budget-s and the execution options may change on a resume); "
            f"use another output folder")
    return study


def counted(trial) -> bool:
    """A finished trial: told a result (complete, or failed runs), not one interrupted."""
    import optuna

    return trial.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL) \
        and not trial.user_attrs.get("interrupted", False)


def requeue_interrupted(study) -> int:
    """Trials left running by a stopped search: mark them interrupted (failed, not counted)
    and ask their designs again. Returns how many."""
    import optuna

    n = 0
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        study._storage.set_trial_user_attr(t._trial_id, "interrupted", True)
        study.tell(t.number, state=optuna.trial.TrialState.FAIL)
        if t.params:
            study.enqueue_trial(t.params, user_attrs={"requeued_from": t.number})
        n += 1
    return n


@dataclass
class SearchLog:
    trials_done: int = 0
    trials_run: int = 0       # told in this call
    runs_run: int = 0         # scenario runs simulated in this call
    runs_reused: int = 0
    run_cpu_s: float = 0.0    # CPU of the runs' tasks (this call)
    sim_cpu_s: float = 0.0    # ... of which engine build + run
    requeued: int = 0
    wall_s: float = 0.0
    stopped_by: str = ""
    best: list = field(default_factory=list)


def search(problem: Problem, out_dir: Path, *, trials: int, cpu_budget_s: Optional[float],
           sampler: str = "auto", seed: int = 0, scheduler=None, workers=None,
           on_trial=None, executor=None) -> tuple:
    """Run the search until ``trials`` are finished (or the CPU budget is spent). Returns
    ``(study, SearchLog)``. ``on_trial(log)`` after each told trial. ``executor``: an
    :class:`~.executor.Executor` the caller keeps (and closes) for later runs, such as the
    refinement; default: one started and closed here."""
    import optuna

    from .. import api
    from .executor import Executor

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    study = open_study(out_dir, problem, sampler, seed)
    log = SearchLog()
    log.requeued = requeue_interrupted(study)
    log.trials_done = sum(counted(t) for t in study.get_trials(deepcopy=False))
    t0, c0 = time.perf_counter(), time.process_time()

    def spent() -> float:
        return log.run_cpu_s + (time.process_time() - c0) * (0 if executor.local else 1)

    own = executor is None
    if own:
        executor = Executor(out_dir, scheduler, workers)
    in_flight: dict = {}
    try:
        while True:
            api.check_cancel()
            while (len(in_flight) < executor.parallel
                   and log.trials_done + len(in_flight) < trials
                   and (cpu_budget_s is None or spent() < cpu_budget_s)):
                trial = study.ask()
                design = {v.path: v.suggest(trial) for v in problem.variables}
                trial.set_user_attr("design_key", design_key(design))
                handle = executor.submit(problem.specs(design))
                in_flight[handle] = (trial, design)
                if executor.local:
                    break  # ran already: tell it before asking the next
            if not in_flight:
                if log.trials_done >= trials:
                    log.stopped_by = f"{trials} trials finished"
                else:
                    log.stopped_by = f"CPU budget {cpu_budget_s:g} s spent"
                break
            for handle, outcomes in executor.wait_any():
                trial, design = in_flight.pop(handle)
                _tell(study, trial, problem, outcomes, log)
                if on_trial is not None:
                    on_trial(log)
    finally:
        if own:
            executor.close()
        else:
            executor.cancel_pending()
        log.wall_s = time.perf_counter() - t0
    return study, log


def _tell(study, trial, problem: Problem, outcomes: list[dict], log: SearchLog) -> None:
    import optuna

    for o in outcomes:
        s = o.get("summary") or {}
        if o.get("skipped"):
            log.runs_reused += 1
        else:
            log.runs_run += 1
            log.run_cpu_s += float(s.get("task_cpu_s") or o.get("wall_s") or 0.0)
            log.sim_cpu_s += float(s.get("sim_cpu_s") or 0.0)
    ev = problem.evaluate(outcomes)
    keep = ("scenario", "status", "error") + tuple(problem.run_keys)
    trial.set_user_attr("scenarios", [{k: r.get(k) for k in keep} for r in ev["rows"]])
    if ev["failed"]:
        trial.set_user_attr("failed_runs", ev["failed"])
        study.tell(trial, state=optuna.trial.TrialState.FAIL)
    else:
        trial.set_user_attr("constraints", ev["constraints"])
        for (metric, how, limit), c in zip(problem.constraints, ev["constraints"]):
            trial.set_constraint(f"{metric}:{how}<={limit:g}",
                                 c if math.isfinite(c) else 1e300)
        values = [v if math.isfinite(v) else 1e300 for v in ev["values"]]
        study.tell(trial, values)
    log.trials_done += 1
    log.trials_run += 1
