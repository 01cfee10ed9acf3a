"""Changing a kinematic body's prescribed motion between runs of a system.

Quasi-static protocols decide their next move from the state they reach: the wedge test
(seed 4.2) holds after each 1 mm step until the root force is steady, then takes the next
step. ``prescribe_motion`` replaces a kinematic body's profile from the current simulated time
on, starting from the pose the body is at, so such a protocol is a loop of
``prescribe_motion`` and ``run`` calls on one system.
"""
from __future__ import annotations

from typing import Optional, Union

import numpy as np
from pydantic import TypeAdapter, ValidationError

from engine.kernels.bodies import KINEMATIC, kinematic_state
from engine.assembly.system import System
from engine.assembly.bodies import kinematic_segments
from engine.errors import SceneError
from engine.model.spec import _problems_from
from engine.model.spec_bodies import Profile

_PROFILE = TypeAdapter(Profile)


def prescribe_motion(system: System, body: str, profile: Union[dict, object],
                     after: Optional[str] = None) -> None:
    """From ``system.time`` on, move kinematic ``body`` along ``profile``.

    ``profile`` is a dict (or model) of one of the scene's kinematic profile kinds
    (``constant``, ``stepped_parabolic``, ``waypoints``) with its times counted from now; it
    starts from the body's current pose (a ``waypoints`` profile must start there too). A
    ``constant`` profile without a duration lasts to the scene's ``run.duration``.
    ``after`` (``"hold"`` or ``"free"``) replaces what the body does when the profile ends;
    None keeps the scene's choice. Raises :class:`SceneError` for an unknown body, a body that
    is not (or no longer) kinematic, or an invalid profile. The change is listed in the
    ``prescribed_motions`` attribute of the result files written afterwards.
    """
    try:
        prof = _PROFILE.validate_python(profile if isinstance(profile, dict)
                                        else profile.model_dump())
    except ValidationError as err:
        problems = _problems_from(err)
        for p in problems:
            p.field = f"profile.{p.field}" if p.field else "profile"
        raise SceneError(problems) from None
    if body not in system.body_names:
        raise SceneError.single("body", body, f"one of {system.body_names}")
    k = system.body_names.index(body)
    bd = system.bodies
    if bd.motion[k] != KINEMATIC:
        raise SceneError.single("body", body, "a kinematic body (this one is not, or its "
                                              "profile ended and it was released as free)")
    if after is not None and after not in ("hold", "free"):
        raise SceneError.single("after", after, '"hold" or "free"')
    now = system.time
    horizon = max(system.scene.run.duration - now, 0.0)
    if prof.kind == "constant" and prof.duration is None and horizon <= 0.0:
        raise SceneError.single("profile.duration", None,
                                "a duration: the scene's run.duration has passed")
    geo = system.body_geometry[k]
    segs = kinematic_segments(prof, bd.pos[k].copy(), bd.q[k].copy(),
                              np.asarray(system.body_frame_offset[k], float),
                              np.asarray(geo.com_in_shape, float), horizon)
    if not segs:
        raise SceneError.single("profile", prof.kind, "a profile that produces motion")
    if prof.kind == "waypoints":
        first = segs[0][2]
        gap = float(np.linalg.norm(np.asarray(first) - bd.pos[k]))
        if gap > 1e-9:
            raise SceneError.single("profile.positions[0]", list(prof.positions[0]),
                                    f"the body's current pose (it is {gap:.3g} m away: a "
                                    f"jump would hit the bristles at infinite speed)")
    rows = []
    new_start = [0]
    for j in range(len(system.body_names)):
        if j == k:
            for s in segs:
                rows.append((s[0] + now, s[1] + now) + tuple(np.asarray(x, float)
                                                             for x in s[2:]))
        else:
            for c in range(int(bd.seg_start[j]), int(bd.seg_start[j + 1])):
                rows.append((bd.t0[c], bd.t1[c], bd.p0[c], bd.p1[c], bd.v0[c], bd.v1[c],
                             bd.wseg[c], bd.q0[c]))
        new_start.append(len(rows))
    cols = list(zip(*rows))
    seg_start = np.asarray(new_start, np.int64)
    cursor = bd.cursor.copy()
    for j in range(len(system.body_names)):  # cursors index rows: re-base them
        if j != k:
            cursor[j] = cursor[j] - bd.seg_start[j] + seg_start[j]
    cursor[k] = seg_start[k]
    system.bodies = bd._replace(
        seg_start=seg_start, t0=np.asarray(cols[0], float), t1=np.asarray(cols[1], float),
        p0=np.asarray(cols[2], float), p1=np.asarray(cols[3], float),
        v0=np.asarray(cols[4], float), v1=np.asarray(cols[5], float),
        wseg=np.asarray(cols[6], float), q0=np.asarray(cols[7], float), cursor=cursor)
    bd = system.bodies
    if after is not None:
        bd.after_free[k] = after == "free"
    kinematic_state(k, now, bd.seg_start, bd.t0, bd.t1, bd.p0, bd.p1, bd.v0, bd.v1, bd.wseg,
                    bd.q0, bd.cursor, bd.pos, bd.v, bd.q, bd.w)
    system.prescribed_motions.append({"time": now, "body": body,
                                      "profile": prof.model_dump(mode="json"),
                                      "after": after})
