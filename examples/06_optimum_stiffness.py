"""06: the seed's question (thesis 4.3.4): is there a bristle stiffness at which a spinning
cube keeps no spin after its first collision with the brush, and which stiffness serves
several cube sizes best?

The spin-cube rig of ``study spin`` (the preset ``spin_cube_20``'s 17 x 5 silicone brush,
configuration 2: the brush at the axis level, its tips halfway between touching the face and
touching the edge, so that each corner sweeps through it; in configuration 1, the seed's
first, the tips touch the face and a stiff brush keeps the cube rocking in its well, with no
first collision that ends) at a cheap resolution (3 nodes per bristle), cubes of 20, 30 and
40 mm at 10 rad/s. For each cube size, the fraction of the spin left just after the first contact,
``spin_left`` (``studio.studies.optimise.metrics``), as a function of the bristle bending
stiffness S = E d^4 (varied through E, the geometry kept):

1. a scan of S on a log grid finds where ``spin_left`` changes sign (a soft brush lets the
   cube through still turning, a stiff one throws it back);
2. scipy's ``brentq`` brackets the zero crossing in log10 S: the optimum stiffness of that
   cube;
3. the design search (``study optimise`` through the study registry) looks for the robust
   choice over all the cubes (objective: the worst |spin_left| over them) and re-runs its
   winner finer (twice the nodes, half the time step) to say whether it is resolved.

Every simulation is a run file under the output folder; running the script again in the
same folder reuses them. Prints one line per cube, the robust choice, the refinement check and
the number of simulations it ran (``runs: N``).

    python examples/06_optimum_stiffness.py [OUT_DIR]
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

OUT = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output/06_optimum_stiffness")
CUBES_MM = (20.0, 30.0, 40.0)
S_GRID = np.logspace(-6, -3, 4)  # Pa m^4 (the seed's brush: 2.7 MPa x (2 mm)^4 = 4.3e-5)
CONFIG = 2           # the brush's tips halfway to the edge: each corner sweeps through it
NODES = 3
DURATION_S = 0.3     # the first contact of a 10 rad/s cube is over well before this
XTOL_DECADES = 0.03  # brentq's tolerance in log10 S: 7 % in S
SEARCH_TRIALS = 8


def main() -> None:
    from studio.studies.optimise import Options
    from studio.studies.optimise.executor import Executor
    from studio.studies.optimise.search import Problem
    from studio.studies.registry import get

    OUT.mkdir(parents=True, exist_ok=True)
    runs = {"n": 0}

    def make_spin_left(cube_mm: float):
        options = Options(preset="spin_cube_20", cubes_mm=[cube_mm], nodes=NODES,
                          duration_s=DURATION_S, workers=1, configs=[CONFIG],
                          variables=[f"bending_stiffness={S_GRID[0] / 10:g}:"
                                     f"{S_GRID[-1] * 10:g}:log"])
        problem = Problem.from_options(options)
        executor = Executor(OUT / "runs_1d", None, 1)

        def spin_left(S: float) -> float:
            executor.submit(problem.specs({"bending_stiffness": float(S)}))
            (_, outcomes), = executor.wait_any()
            o = outcomes[0]
            runs["n"] += 0 if o.get("skipped") else 1  # the bracket's ends come back cached
            if o["status"] not in ("completed", "stopped"):
                raise RuntimeError(f"run failed at S = {S:g}: {o.get('error')}")
            return float(o["summary"]["spin_left"])

        return spin_left

    roots = {}
    for cube in CUBES_MM:
        f = make_spin_left(cube)
        values = [f(S) for S in S_GRID]
        print(f"cube {cube:g} mm: spin_left at E d^4 = "
              + ", ".join(f"{S:.3g}: {v:+.3f}" for S, v in zip(S_GRID, values)))
        k = next((i for i in range(len(values) - 1) if values[i] * values[i + 1] <= 0), None)
        if k is None:
            print(f"cube {cube:g} mm: no sign change of spin_left over "
                  f"[{S_GRID[0]:.3g}, {S_GRID[-1]:.3g}] Pa m^4")
            continue
        u = brentq(lambda x: f(10 ** x), math.log10(S_GRID[k]), math.log10(S_GRID[k + 1]),
                   xtol=XTOL_DECADES)
        roots[cube] = 10 ** u
        E = roots[cube] / (2e-3) ** 4
        print(f"cube {cube:g} mm: optimum E d^4 = {roots[cube]:.3g} Pa m^4 "
              f"(E = {E / 1e6:.3g} MPa at the seed's 2 mm root), bracketed in "
              f"[{S_GRID[k]:.3g}, {S_GRID[k + 1]:.3g}]")
    if len(roots) >= 2:
        lo, hi = min(roots.values()) / 1.5, max(roots.values()) * 1.5
    else:
        lo, hi = S_GRID[0], S_GRID[-1]
    options = Options(preset="spin_cube_20", cubes_mm=list(CUBES_MM), nodes=NODES,
                      duration_s=DURATION_S, workers=1, no_progress=True, configs=[CONFIG],
                      variables=[f"bending_stiffness={lo:.4g}:{hi:.4g}:log"],
                      objectives=["abs_spin_left:worst"], trials=SEARCH_TRIALS, refine=True)
    result = get("optimise").run(options, OUT / "search")
    if not result.ok:
        raise SystemExit(f"the search ended with exit code {result.exit_code}")
    s = result.summary
    runs["n"] += s["runs_run"] + (len(CUBES_MM) if s["refinement"] else 0)
    w = s["winner"]
    print(f"robust choice over {', '.join(f'{c:g}' for c in CUBES_MM)} mm: E d^4 = "
          f"{w['design']['bending_stiffness']:.3g} Pa m^4, worst |spin_left| "
          f"{w['objectives'][0]:.3f} ({SEARCH_TRIALS} trials)")
    ref = s["refinement"]
    print(f"refinement ({2 * NODES - 1} nodes, half the time step): worst |spin_left| "
          f"{ref['fine'][0]:.3f}, {'resolved' if ref['resolved'] else 'UNRESOLVED'} "
          f"({ref['why']})")
    print(f"runs: {runs['n']}")


if __name__ == "__main__":
    main()
