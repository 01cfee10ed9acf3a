"""Build, reduced brushes: the bodies' ``patches`` (engine.model.spec_bodies.Patch) turned into the
``Patches`` bundle of ``engine.kernels.patch``, their time-step stiffness and their run
summary (docs/scene.md, "Reduced brushes")."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.model import reduced_law
from engine.errors import SceneError
from engine.kernels import patch as P
from engine.kernels.bodies import FIXED, FREE, HINGE
from engine.model.layout import quat_to_matrix
from engine.state import Patches

GRID_SHORT = 4        # default sample points along the patch's shorter side
GRID_MAX = 64         # ... and at most along the longer one


def default_grid(a: float, b: float) -> tuple[int, int]:
    """About square cells, ``GRID_SHORT`` along the shorter side."""
    if a <= b:
        return GRID_SHORT, min(GRID_MAX, max(GRID_SHORT, round(GRID_SHORT * b / a)))
    return min(GRID_MAX, max(GRID_SHORT, round(GRID_SHORT * a / b))), GRID_SHORT


def _law(patch, field: str) -> dict:
    try:
        if isinstance(patch.law, dict):
            return reduced_law.check_law(dict(patch.law))
        return reduced_law.load_law(Path(patch.law))
    except (OSError, ValueError) as exc:
        raise SceneError.single(f"{field}.law", patch.law if isinstance(patch.law, str)
                                else "(inline law)", f"not a usable reduced law: {exc}") \
            from None


def grid_points(a: float, b: float, nx: int, ny: int) -> np.ndarray:
    """Cell centres of an nx x ny grid over the a x b rectangle centred on the origin
    (z = 0)."""
    x = ((np.arange(nx) + 0.5) / nx - 0.5) * a
    y = ((np.arange(ny) + 0.5) / ny - 0.5) * b
    X, Y = np.meshgrid(x, y, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)


def build_patches(scene, bodies, names: list[str]) -> tuple[Patches, list[dict]]:
    """The bundle (one dummy point without patches) and per patch its description (body,
    name, law file, size, grid, area ratio) for the summary and the time step."""
    K = len(names)
    rows, pts, weights, pairs, starts, info = [], [], [], [], [0], []
    for k, body in enumerate(scene.bodies):
        for j, patch in enumerate(body.patches):
            fld = f"bodies.{k}.patches.{j}"
            law = _law(patch, fld)
            par = law["parameters"]
            a_law, b_law = (float(v) for v in law["patch"]["size"])
            a, b = patch.size if patch.size is not None else (a_law, b_law)
            nx, ny = patch.grid if patch.grid is not None else default_grid(a, b)
            local = grid_points(a, b, nx, ny)
            # the patch frame -> the body's pose frame -> world at the build pose -> body
            R_pose = quat_to_matrix(np.asarray(body.pose.orientation, float))
            R_patch = quat_to_matrix(np.asarray(patch.pose.orientation, float))
            world = (np.asarray(body.pose.position, float)
                     + (np.asarray(patch.pose.position, float) + local @ R_patch.T) @ R_pose.T)
            Rb = quat_to_matrix(bodies.q[k])
            in_body = (world - bodies.pos[k]) @ Rb
            centre = in_body.mean(axis=0)
            radius = float(np.linalg.norm(in_body - centre, axis=1).max())
            rng = law["ranges"]
            d_hi = float(rng["interference"][1])
            # how deep a point is looked for: three times the fitted range, at least half the
            # shorter side (a point deeper than this is not seen: the summary's out-of-range
            # count says when the run came near)
            reach = max(3.0 * d_hi, 0.5 * min(a, b))
            row = np.zeros(P.N_PAR)
            row[[P.P_K, P.P_P, P.P_C, P.P_ETA, P.P_MU, P.P_Q, P.P_VS]] = [
                float(par[n]) for n in reduced_law.PARAMS]
            row[P.P_RT] = reduced_law.torsion_radius(a, b)
            row[P.P_D_HI] = d_hi
            row[P.P_DD_LO], row[P.P_DD_HI] = (float(v) for v in rng["rate"])
            row[P.P_V_HI] = float(rng["slip_speed"][1])
            row[P.P_REACH] = reach
            row[P.P_RADIUS] = radius
            row[P.P_CX:P.P_CZ + 1] = centre
            rows.append(row)
            pts.append(in_body)
            area_ratio = a * b / (a_law * b_law)
            weights.append(np.full(len(local), area_ratio / len(local)))
            starts.append(starts[-1] + len(local))
            pair = np.zeros(K, np.bool_)
            for t, other in enumerate(scene.bodies):
                if t == k or not bodies.collide[t] or not bodies.watertight[t] \
                        or bodies.sphere_r[t] > 0:
                    continue
                if other.name in body.no_contact_with or body.name in other.no_contact_with:
                    continue
                if bodies.motion[k] == FIXED and bodies.motion[t] == FIXED:
                    continue  # (a kinematic press against a fixed plate records its force)
                pair[t] = True
            pairs.append(pair)
            info.append({"body": names[k], "name": patch.name,
                         "law": patch.law if isinstance(patch.law, str) else "(inline)",
                         "size": [float(a), float(b)], "grid": [int(nx), int(ny)],
                         "area_ratio": float(area_ratio), "k": float(par["k"]),
                         "p": float(par["p"]), "c": float(par["c"]), "mu": float(par["mu"]),
                         "q": float(par["q"]), "v_s": float(par["v_s"]),
                         "d_max": d_hi, "ranges": rng, "body_index": k,
                         "lever": float(np.linalg.norm(in_body, axis=1).max()),
                         "touches": [names[t] for t in range(K) if pair[t]]})
    # working rows: a patch's points against every body it may touch
    n_pts = max([1] + [len(x) * max(1, int(pr.sum())) for x, pr in zip(pts, pairs)])
    bundle = Patches(
        body=np.array([i["body_index"] for i in info], np.int64),
        par=np.array(rows, float).reshape(len(rows), P.N_PAR),
        state=np.zeros((len(rows), P.N_STATE)),
        pair=np.array(pairs, np.bool_).reshape(len(rows), K),
        start=np.asarray(starts, np.int64),
        pts=np.concatenate(pts) if pts else np.zeros((1, 3)),
        w=np.concatenate(weights) if weights else np.zeros(1),
        hits=np.zeros((n_pts, P.HIT)), scratch=np.zeros(3))
    return bundle, info


def patch_stiffness(info: dict) -> float:
    """The patch's normal stiffness dF/dd (N/m) at the fitted range's largest interference
    (times its area ratio): what the automatic time step must be stable with."""
    d = max(info["d_max"], 1e-9)
    return info["area_ratio"] * info["k"] * info["p"] * d ** (info["p"] - 1.0)


def patch_damping(info: dict) -> float:
    """The largest viscous slope of the patch's forces (N s/m) at the fitted range's largest
    interference: the rate term ``c k d^p`` and the friction's ``mu_eff F_n / v_s`` near
    zero slip (its tanh), F_n the force there. An explicit step needs dt < 2 m / slope."""
    d = max(info["d_max"], 1e-9)
    fn = info["area_ratio"] * info["k"] * d ** info["p"]
    mu_eff = info["mu"] * max(fn, 1e-12) ** info["q"]
    return info["c"] * fn + mu_eff * fn / info["v_s"]


def timestep_entries(info: list[dict], bodies, names: list[str]) -> list[tuple]:
    """``engine.assembly.timestep``'s body entries (name, mass, smallest moment, stiffness, lever) for
    the patches' stiffness on both bodies of each pair, and their damping as an equivalent
    stiffness (m (c/m)^2, the frequency at which an explicit step's damping limit 2 m / c
    equals leapfrog's 2 / omega)."""
    out = []
    for pi in info:
        k_s = pi["body_index"]
        touched = [names.index(n) for n in pi["touches"]]
        kn = patch_stiffness(pi)
        cd = patch_damping(pi)
        for k in [k_s] + touched:
            if bodies.motion[k] not in (FREE, HINGE) and not bodies.after_free[k]:
                continue
            m = float(bodies.mass[k])
            imin = float(bodies.Ip[k].min())
            # lever: the farthest patch point from the body's centre (the carrier), or the
            # touched body's bounding radius
            lever = (float(bodies.bound_r[k]) if k != k_s
                     else max(float(bodies.bound_r[k]), pi["lever"]))
            k_eq = kn + (cd * cd / m if m > 0 else 0.0)
            out.append((f"{names[k]} via patch {pi['name']}", m, imin, k_eq, lever))
    return out


def summary(system) -> list[dict]:
    """Per patch: what the run did with it and how much of it lay outside the law's fitted
    ranges (engine.kernels.patch's state)."""
    out = []
    for p, pi in enumerate(system.patch_info):
        st = system.patches.state[p]
        steps = int(st[P.S_STEPS])
        out.append({"body": pi["body"], "name": pi["name"], "law": pi["law"],
                    "steps_in_contact": steps,
                    "steps_out_of_range": {"interference": int(st[P.S_OUT_D]),
                                           "rate": int(st[P.S_OUT_DD]),
                                           "slip_speed": int(st[P.S_OUT_V])},
                    "largest": {"interference": float(st[P.S_MAX_D]),
                                "rate": float(st[P.S_MAX_DD]),
                                "slip_speed": float(st[P.S_MAX_V])},
                    "fitted_ranges": pi["ranges"],
                    "dissipated": float(st[P.S_DISS])})
    return out


def out_of_range_warnings(rows: list[dict]) -> list[str]:
    """A warning per patch used outside its law's fitted ranges."""
    warn = []
    for r in rows:
        bad = {k: v for k, v in r["steps_out_of_range"].items() if v}
        if bad:
            parts = ", ".join(
                f"{k} in {v} of {r['steps_in_contact']} steps (largest {r['largest'][k]:.3g}, "
                f"fitted up to {_hi(r['fitted_ranges'], k):.3g})" for k, v in bad.items())
            warn.append(f"patch {r['name']!r} of body {r['body']!r} was used outside its "
                        f"law's fitted ranges: {parts}")
    return warn


def _hi(ranges: dict, key: str) -> float:
    rng = ranges[{"interference": "interference", "rate": "rate",
                  "slip_speed": "slip_speed"}[key]]
    return max(abs(float(rng[0])), abs(float(rng[1]))) if key == "rate" else float(rng[1])
