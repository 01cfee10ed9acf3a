"""Running the levels (through the studies' runner, or one after another in this process),
measuring the quantity in each (:func:`tabulate`), and the whole study (:func:`run_convergence`)."""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Optional, Sequence

from engine.jsonable import jsonable_null as _json_null
from .quantities import ConvergenceError, Quantity, check_measurable, measure, parse_quantity
from .references import analytic_reference
from .ladder import Level, make_levels
from .table import ConvergenceTable, analyse
from .outputs import write_outputs
from .protocol_ladder import (curve_changes, measure_protocol_level, protocol_levels,
                              run_protocol_ladder)


def run_level(scene, h5_path: Path, params: dict) -> dict:
    """The Dask task of one level: build and run ``scene`` into ``h5_path``. Before the timed
    run a few steps of the same scene run into a temporary file, so that loading the compiled
    kernels (a fresh worker process) is not counted in the level's wall time."""
    import tempfile

    import engine

    if not isinstance(scene, engine.Scene):
        scene = engine.parse_scene(scene)
    if params.get("warm_up", True):
        warm = engine.build(scene)
        with tempfile.TemporaryDirectory() as tmp:
            engine.run(warm, until=min(scene.run.duration, 20 * warm.dt),
                       output=Path(tmp) / "warm_up.h5")
    try:
        from studio.studies.runner import report_progress
    except ImportError:  # pragma: no cover - the runner is part of this project
        def report_progress(fraction):
            return None
    system = engine.build(scene)
    t0 = time.perf_counter()
    try:
        result = engine.run(system, output=h5_path,
                            on_progress=lambda p: report_progress(p.fraction))
    except engine.InstabilityError as exc:
        summary = dict(exc.result.summary) if exc.result is not None else {}
        summary.update(status="failed", error=str(exc))
        return summary
    summary = dict(result.summary)
    summary["wall_total_s"] = time.perf_counter() - t0
    return summary


def _run_serial(specs, out_dir: Path, progress: bool) -> list[dict]:
    """Run the levels one after another in this process (no Dask): each writes
    out_dir/runs/<run_id>.h5 and, last, <run_id>.json, like the studies' runner; a finished
    level from an earlier attempt is reused."""
    from tqdm import tqdm

    import engine

    from studio.studies import api

    runs = out_dir / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    out = []
    session = api.current()
    for i, spec in enumerate(tqdm(specs, desc="levels", disable=not progress, unit="run")):
        session.report(i / len(specs), f"levels: {i}/{len(specs)} run", force=True)
        session.check()
        h5, meta = runs / f"{spec.run_id}.h5", runs / f"{spec.run_id}.json"
        if meta.exists():
            old = json.loads(meta.read_text())
            if old.get("status") in ("completed", "stopped") and h5.exists():
                out.append(dict(old, skipped=True))
                continue
        t0 = time.perf_counter()
        error = None
        try:
            summary = run_level(engine.parse_scene(spec.scene), h5, spec.params)
            status = summary.get("status", "failed")
            error = summary.get("error") if status == "failed" else None
        except Exception as exc:  # a level that fails is reported; the others go on
            summary, status, error = {}, "failed", f"{type(exc).__name__}: {exc}"
        record = {"run_id": spec.run_id, "params": spec.params, "status": status,
                  "summary": _json_null(summary), "error": error, "h5": str(h5),
                  "wall_s": time.perf_counter() - t0, "skipped": False}
        tmp = meta.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(record, indent=1))
        tmp.replace(meta)
        out.append(record)
    return out


def _run_dask(specs, out_dir: Path, scheduler, workers, progress) -> list[dict]:
    from studio.studies.runner import run_many

    outcomes = run_many(specs, out_dir, scheduler=scheduler, n_workers=workers,
                        progress=progress, desc="levels")
    return [{"run_id": o.run_id, "params": o.params, "status": o.status,
             "summary": o.summary or {}, "error": o.error, "h5": str(o.h5),
             "wall_s": o.wall_s, "skipped": o.skipped} for o in outcomes]


def run_ladder(scene, out_dir, *, n_nodes: Optional[Sequence[int]] = None,
               dt_factors: Optional[Sequence[float]] = None, serial: bool = False,
               scheduler: Optional[str] = None, workers: Optional[int] = None,
               progress: bool = True, warm_up: bool = True) -> tuple[list[Level], list[dict]]:
    """Run the ladder's levels (results under ``out_dir/runs``); returns the levels and one
    record per level (run_id, params, status, summary, error, h5, wall_s, skipped). Levels
    finished by an earlier call with the same scene are reused. Levels run through
    :func:`studio.studies.runner.run_many` (``scheduler``/``workers`` as there), or in this
    process one after another with ``serial=True``."""
    import engine

    if not isinstance(scene, engine.Scene):
        scene = engine.parse_scene(scene)
    levels = make_levels(json.loads(scene.to_json()), n_nodes, dt_factors)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if serial:
        from types import SimpleNamespace as RunSpec  # the same fields, no Dask needed
    else:
        from studio.studies.runner import RunSpec

    specs = [RunSpec(run_id=lv.run_id, scene=lv.scene,
                     params={"level": lv.level, "n_nodes": lv.n_nodes,
                             "dt_factor": lv.dt_factor, "warm_up": warm_up},
                     task="studio.studies.convergence:run_level") for lv in levels]
    records = _run_serial(specs, out_dir, progress) if serial else \
        _run_dask(specs, out_dir, scheduler, workers, progress)
    return levels, records


def tabulate(scene, quantity: Quantity | str, levels: Sequence[Level],
             records: Sequence[dict], reference: str = "auto") -> ConvergenceTable:
    """Measure ``quantity`` in each finished level of :func:`run_ladder` and analyse it."""
    import engine

    q = parse_quantity(quantity) if isinstance(quantity, str) else quantity
    if not isinstance(scene, engine.Scene):
        scene = engine.parse_scene(scene)
    if reference not in ("auto", "analytic", "richardson", "finest"):
        raise ConvergenceError(f"reference {reference!r}: auto, analytic, richardson or finest")
    values, walls, statuses, messages, dts, h5s = [], [], [], [], [], []
    for lv, rec in zip(levels, records):
        summary = rec.get("summary") or {}
        status = rec.get("status") or summary.get("status") or "failed"
        value, message = None, rec.get("error") or summary.get("error") or ""
        if status in ("completed", "stopped"):
            try:
                value = measure(rec["h5"], q) if lv.protocol is None else \
                    measure_protocol_level(rec["h5"], q)
            except ConvergenceError as exc:
                message = str(exc)
        values.append(value)
        wall = summary.get("wall_s")
        walls.append(float(wall) if isinstance(wall, (int, float)) else rec.get("wall_s"))
        statuses.append(status)
        messages.append(str(message) if message else "")
        dt = summary.get("dt", lv.dt)
        dts.append(dt if isinstance(dt, (int, float)) else None)
        h5s.append(rec["h5"])
    if all(v is None for v in values):
        detail = "; ".join(f"level {i}: {m or s}" for i, (s, m) in
                           enumerate(zip(statuses, messages)))
        raise ConvergenceError(f"no level gave a value of {q.text}: {detail}")
    return analyse(q, levels, values, walls, statuses, messages, dts,
                   analytic_reference(scene, q), reference, scene.name,
                   [lv.run_id for lv in levels], h5s)


def run_convergence(scene, quantity: Quantity | str, out_dir, *,
                    n_nodes: Optional[Sequence[int]] = None,
                    dt_factors: Optional[Sequence[float]] = None,
                    reference: str = "auto", serial: bool = False,
                    scheduler: Optional[str] = None, workers: Optional[int] = None,
                    progress: bool = True, warm_up: bool = True,
                    protocol: Optional[tuple[str, Sequence]] = None) -> ConvergenceTable:
    """Run a ladder (:func:`run_ladder`), measure and analyse ``quantity``
    (:func:`tabulate`) and write the outputs into ``out_dir``; returns the table.
    ``scene``: an ``engine.Scene``, a dict or JSON text. ``protocol``: a loading ladder
    ``(name, values)`` instead (:mod:`.protocol_ladder`), with the table's ``curve_changes``."""
    import engine

    q = parse_quantity(quantity) if isinstance(quantity, str) else quantity
    if not isinstance(scene, engine.Scene):
        scene = engine.parse_scene(scene)
    if reference not in ("auto", "analytic", "richardson", "finest"):
        raise ConvergenceError(f"reference {reference!r}: auto, analytic, richardson or finest")
    check_measurable(scene, q)
    if protocol is not None:
        if n_nodes or dt_factors:
            raise ConvergenceError(f"a {protocol[0]} ladder changes the loading only: leave "
                                   "out --dt-factor (and give one --ladder)")
        levels = protocol_levels(json.loads(scene.to_json()), q, *protocol)
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        records = run_protocol_ladder(levels, out_dir, serial=serial, scheduler=scheduler,
                                      workers=workers, progress=progress)
        table = tabulate(scene, q, levels, records, "finest" if reference == "auto"
                         else reference)
        table.curve_changes = curve_changes(levels, records)
        write_outputs(table, out_dir, scene_json=scene.to_json())
        return table
    levels, records = run_ladder(scene, out_dir, n_nodes=n_nodes, dt_factors=dt_factors,
                                 serial=serial, scheduler=scheduler, workers=workers,
                                 progress=progress, warm_up=warm_up)
    table = tabulate(scene, q, levels, records, reference)
    write_outputs(table, out_dir, scene_json=scene.to_json())
    return table
