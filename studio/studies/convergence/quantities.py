"""The quantities of interest: their grammar (``tip_deflection:B``, ``wedge_force@10mm``) and
their measurement in a level's result file."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Optional

import numpy as np

from engine.model.layout import quat_to_matrix
from engine.analysis.spectrum import peak_frequencies, uniform_part

CSV_COLUMNS = ("level", "n_nodes", "dt", "quantity", "error", "wall_s")
TOLERANCES = (0.01, 0.05)
FORMAT = "brush-studio-convergence"

QUANTITY_HELP = """\
quantities (SI units; measured from each level's result file):
  tip_deflection[:B]          displacement of bristle B's tip (default 0) perpendicular to its
                              initial root-to-tip axis at the last frame, m (a static load:
                              let the run settle, e.g. with environment.local_damping)
  spectral_peak[:K]           frequency of the K-th spectral peak (default 1) of bristle 0's
                              tip trajectory after the last load-profile time, Hz
  spectral_peak:K:B           the same for bristle B
  wedge_force@DEPTH[:BODY]    force the bristles push back on a body driven by a
                              stepped_parabolic profile, against its motion, averaged over the
                              last quarter of the rest (dwell) at DEPTH on the way in, N;
                              DEPTH in m, or with a unit: 10mm (default BODY: the first body
                              with a stepped_parabolic profile)
  body_omega_after_first_contact[:BODY]
                              angular velocity of a hinge body about its axis (signed; a free
                              body: its magnitude) at the first frame after its first contact
                              ended (the first gap of 40 ms and two frames without contact
                              force; grazes that change its speed by < 2 % do not count),
                              rad/s (default BODY: the first hinge or free body)
  peak_plate_force[:BODY]     largest force on a body over the recorded frames: its contact
                              force plus the reaction of the roots of brushes mounted on it
                              (or, for a fixed body, with their fixed base within 1 mm of
                              it), N (default BODY: 'plate', else the first fixed body)
references: analytic for the single-bristle rod cases (tip_deflection: elastica of a tapered
cantilever under a tip load and its own weight; spectral_peak: Euler-Bernoulli modes of a
uniform rod), otherwise the Richardson extrapolation of the three finest levels, or the
finest level when those do not converge monotonically (--reference overrides)."""


class ConvergenceError(ValueError):
    """A bad quantity, ladder or scene for a convergence study (exit code 2)."""


# ============================================================================ quantities
@dataclass(frozen=True)
class Quantity:
    """A parsed quantity of interest: ``kind`` plus its optional arguments."""

    text: str
    kind: str
    index: int = 0                  # bristle index (tip_deflection, spectral_peak)
    peak: int = 1                   # spectral_peak: which peak, 1 = lowest
    depth: Optional[float] = None   # wedge_force, m
    body: Optional[str] = None

    @property
    def unit(self) -> str:
        return {"tip_deflection": "m", "spectral_peak": "Hz", "wedge_force": "N",
                "body_omega_after_first_contact": "rad/s", "peak_plate_force": "N"}[self.kind]


KINDS = ("tip_deflection", "spectral_peak", "wedge_force", "body_omega_after_first_contact",
         "peak_plate_force")


def _parse_length(text: str) -> float:
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*(mm|cm|m)?\s*", text)
    if not m:
        raise ConvergenceError(f"depth {text!r}: a number in m, or with a unit (10mm)")
    try:
        value = float(m.group(1))
    except ValueError:
        raise ConvergenceError(f"depth {text!r}: a number in m, or with a unit (10mm)") from None
    value *= {"mm": 1e-3, "cm": 1e-2, "m": 1.0, None: 1.0}[m.group(2)]
    if not (math.isfinite(value) and value > 0):
        raise ConvergenceError(f"depth {text!r}: must be > 0")
    return value


def _parse_int(text: str, what: str, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise ConvergenceError(f"{what} {text!r}: an integer >= {minimum}") from None
    if value < minimum:
        raise ConvergenceError(f"{what} {text!r}: an integer >= {minimum}")
    return value


def parse_quantity(text: str) -> Quantity:
    """``"wedge_force@10mm:wedge"`` -> Quantity(kind="wedge_force", depth=0.01, body="wedge").
    Raises ConvergenceError naming what is wrong and what is allowed."""
    text = text.strip()
    head, _, rest = text.partition(":")
    args = rest.split(":") if rest else []
    if head.startswith("wedge_force@") or head == "wedge_force":
        if "@" not in head:
            raise ConvergenceError("wedge_force needs a depth: wedge_force@DEPTH[:BODY], "
                                   "e.g. wedge_force@10mm")
        if len(args) > 1:
            raise ConvergenceError(f"{text!r}: wedge_force@DEPTH[:BODY]")
        return Quantity(text, "wedge_force", depth=_parse_length(head.split("@", 1)[1]),
                        body=args[0] if args else None)
    if head == "tip_deflection":
        if len(args) > 1:
            raise ConvergenceError(f"{text!r}: tip_deflection[:BRISTLE]")
        return Quantity(text, head, index=_parse_int(args[0], "bristle", 0) if args else 0)
    if head == "spectral_peak":
        if len(args) > 2:
            raise ConvergenceError(f"{text!r}: spectral_peak[:K[:BRISTLE]]")
        peak = _parse_int(args[0], "peak number", 1) if args else 1
        index = _parse_int(args[1], "bristle", 0) if len(args) > 1 else 0
        return Quantity(text, head, index=index, peak=peak)
    if head in ("body_omega_after_first_contact", "peak_plate_force"):
        if len(args) > 1:
            raise ConvergenceError(f"{text!r}: {head}[:BODY]")
        return Quantity(text, head, body=args[0] if args else None)
    raise ConvergenceError(f"unknown quantity {text!r}; allowed: tip_deflection[:B], "
                           "spectral_peak[:K[:B]], wedge_force@DEPTH[:BODY], "
                           "body_omega_after_first_contact[:BODY], peak_plate_force[:BODY]")


def _bristle_tip(res, index: int) -> tuple[np.ndarray, np.ndarray]:
    """(time, tip positions (F, 3)) and the root position at frame 0 of bristle ``index``."""
    if "nodes/positions" not in res.channels():
        raise ConvergenceError("the scene does not record node positions: add \"nodes\" to "
                               "run.channels")
    first = np.asarray(res.static("bristles/first_node"))
    if not 0 <= index < len(first) - 1:
        raise ConvergenceError(f"bristle {index}: the scene has {len(first) - 1} bristle(s)")
    root, tip = int(first[index]), int(first[index + 1]) - 1
    tip_xyz = np.asarray(res.series("nodes/positions")[:, tip, :])
    root0 = np.asarray(res.frame("nodes/positions", 0)[root])
    return tip_xyz, root0


def _transverse(tip: np.ndarray, root0: np.ndarray) -> np.ndarray:
    """Tip displacement from frame 0 with the component along the initial root-to-tip axis
    removed, (F, 3)."""
    axis = tip[0] - root0
    axis = axis / np.linalg.norm(axis)
    d = tip - tip[0]
    return d - np.outer(d @ axis, axis)


def spectral_peaks(time: np.ndarray, signal: np.ndarray, n_peaks: int) -> np.ndarray:
    """Frequencies (Hz, ascending) of the ``n_peaks`` largest spectral peaks of a uniformly
    sampled signal, by the shared estimator :func:`engine.analysis.spectrum.peak_frequencies`
    (Blackman-Harris PSD, side lobes refused, parabolic refinement); ConvergenceError when
    the record is too short, not sampled uniformly, or has fewer peaks."""
    time = np.asarray(time, float)
    signal = np.asarray(signal, float)
    if len(time) < 16:
        raise ConvergenceError(f"only {len(time)} frames to take a spectrum of: record more "
                               "often (run.record_interval) or longer")
    # the run records its last frame at the end time, usually off the regular grid: that
    # one is dropped; a record off the grid earlier is not a free vibration to analyse
    if len(uniform_part(time)[0]) < 0.99 * len(time) - 1:
        raise ConvergenceError("the tip trajectory is not sampled uniformly")
    try:
        return peak_frequencies(time, signal, n_peaks)
    except ValueError as exc:
        raise ConvergenceError(str(exc)) from None


def _free_after(scene) -> float:
    """The last time any load's amplitude changes (its last profile time), or 0."""
    t = 0.0
    for load in scene.loads:
        if load.profile.frequency > 0:
            return math.inf
        t = max(t, max(load.profile.times))
    return t


def _stepped_body(scene, name: Optional[str]):
    for body in scene.bodies:
        if name is not None and body.name != name:
            continue
        if body.motion.type == "kinematic" and body.motion.profile.kind == "stepped_parabolic":
            return body
        if name is not None:
            raise ConvergenceError(f"body {name!r} has no stepped_parabolic kinematic profile")
    if name is not None:
        raise ConvergenceError(f"no body named {name!r}; bodies: "
                               f"{[b.name for b in scene.bodies]}")
    raise ConvergenceError("wedge_force needs a body driven by a stepped_parabolic profile")


def _body_channel(res, body: str, what: str) -> np.ndarray:
    name = f"bodies/{body}/{what}"
    if name not in res.channels():
        raise ConvergenceError(f"the result has no {name}: add \"bodies\" to run.channels")
    return np.asarray(res.series(name))


def _wedge_force(res, q: Quantity) -> float:
    scene = res.scene
    body = _stepped_body(scene, q.body)
    prof = body.motion.profile
    direction = np.asarray(prof.direction, float)
    direction /= np.linalg.norm(direction)
    pos = _body_channel(res, body.name, "position")
    force = _body_channel(res, body.name, "contact_force")
    depth = (pos - pos[0]) @ direction
    at = np.abs(depth - q.depth) <= 1e-3 * prof.step
    if not at.any():
        rests = sorted({round(float(d) / prof.step) * prof.step for d in depth
                        if abs(d / prof.step - round(d / prof.step)) < 1e-3})
        raise ConvergenceError(
            f"body {body.name!r} never rests at depth {q.depth:g} m; depths reached at rest: "
            f"{', '.join(f'{d:g}' for d in rests) or 'none'} m (the depth must be a multiple "
            f"of the step, {prof.step:g} m, within n_steps)")
    first = int(np.argmax(at))
    last = first
    while last + 1 < len(at) and at[last + 1]:
        last += 1
    n = last - first + 1
    window = slice(last + 1 - max(1, n // 4), last + 1)
    return float(np.mean(-(force[window] @ direction)))


def _spinning_body(scene, name: Optional[str]):
    for body in scene.bodies:
        if name is not None and body.name != name:
            continue
        if body.motion.type in ("hinge", "free") or name is not None:
            return body
    if name is not None:
        raise ConvergenceError(f"no body named {name!r}; bodies: "
                               f"{[b.name for b in scene.bodies]}")
    raise ConvergenceError("body_omega_after_first_contact needs a hinge or free body")


# a contact ends at the first gap of at least this long (and at least two frames) without a
# contact force or torque on the body: a corner sweeping through a brush loses touch for a few
# milliseconds between rows of bristles, which is still the same contact
CONTACT_GAP_S = 0.04
# a contact episode that changes the body's angular speed by less than this fraction is a
# graze (a bristle tip brushing a corner), not the first contact
GRAZE_CHANGE = 0.02


def contact_episodes(time: np.ndarray, touching: np.ndarray,
                     gap: float = CONTACT_GAP_S) -> list[tuple[int, int]]:
    """Contact episodes as (first frame in contact, first frame after it): runs of frames in
    contact, merged across gaps shorter than ``gap`` seconds or than two frames (measured from
    the last frame in contact to the next one in contact). An episode still going on at the
    end of the run has ``None`` as its end."""
    touching = np.asarray(touching, bool)
    n = len(touching)
    out = []
    i = 0
    while i < n:
        if not touching[i]:
            i += 1
            continue
        start = i
        end = None
        while i < n:
            if touching[i]:
                i += 1
                continue
            j = i
            while j < n and not touching[j]:
                j += 1
            gap_end = time[j] if j < n else time[-1]
            if j - i >= 2 and gap_end - time[i - 1] >= gap:
                end = i
                break
            i = j
        out.append((start, end))
        if end is None:
            break
        i = end
    return out


def first_contact_end(time: np.ndarray, touching: np.ndarray, gap: float = CONTACT_GAP_S,
                      speed: Optional[np.ndarray] = None,
                      min_change: float = GRAZE_CHANGE) -> Optional[int]:
    """Index of the first frame after the first contact episode (:func:`contact_episodes`);
    None if there is none or it does not end. With ``speed`` (the body's angular speed per
    frame), episodes across which it changes by less than ``min_change`` of its value before
    the episode (grazes) are skipped."""
    for start, end in contact_episodes(time, touching, gap):
        if end is None:
            return None
        if speed is not None:
            before = abs(float(speed[max(start - 1, 0)]))
            if abs(float(speed[end]) - float(speed[max(start - 1, 0)])) < min_change * before:
                continue
        return end
    return None


def _omega_after_first_contact(res, q: Quantity) -> float:
    scene = res.scene
    body = _spinning_body(scene, q.body)
    force = np.linalg.norm(_body_channel(res, body.name, "contact_force"), axis=1)
    torque = np.linalg.norm(_body_channel(res, body.name, "contact_torque"), axis=1)
    omega = _body_channel(res, body.name, "angular_velocity")
    touching = (force > 0) | (torque > 0)
    if not touching.any():
        raise ConvergenceError(f"body {body.name!r} never touches anything")
    if body.motion.type == "hinge":
        axis = np.asarray(body.motion.axis, float)
        value = omega @ (axis / np.linalg.norm(axis))
    else:
        value = np.linalg.norm(omega, axis=1)
    i = first_contact_end(np.asarray(res.time), touching, speed=value)
    if i is None:
        raise ConvergenceError(f"the first contact of body {body.name!r} does not end (no "
                               f"gap of {CONTACT_GAP_S * 1e3:g} ms without contact after a "
                               f"contact that changed its angular speed by "
                               f"{GRAZE_CHANGE:.0%} or more) before the run does: run longer")
    return float(value[i])


# a world-fixed brush whose base lies within this distance of a fixed body's bounding box is
# rooted on that body: its root reaction is part of the force on it
ROOTED_WITHIN = 1e-3


def _peak_plate_force(res, q: Quantity) -> float:
    scene = res.scene
    names = [b.name for b in scene.bodies]
    name = q.body
    if name is None:
        name = "plate" if "plate" in names else next(
            (b.name for b in scene.bodies if b.motion.type == "fixed"), None)
    if name is None or name not in names:
        raise ConvergenceError(f"peak_plate_force: no body {q.body or 'plate'!r} (and no "
                               f"fixed body); bodies: {names}")
    total = _body_channel(res, name, "contact_force").copy()
    body = next(b for b in scene.bodies if b.name == name)
    lo = hi = None
    if body.motion.type == "fixed" and f"bodies/{name}/vertices" in res.statics():
        # a fixed plate's world box, to find world-fixed brushes rooted on it
        verts = np.asarray(res.static(f"bodies/{name}/vertices"))
        pos = np.asarray(res.frame(f"bodies/{name}/position", 0))
        q = res.frame(f"bodies/{name}/orientation", 0)
        rot = quat_to_matrix(q / np.linalg.norm(q))
        world = verts @ rot.T + pos
        lo, hi = world.min(axis=0) - ROOTED_WITHIN, world.max(axis=0) + ROOTED_WITHIN
    for brush in scene.brushes:
        base = np.asarray(brush.base.position, float)
        rooted = brush.mount is None and lo is not None and \
            bool(np.all(base >= lo) and np.all(base <= hi))
        if brush.mount == name or rooted:
            channel = f"brushes/{brush.name}/root_force"
            if channel not in res.channels():
                raise ConvergenceError(f"the result has no {channel}: add \"root_force\" to "
                                       "run.channels")
            total -= np.asarray(res.series(channel))  # the roots push the plate back
    return float(np.max(np.linalg.norm(total, axis=1)))


def measure(result_path, quantity: Quantity | str) -> float:
    """The quantity of interest measured from one result file."""
    import engine

    q = parse_quantity(quantity) if isinstance(quantity, str) else quantity
    with engine.open_result(result_path) as res:
        if res.n_frames < 2:
            raise ConvergenceError(f"{result_path}: only {res.n_frames} frame(s) recorded")
        if q.kind == "tip_deflection":
            tip, root0 = _bristle_tip(res, q.index)
            return float(np.linalg.norm(_transverse(tip, root0)[-1]))
        if q.kind == "spectral_peak":
            tip, root0 = _bristle_tip(res, q.index)
            t = np.asarray(res.time)
            d = _transverse(tip, root0)
            free = t > _free_after(res.scene) + 1e-12
            if free.sum() < 16:
                raise ConvergenceError("fewer than 16 frames after the loads end: nothing "
                                       "to take a spectrum of")
            d, t = d[free], t[free]
            # the transverse direction the tip moves most along (principal axis)
            _, _, vt = np.linalg.svd(d - d.mean(axis=0), full_matrices=False)
            return float(spectral_peaks(t, d @ vt[0], q.peak)[q.peak - 1])
        if q.kind == "wedge_force":
            return _wedge_force(res, q)
        if q.kind == "body_omega_after_first_contact":
            return _omega_after_first_contact(res, q)
        return _peak_plate_force(res, q)


def check_measurable(scene, quantity: Quantity) -> None:
    """Refuse, before anything runs, a quantity the scene cannot give a meaningful value of.

    ``tip_deflection`` is read at the last frame, so it means something only where the run
    ends in a static state: a scene without any damping (no ``environment.local_damping``,
    no material ``bond_damping``) ends in a free vibration, whose last frame is a random
    point of the swing (a ladder of those looks like a convergence failure); an oscillating
    load never lets it settle either. ``spectral_peak`` needs a free vibration after the last
    load; ``wedge_force`` a body with a stepped profile reaching the depth;
    ``body_omega_after_first_contact`` a hinge or free body."""
    name = scene.name
    if quantity.kind == "spectral_peak":
        free_from = _free_after(scene)
        if free_from >= scene.run.duration:
            raise ConvergenceError(
                f"spectral_peak needs a free vibration after the loads end: in {name!r} they "
                f"{'oscillate to the end' if math.isinf(free_from) else f'last until {free_from:g} s'}"
                f" and the run ends at {scene.run.duration:g} s")
        return
    if quantity.kind == "wedge_force":
        prof = _stepped_body(scene, quantity.body).motion.profile
        deepest = prof.n_steps * prof.step
        if quantity.depth > deepest * (1 + 1e-9):
            raise ConvergenceError(
                f"wedge_force@{quantity.depth:g}: the body goes down to {deepest:g} m only "
                f"({prof.n_steps} steps of {prof.step:g} m)")
        return
    if quantity.kind == "body_omega_after_first_contact":
        _spinning_body(scene, quantity.body)
        return
    if quantity.kind != "tip_deflection":
        return
    damped = scene.environment.local_damping > 0 or any(
        scene.materials[b.material].bond_damping > 0 for b in scene.brushes)
    if not damped:
        raise ConvergenceError(
            f"tip_deflection needs a static scene: it is read at the last frame, and "
            f"{name!r} has no damping (environment.local_damping = 0, bond_damping = 0), so "
            f"its last frame is a point of a free vibration. Add damping "
            f"(environment.local_damping, e.g. 0.7) so that the rod settles, use a static "
            f"scene (the preset rod_weight_static), or measure the vibration with "
            f"spectral_peak")
    for load in scene.loads:
        if load.profile.frequency > 0:
            raise ConvergenceError(
                f"tip_deflection needs a static scene: {name!r} has a load oscillating at "
                f"{load.profile.frequency:g} Hz, so its tip never settles; measure a static "
                f"load, or the vibration with spectral_peak")
