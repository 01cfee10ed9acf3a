"""How much room the automatic timestep leaves: for each stability case
(``tests/engine/stability_cases.py``), the largest dt factor (a multiple of the automatic dt,
set through ``run.dt``) that still runs stably, found by bisection.

    python benchmarks/dt_margins.py              # the quick (reduced) cases
    python benchmarks/dt_margins.py --full       # the full-size cases (much longer)
    python benchmarks/dt_margins.py --only steel_bristles fine_bristles --tol 0.02

"Stable" means what the stability suite means: the run reaches its end with no
``InstabilityError`` and its result file passes ``stability_cases.judge`` (no NaN, no
bristle node inside or through a body). Each trial runs in a worker process under a
wall-clock bound. The search first doubles the factor from 1 until a run fails (or
``--max`` is reached), then bisects between the last stable and the first failing factor
until they are within ``--tol`` (relative). A case that already fails at factor 1 is
reported with its error and tried at smaller factors too, to tell whether the failure
depends on dt at all. Results are printed as a table (Markdown, as in docs/stability.md).
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "engine"))
if str(ROOT) not in sys.path:
    sys.path.append(str(ROOT))

import stability_cases as cases  # noqa: E402

DEFAULT_CASES = [n for n in cases.CASES if n != "crossing_bristles"]


def trial(runner, name: str, full: bool, factor: float, folder: Path, bound: float):
    """Run one case at ``factor`` x the automatic dt; returns (stable, why, outcome)."""
    sub = folder / f"{name}_{factor:.6g}"
    scene = cases.build_case(name, sub, full)
    outcome = runner.run(scene, sub, timeout=bound, dt_factor=factor)
    problems = cases.judge(outcome)
    if outcome.stable and not problems:
        why = ""
    elif outcome.status == "instability":
        e = outcome.instability
        why = f"{e['quantity']} at t = {e['time']:.3g} s"
    else:
        why = "; ".join(problems) or outcome.status
    if problems and outcome.stable:
        why = "; ".join(problems)
    shutil.rmtree(sub, ignore_errors=True)
    return outcome.stable and not problems, why, outcome


def margin(runner, name: str, full: bool, folder: Path, tol: float, max_factor: float,
           bound: float, log) -> dict:
    t0 = time.perf_counter()
    ok, why, out = trial(runner, name, full, 1.0, folder, bound)
    row = {"case": name, "auto_dt": out.answer.get("auto_dt"),
           "limited_by": out.answer.get("auto_limited_by", "").replace("brush 'brush' ", ""),
           "trials": 1}
    log(f"{name}: factor 1 -> {'stable' if ok else why}")
    if not ok:
        # does the failure depend on dt? try much smaller steps
        row.update(stable_at_1=False, failure=why)
        for f in (0.5, 0.25, 0.1):
            ok_small, why_small, _ = trial(runner, name, full, f, folder, bound)
            row["trials"] += 1
            log(f"{name}: factor {f:g} -> {'stable' if ok_small else why_small}")
            if ok_small:
                row["largest_stable"] = f
                break
        row["wall_s"] = time.perf_counter() - t0
        return row
    lo, hi, hi_why = 1.0, None, ""
    f = 2.0
    while f <= max_factor:
        ok, why, _ = trial(runner, name, full, f, folder, bound)
        row["trials"] += 1
        log(f"{name}: factor {f:g} -> {'stable' if ok else why}")
        if ok:
            lo = f
            f *= 2.0
        else:
            hi, hi_why = f, why
            break
    while hi is not None and (hi - lo) / lo > tol:
        f = 0.5 * (lo + hi)
        ok, why, _ = trial(runner, name, full, f, folder, bound)
        row["trials"] += 1
        log(f"{name}: factor {f:.4g} -> {'stable' if ok else why}")
        if ok:
            lo = f
        else:
            hi, hi_why = f, why
    row.update(stable_at_1=True, largest_stable=lo, first_unstable=hi, failure=hi_why,
               wall_s=time.perf_counter() - t0)
    return row


def table(rows: list[dict]) -> str:
    lines = ["| case | automatic dt [s] | limited by | largest stable factor "
             + "| first unstable factor: what failed |",
             "|---|---|---|---|---|"]
    for r in rows:
        dt = f"{r['auto_dt']:.3g}" if r.get("auto_dt") else "–"
        if r["stable_at_1"]:
            largest = f"{r['largest_stable']:.3g}"
            if r["first_unstable"] is None:
                first = "none up to the search's maximum"
            else:
                first = f"{r['first_unstable']:.3g}: {r['failure']}"
        else:
            largest = (f"{r['largest_stable']:g}" if r.get("largest_stable")
                       else "none down to 0.1")
            first = f"1: {r['failure']}"
        lines.append(f"| {r['case']} | {dt} | {r['limited_by']} | {largest} | {first} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="the full-size cases")
    ap.add_argument("--only", nargs="+", choices=list(cases.CASES), help="these cases only")
    ap.add_argument("--tol", type=float, default=0.05,
                    help="relative width at which bisection stops (default 0.05)")
    ap.add_argument("--max", type=float, default=64.0, dest="max_factor",
                    help="largest factor tried (default 64)")
    ap.add_argument("--bound", type=float, default=600.0,
                    help="wall-clock bound of one trial, s (default 600)")
    args = ap.parse_args(argv)
    names = args.only or DEFAULT_CASES
    from tqdm import tqdm
    rows = []
    with tempfile.TemporaryDirectory(prefix="dt-margins-") as tmp, cases.CaseRunner() as runner:
        bar = tqdm(names, desc="cases", unit="case")
        for name in bar:
            bar.set_postfix_str(name)
            rows.append(margin(runner, name, args.full, Path(tmp), args.tol, args.max_factor,
                               args.bound, log=tqdm.write))
    print()
    print(f"dt margins ({'full' if args.full else 'quick'} cases; factor = run.dt / automatic "
          f"dt, bisection to {args.tol:.0%}):")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
