"""Why a run failed: the step loop's failure codes turned into errors that name the quantity,
the element, the time and the change to make."""
from __future__ import annotations

from typing import Optional

from engine.assembly.system import System
from engine.errors import InstabilityError
from engine.state import (FAIL_BODY_SPEED, FAIL_NODE_SPEED, FAIL_NONFINITE_BODY, FAIL_NONFINITE_NODE,
                    FAIL_OVERLAP_BB, FAIL_OVERLAP_BODY, FAIL_OVERLAP_BODYBODY, LIMIT_OVERLAP)


def dt_cause(system: System) -> Optional[str]:
    """When the scene's own ``run.dt`` exceeds the stability limit the build found
    (``system.dt_stable``), any blow-up is the timestep's: the advice that says so (and
    nothing else, which would send the user after tip randomness or contact stiffness)."""
    given, bound = system.scene.run.dt, system.dt_stable
    if given is None or not given > bound:
        return None
    return (f"The cause is the timestep: run.dt = {given:.3g} s is {given / bound:.3g} x the "
            f"stability limit {bound:.3g} s of this scene; remove run.dt (automatic dt = "
            f"{system.scene.run.dt_safety:g} x the limit) or set it below {bound:.3g} s.")


def instability(system: System, code: int) -> InstabilityError:
    """The error for the step loop's failure ``code``: what failed, where, when and what to
    change (the timestep first when the scene's own dt is above the stability limit)."""
    exc = _instability_by_code(system, code)
    cause = dt_cause(system)
    if cause is None:
        return exc
    return InstabilityError(exc.quantity, exc.where, exc.time, cause, detail=exc.detail)


def _instability_by_code(system: System, code: int) -> InstabilityError:
    e = system.err
    t = system.time
    sc = system.scene
    lower_dt = (f"lower run.dt_safety (now {sc.run.dt_safety:g}) or set a smaller run.dt "
                f"(now {system.dt:.3g} s)")
    if code == FAIL_NONFINITE_NODE:
        return InstabilityError("non-finite node position or velocity",
                                system.node_label(int(e[0])), t,
                                f"The integration diverged: {lower_dt}, and check for "
                                f"extreme material values.")
    if code == FAIL_NODE_SPEED:
        return InstabilityError("node displacement per step", system.node_label(int(e[0])), t,
                                f"It moves {e[1]:.3g} m in one step, more than half its "
                                f"radius: the run is blowing up or the motion is too fast for "
                                f"the timestep; {lower_dt}.",
                                detail=f"{e[1]:.3g} m > {e[2]:.3g} m")
    at_start = system.steps <= system.flags.check_every
    start_note = ("The overlap is there from the first steps: the scene starts with these "
                  "elements overlapping (bristles that cross because of tip randomness, or "
                  "roots resting on a body: lift the brush base by the root radius). ")
    soft_note = ("If a smaller dt stops at the same time, the linear contact (k_n = 2 E1 r1 "
                 "E2 r2 / (E1 r1 + E2 r2), seed eq. 3.6) cannot hold this load within half a "
                 "radius whatever the step: ")
    if code == FAIL_OVERLAP_BB:
        if at_start:
            return InstabilityError("bristle-bristle contact overlap",
                                    f"{system.segment_label(int(e[0]))} and "
                                    f"{system.segment_label(int(e[2]))}", t,
                                    start_note + "Reduce brushes[].tip_variance or increase "
                                    "the pitch.", detail=f"overlap ratio {e[1]:.3g}")
        return InstabilityError("bristle-bristle contact overlap",
                                f"{system.segment_label(int(e[0]))} and "
                                f"{system.segment_label(int(e[2]))}", t,
                                f"The capsules overlap by {e[1]:.2f} of the smaller radius "
                                f"(limit {system.limits[LIMIT_OVERLAP]:g}): the contact is too soft for the "
                                f"load or the step too large; {lower_dt}. {soft_note}load the "
                                f"brush more gently or use stiffer or thicker bristles.",
                                detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_OVERLAP_BODY and at_start:
        return InstabilityError("bristle-body contact overlap",
                                f"{system.segment_label(int(e[0]))} against body "
                                f"{system.body_names[int(e[2])]!r}", t,
                                start_note + "Move the body or the brush base apart.",
                                detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_OVERLAP_BODY:
        return InstabilityError("bristle-body contact overlap",
                                f"{system.segment_label(int(e[0]))} against body "
                                f"{system.body_names[int(e[2])]!r}", t,
                                f"The capsule penetrates the body by {e[1]:.2f} of its radius "
                                f"(limit {system.limits[LIMIT_OVERLAP]:g}): the body pushes harder or "
                                f"faster than the contact can resist at this step; "
                                f"{lower_dt}. {soft_note}slow the body down, or use stiffer "
                                f"or thicker bristles.",
                                detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_OVERLAP_BODYBODY:
        return InstabilityError("body-body contact overlap (overlap / sphere radius, or a "
                                "mesh vertex's depth / its vertex length)", "two bodies", t,
                                f"{lower_dt}.", detail=f"overlap ratio {e[1]:.3g}")
    if code == FAIL_BODY_SPEED:
        return InstabilityError("body displacement per step",
                                f"body {system.body_names[int(e[0])]!r}", t,
                                f"Its surface moves {e[1]:.3g} m per step, more than a quarter "
                                f"of the smallest bristle radius ({e[2]:.3g} m): it could pass "
                                f"through bristles; set a smaller run.dt.",
                                detail=f"{e[1]:.3g} m > {e[2]:.3g} m")
    if code == FAIL_NONFINITE_BODY:
        return InstabilityError("non-finite body state", f"body "
                                f"{system.body_names[int(e[0])]!r}", t, f"{lower_dt}.")
    return InstabilityError(f"unknown failure code {code}", "?", t, lower_dt)
