"""``brush-studio convergence``: error against run time for a ladder of resolutions.

    brush-studio convergence SCENE.json --quantity tip_deflection \\
        --ladder n_nodes=3,5,9,17,33 [--dt-factor 1,0.5,0.25] -o DIR

Each *level* of the ladder is the scene with every brush at ``n_nodes`` nodes per bristle and
(with ``--dt-factor``) ``run.dt`` = factor x the automatic time step of that level. The levels
run as independent simulations through the studies' Dask layer
(:func:`studio.studies.runner.run_many`), or one after another in this process with
``--serial`` (undisturbed wall times). From each level's result file the quantity of interest
is measured, and compared with a reference:

* **analytic** where one exists: the single-bristle rod cases (tip deflection against the
  elastica of a tapered, self-weighted cantilever, which is ``P L^3 / 3 E I`` for small
  loads; bending frequencies of a uniform rod against Euler-Bernoulli);
* otherwise the **Richardson extrapolation** of the three finest levels (with the observed
  order of convergence), or the **finest level** itself when the three finest levels do not
  converge monotonically.

Outputs in DIR: ``convergence.csv`` (``level,n_nodes,dt,quantity,error,wall_s``; ``error`` is
the relative error ``(q - reference) / |reference|``, ``wall_s`` the run's own wall time),
``convergence.h5`` (group ``/convergence``), ``convergence.json`` (everything, for
:func:`load_convergence`), ``convergence.png`` (log-log |error| against wall time) and the
runs themselves under ``DIR/runs/``. Running again into the same DIR reuses finished runs, so
another ``--quantity`` of the same ladder costs only the measurement.
"""
from __future__ import annotations

import csv
import hashlib
import json
import math
import re
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from ..jsonable import jsonable as _to_json
from ..exit_codes import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_FAILED, EXIT_OK


def _json_null(value):
    return _to_json(value, nonfinite="null")


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


def _quat_matrix(q) -> np.ndarray:
    w, x, y, z = (float(c) for c in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


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


def spectral_peaks(time: np.ndarray, signal: np.ndarray, n_peaks: int,
                   padding: int = 16) -> np.ndarray:
    """Frequencies (Hz, ascending) of the ``n_peaks`` largest peaks of the amplitude spectrum
    of a uniformly sampled signal: Hann window, zero padding to ``padding`` x the length, peaks
    at least 3 unpadded bins apart (which drops the window's side lobes: each lies within 3
    bins of a larger lobe), then a parabola through the log-magnitude at the peak bin and its
    two neighbours."""
    from scipy.signal import find_peaks

    time = np.asarray(time, float)
    signal = np.asarray(signal, float)
    if len(time) < 16:
        raise ConvergenceError(f"only {len(time)} frames to take a spectrum of: record more "
                               "often (run.record_interval) or longer")
    steps = np.diff(time)
    dt = float(np.median(steps))
    # the run records its last frame at the end time, usually off the regular grid: drop it
    off_grid = np.flatnonzero(np.abs(steps - dt) > 1e-6 * dt)
    n_uniform = int(off_grid[0]) + 1 if off_grid.size else len(time)
    if n_uniform < 0.99 * len(time) - 1:
        raise ConvergenceError("the tip trajectory is not sampled uniformly")
    signal = signal[:n_uniform]
    x = (signal - signal.mean()) * np.hanning(len(signal))
    n_fft = 1 << int(math.ceil(math.log2(padding * len(signal))))
    mag = np.abs(np.fft.rfft(x, n_fft))
    freq = np.fft.rfftfreq(n_fft, dt)
    idx, _ = find_peaks(mag, distance=3 * n_fft // len(signal))
    idx = idx[(idx > 0) & (idx < len(mag) - 1)]
    if len(idx) < n_peaks:
        raise ConvergenceError(f"the spectrum has {len(idx)} peak(s), {n_peaks} needed")
    idx = np.sort(idx[np.argsort(mag[idx])[::-1][:n_peaks]])
    out = []
    for i in idx:
        a, b, c = np.log(np.maximum(mag[i - 1:i + 2], 1e-300))
        den = a - 2.0 * b + c
        shift = 0.5 * (a - c) / den if den != 0 else 0.0
        out.append(freq[i] + shift * (freq[1] - freq[0]))
    return np.array(out)


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
        rot = _quat_matrix(res.frame(f"bodies/{name}/orientation", 0))
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


# ============================================================================ references
def cantilever_beta_l(n_modes: int = 3) -> np.ndarray:
    """Roots beta_n L of the clamped-free frequency equation cos(bL) cosh(bL) = -1."""
    from scipy.optimize import brentq

    roots = []
    for n in range(1, n_modes + 1):
        centre = (n - 0.5) * math.pi
        roots.append(brentq(lambda b: math.cos(b) * math.cosh(b) + 1.0,
                            centre - 1.3 if n == 1 else centre - 0.35, centre + 0.35,
                            xtol=1e-14))
    return np.array(roots)


def cantilever_frequency(mode: int, length: float, youngs_modulus: float, radius: float,
                         density: float) -> float:
    """Euler-Bernoulli bending frequency (Hz) of mode ``mode`` (1-based) of a uniform
    cantilever of circular section: (beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4))."""
    bl = cantilever_beta_l(mode)[mode - 1]
    second_moment = math.pi * radius ** 4 / 4.0
    area = math.pi * radius ** 2
    return bl ** 2 / (2.0 * math.pi) * math.sqrt(
        youngs_modulus * second_moment / (density * area * length ** 4))


def tapered_elastica_tip(length: float, youngs_modulus: float, root_radius: float,
                         tip_radius: float, tip_force: float, weight_density: float = 0.0,
                         tol: float = 1e-10) -> tuple[float, float]:
    """Large deflection of an inextensible, unshearable cantilever of circular section whose
    radius tapers linearly from ``root_radius`` to ``tip_radius``, clamped with its axis
    horizontal, under a dead vertical tip force ``tip_force`` (N) and its own weight
    (``weight_density`` = rho g, N/m^3, along the same direction).

    With u = s / L in [0, 1], theta the slope (measured towards the load) and m = M L / (E I0)
    the bending moment in units of E I0 / L (I0 the root's second moment), the shear force
    V(u) = P + rho g L int_u^1 A du' carried by the section gives

        theta' = m I0 / I(u),   m' = -(L^2 / E I0) V(u) cos(theta),
        x' = cos(theta),  y' = sin(theta);  theta(0) = x(0) = y(0) = 0,  m(1) = 0,

    solved with scipy ``solve_bvp`` from the linear solution, with continuation in the load.
    Returns ``(x_tip / L, y_tip / L)``: the tip's position along the clamp axis and its
    deflection along the load, relative to L."""
    from scipy.integrate import solve_bvp

    r0, r1 = root_radius, tip_radius
    i0 = math.pi * r0 ** 4 / 4.0
    scale = length ** 2 / (youngs_modulus * i0)

    def radius(u):
        return r0 + (r1 - r0) * u

    def shear(u, load):
        ru = radius(u)
        # int_u^1 pi r^2 du' for a linear taper, exactly: pi (1 - u)(r1^2 + r1 ru + ru^2) / 3
        weight = weight_density * length * math.pi * (1.0 - u) * (r1 ** 2 + r1 * ru + ru ** 2) / 3
        return load * (tip_force + weight)

    def stiffness_ratio(u):
        return (r0 / radius(u)) ** 4  # I0 / I(u)

    u = np.linspace(0.0, 1.0, 401)
    total = scale * (abs(tip_force) + abs(weight_density) * length * math.pi * r0 ** 2)
    steps = max(1, int(math.ceil(total / 1.5)))
    guess = None
    sol = None
    for load in np.linspace(1.0 / steps, 1.0, steps):
        if guess is None:
            # linear beam: m(u) = scale int_u^1 V(u') (u' - u) du' ~ scale V(0) (1 - u)^2/2 ...
            # a rough, consistent start (continuation makes it exact)
            m = scale * shear(0.0, load) * (1.0 - u) ** 2 / 2.0
            th = np.cumsum(m * stiffness_ratio(u)) * (u[1] - u[0])
            guess = np.vstack([th, m, u.copy(), np.cumsum(np.sin(th)) * (u[1] - u[0])])

        def rhs(s, y, load=load):
            return np.vstack([y[1] * stiffness_ratio(s), -scale * shear(s, load) * np.cos(y[0]),
                              np.cos(y[0]), np.sin(y[0])])

        def bc(ya, yb):
            return np.array([ya[0], yb[1], ya[2], ya[3]])

        sol = solve_bvp(rhs, bc, u, guess, tol=tol, max_nodes=200_000)
        if not sol.success:
            raise RuntimeError(f"elastica BVP did not converge at load {load:g}: {sol.message}")
        u, guess = sol.x, sol.y
    return float(sol.y[2, -1]), float(sol.y[3, -1])


@dataclass
class Reference:
    value: float
    kind: str          # "analytic" | "richardson" | "finest" | "given"
    note: str


def _amplitude(profile, t: float) -> float:
    return float(np.interp(t, profile.times, profile.values))


def analytic_reference(scene, quantity: Quantity) -> Optional[Reference]:
    """The analytic reference of ``quantity`` for ``scene``, or None where there is none.

    Rod cases only: one brush of one straight bristle (no tip variance, fixed base), no
    bodies. tip_deflection: loads on the tip only, constant in the end (no oscillation), and
    those loads plus gravity all along one direction perpendicular to the bristle
    (the elastica of :func:`tapered_elastica_tip`). spectral_peak: a uniform rod (equal root and
    tip radius; Euler-Bernoulli modes, which ignore the rod's static sag under gravity and
    any damping)."""
    if quantity.kind not in ("tip_deflection", "spectral_peak") or quantity.index != 0:
        return None
    if len(scene.brushes) != 1 or scene.bodies:
        return None
    brush = scene.brushes[0]
    if brush.rows * brush.columns != 1 or brush.tip_variance != 0 or brush.mount is not None:
        return None
    material = scene.materials[brush.material]
    E, rho = material.youngs_modulus, material.density
    L = brush.bristle_length
    if quantity.kind == "spectral_peak":
        if abs(brush.root_radius - brush.tip_radius) > 1e-12 * brush.root_radius:
            return None
        f = cantilever_frequency(quantity.peak, L, E, brush.root_radius, rho)
        return Reference(f, "analytic", f"Euler-Bernoulli cantilever mode {quantity.peak}: "
                         f"(beta_n L)^2 / (2 pi) sqrt(E I / (rho A L^4)) = {f:.6g} Hz")
    axis = _quat_matrix(brush.base.orientation) @ np.array([0.0, 0.0, 1.0])
    total = np.zeros(3)
    for load in scene.loads:
        if load.node not in (-1, brush.n_nodes - 1) or load.profile.frequency > 0:
            return None
        total += np.asarray(load.force, float) * _amplitude(load.profile, scene.run.duration)
    gravity = np.asarray(scene.environment.gravity, float)
    vectors = [v for v in (total, gravity) if np.linalg.norm(v) > 0]
    if not vectors:
        return None
    direction = vectors[0] / np.linalg.norm(vectors[0])
    for v in vectors:
        n = np.linalg.norm(v)
        if np.linalg.norm(np.cross(v / n, direction)) > 1e-9 or abs(v @ axis) > 1e-9 * n:
            return None
    _, y = tapered_elastica_tip(L, E, brush.root_radius, brush.tip_radius,
                                float(total @ direction), rho * float(gravity @ direction))
    what = "tip load" + (" and own weight" if np.linalg.norm(gravity) > 0 else "")
    shape = "uniform" if brush.root_radius == brush.tip_radius else "tapered"
    return Reference(y * L, "analytic", f"elastica of the {shape} cantilever under its "
                     f"{what} (scipy solve_bvp): {y * L:.6g} m")


# ============================================================================ order, Richardson
def observed_orders(h: Sequence[float], errors: Sequence[float]) -> list[float]:
    """Order between successive levels, log(e_i / e_{i+1}) / log(h_i / h_{i+1}) (NaN where an
    error is zero or the resolutions are equal)."""
    out = []
    for i in range(len(h) - 1):
        e0, e1 = abs(errors[i]), abs(errors[i + 1])
        if e0 > 0 and e1 > 0 and h[i] != h[i + 1]:
            out.append(math.log(e0 / e1) / math.log(h[i] / h[i + 1]))
        else:
            out.append(math.nan)
    return out


def fitted_order(h: Sequence[float], errors: Sequence[float]) -> float:
    """Least-squares slope of log|error| against log h (NaN with fewer than two usable
    levels)."""
    pts = [(math.log(a), math.log(abs(e))) for a, e in zip(h, errors) if e != 0 and a > 0]
    if len(pts) < 2 or len({p[0] for p in pts}) < 2:
        return math.nan
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def richardson(h: Sequence[float], q: Sequence[float]) -> tuple[float, float]:
    """Richardson extrapolation from the last three levels (h decreasing): the observed order
    p solving (q1 - q2) / (q2 - q3) = (h1^p - h2^p) / (h2^p - h3^p) (any refinement ratios),
    and the extrapolated value q3 + (q3 - q2) / ((h2 / h3)^p - 1).

    Returns (estimate, p); (NaN, NaN) when the three do not converge monotonically (the
    differences change sign or do not shrink) or p falls outside (0.1, 12)."""
    from scipy.optimize import brentq

    if len(q) < 3:
        return math.nan, math.nan
    h1, h2, h3 = (float(v) for v in h[-3:])
    q1, q2, q3 = (float(v) for v in q[-3:])
    d12, d23 = q1 - q2, q2 - q3
    if not (h1 > h2 > h3 > 0) or d23 == 0 or d12 == 0 or d12 * d23 < 0:
        return math.nan, math.nan
    ratio = d12 / d23

    def f(p):
        return (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - ratio

    lo, hi = 0.1, 12.0
    if f(lo) * f(hi) > 0:
        return math.nan, math.nan
    p = brentq(f, lo, hi, xtol=1e-12)
    return q3 + (q3 - q2) / ((h2 / h3) ** p - 1.0), p


# ============================================================================ ladder
@dataclass
class Level:
    level: int
    n_nodes: Optional[int]
    dt_factor: Optional[float]
    dt: Optional[float]
    run_id: str
    scene: dict


def parse_ladder(text: str) -> list[int]:
    """``"n_nodes=3,5,9"`` -> [3, 5, 9]."""
    key, sep, values = text.partition("=")
    if key.strip() != "n_nodes" or not sep:
        raise ConvergenceError(f"--ladder {text!r}: expected n_nodes=N1,N2,... (the only "
                               "ladder parameter is n_nodes)")
    out = [_parse_int(v.strip(), "n_nodes", 2) for v in values.split(",") if v.strip()]
    if not out:
        raise ConvergenceError(f"--ladder {text!r}: no values")
    if any(b <= a for a, b in zip(out, out[1:])):
        raise ConvergenceError(f"--ladder {text!r}: n_nodes must increase from level to level")
    if max(out) > 4096:
        raise ConvergenceError(f"--ladder {text!r}: n_nodes at most 4096")
    return out


def parse_factors(text: str) -> list[float]:
    """``"1,0.5,0.25"`` -> [1.0, 0.5, 0.25] (each in (0, 1], decreasing)."""
    out = []
    for v in text.split(","):
        try:
            f = float(v)
        except ValueError:
            raise ConvergenceError(f"--dt-factor {text!r}: numbers in (0, 1]") from None
        if not (math.isfinite(f) and 0 < f <= 1):
            raise ConvergenceError(f"--dt-factor {v!r}: must be in (0, 1] (a fraction of the "
                                   "automatic time step)")
        out.append(f)
    if any(b >= a for a, b in zip(out, out[1:])):
        raise ConvergenceError(f"--dt-factor {text!r}: factors must decrease from level to "
                               "level")
    return out


def make_levels(scene: dict, n_nodes: Optional[Sequence[int]],
                dt_factors: Optional[Sequence[float]]) -> list[Level]:
    """The ladder's scenes. A list of one value applies to every level; two lists of several
    values are paired level by level (equal lengths). Every brush gets the level's n_nodes;
    with a dt factor, run.dt = factor x the automatic dt of that level's scene."""
    import engine

    n_list = list(n_nodes) if n_nodes else [None]
    f_list = list(dt_factors) if dt_factors else [None]
    if len(n_list) > 1 and len(f_list) > 1 and len(n_list) != len(f_list):
        raise ConvergenceError(f"--ladder has {len(n_list)} levels and --dt-factor "
                               f"{len(f_list)}: give equal numbers (they pair up level by "
                               "level) or a single value for one of them")
    count = max(len(n_list), len(f_list))
    if len(n_list) == 1:
        n_list *= count
    if len(f_list) == 1:
        f_list *= count
    if n_list[0] is not None and not scene.get("brushes"):
        raise ConvergenceError("the scene has no brush: an n_nodes ladder needs one")
    levels = []
    for i, (n, f) in enumerate(zip(n_list, f_list)):
        s = json.loads(json.dumps(scene))
        for brush in s.get("brushes", []):
            if n is not None:
                brush["n_nodes"] = n
        dt = None
        if f is not None:
            s["run"]["dt"] = None
            auto = engine.build(engine.parse_scene(s)).dt
            dt = f * auto
            s["run"]["dt"] = dt
        # the run id changes with everything the run computes (not with the description)
        physics = {k: v for k, v in s.items() if k != "description"}
        digest = hashlib.sha256(json.dumps(physics, sort_keys=True).encode()).hexdigest()[:10]
        tag = f"L{i:02d}" + (f"_n{n}" if n is not None else "") + \
            (f"_dt{f:g}" if f is not None else "")
        levels.append(Level(i, n, f, dt, f"{tag}_{digest}".replace(".", "p"), s))
    return levels


def level_resolution(levels: Sequence[Level]) -> tuple[list[float], str]:
    """The h of each level for the observed order: 1 / (n_nodes - 1) (relative segment
    length) when n_nodes varies, else the dt factor."""
    ns = [lv.n_nodes for lv in levels]
    if ns[0] is not None and len(set(ns)) > 1:
        return [1.0 / (n - 1) for n in ns], "segment length / bristle length"
    fs = [lv.dt_factor for lv in levels]
    if fs[0] is not None and len(set(fs)) > 1:
        return list(fs), "dt factor"
    return [1.0] * len(levels), "none (a single resolution)"


# ============================================================================ running
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


@dataclass
class ConvergenceTable:
    """A convergence study: one row per level plus the reference and the observed order.

    ``rows``: dicts with level, n_nodes, dt, dt_factor, quantity, error (relative, against
    ``reference``), wall_s (the run's own wall time), status, run_id, h5, message.
    ``cheapest``: ``{"0.01": row or None, "0.05": ...}``, the level with the least wall time
    whose |error| is within that tolerance (for a ``finest`` reference the finest level itself
    is excluded)."""

    quantity: str
    unit: str
    scene_name: str
    reference: Optional[float]
    reference_kind: Optional[str]
    reference_note: str
    resolution: str
    observed_orders: list
    fitted_order: Optional[float]
    richardson: Optional[float]
    richardson_order: Optional[float]
    rows: list = field(default_factory=list)
    cheapest: dict = field(default_factory=dict)
    measured_at: str = ""

    def to_dict(self) -> dict:
        return _json_null(asdict(self))

    def text(self) -> str:
        """A printable table and the analysis below it."""
        name = f"{self.quantity} [{self.unit}]"
        lines = [f"{'level':>5} {'n_nodes':>7} {'dt [s]':>11} {name:>24} "
                 f"{'error':>10} {'wall [s]':>9}  status"]
        for r in self.rows:
            q = "nan" if r["quantity"] is None else f"{r['quantity']:.6g}"
            e = "nan" if r["error"] is None else f"{r['error']:+.3e}"
            w = "nan" if r["wall_s"] is None else f"{r['wall_s']:.2f}"
            dt = "auto" if r["dt"] is None else f"{r['dt']:.4g}"
            n = "" if r["n_nodes"] is None else str(r["n_nodes"])
            lines.append(f"{r['level']:>5} {n:>7} {dt:>11} {q:>24} {e:>10} {w:>9}  "
                         f"{r['status']}{'  ' + r['message'] if r.get('message') else ''}")
        ref = "none" if self.reference is None else f"{self.reference:.8g} {self.unit}"
        lines.append(f"reference: {ref} ({self.reference_kind}: {self.reference_note})")
        if self.richardson is not None:
            lines.append(f"Richardson estimate of the three finest levels: "
                         f"{self.richardson:.8g} {self.unit}, observed order "
                         f"{self.richardson_order:.3g}")
        orders = ", ".join("nan" if o is None else f"{o:.3g}" for o in self.observed_orders)
        if orders:
            fit = "nan" if self.fitted_order is None else f"{self.fitted_order:.3g}"
            lines.append(f"observed order between levels (h = {self.resolution}): {orders}; "
                         f"least-squares fit: {fit}")
        for tol, row in self.cheapest.items():
            pct = f"{100 * float(tol):g} %"
            lines.append(f"cheapest level within {pct}: " + (
                "none" if row is None else
                f"level {row['level']} (n_nodes {row['n_nodes']}, dt {row['dt']:.4g} s) "
                f"in {row['wall_s']:.2f} s"))
        return "\n".join(lines)


def analyse(quantity: Quantity, levels: Sequence[Level], values: Sequence[float],
            walls: Sequence[float], statuses: Sequence[str], messages: Sequence[str],
            dts: Sequence[Optional[float]], analytic: Optional[Reference],
            reference: str = "auto", scene_name: str = "", run_ids=None,
            h5s=None) -> ConvergenceTable:
    """Errors, observed orders, Richardson estimate and cheapest levels of a finished
    ladder. ``reference``: auto | analytic | richardson | finest."""
    h_all, resolution = level_resolution(levels)
    ok = [i for i, v in enumerate(values) if v is not None and math.isfinite(v)]
    h_ok = [h_all[i] for i in ok]
    q_ok = [values[i] for i in ok]
    rich, rich_p = richardson(h_ok, q_ok) if len(ok) >= 3 else (math.nan, math.nan)
    ref: Optional[Reference] = None
    if reference in ("auto", "analytic") and analytic is not None:
        ref = analytic
    elif reference == "analytic":
        raise ConvergenceError(f"no analytic reference for {quantity.text} in this scene "
                               "(analytic references: single-bristle rod cases)")
    if ref is None and reference in ("auto", "richardson") and math.isfinite(rich):
        ref = Reference(rich, "richardson", f"Richardson extrapolation of the three finest "
                        f"levels, observed order {rich_p:.3g}")
    if ref is None and reference == "richardson":
        raise ConvergenceError("no Richardson estimate: it needs three finished levels that "
                               "converge monotonically")
    finest_index = None
    if ref is None and ok:
        finest_index = ok[-1]
        ref = Reference(values[finest_index], "finest",
                        f"the finest level ({finest_index}) itself")
    errors = []
    for v in values:
        if ref is None or v is None or not math.isfinite(v) or ref.value == 0:
            errors.append(None)
        else:
            errors.append((v - ref.value) / abs(ref.value))
    if ref is not None and ref.kind == "finest":
        e_ok = [errors[i] for i in ok[:-1]]
        orders = observed_orders(h_ok[:-1], e_ok)
        fit = fitted_order(h_ok[:-1], e_ok)
    else:
        e_ok = [errors[i] for i in ok]
        orders = observed_orders(h_ok, e_ok)
        fit = fitted_order(h_ok, e_ok)
    rows = []
    for i, lv in enumerate(levels):
        rows.append({"level": lv.level, "n_nodes": lv.n_nodes, "dt": dts[i],
                     "dt_factor": lv.dt_factor, "quantity": values[i], "error": errors[i],
                     "wall_s": walls[i], "status": statuses[i], "message": messages[i],
                     "run_id": run_ids[i] if run_ids else lv.run_id,
                     "h5": str(h5s[i]) if h5s else None})
    cheapest = {}
    for tol in TOLERANCES:
        best = None
        for i, r in enumerate(rows):
            if r["error"] is None or r["wall_s"] is None or i == finest_index:
                continue
            if abs(r["error"]) <= tol and (best is None or r["wall_s"] < best["wall_s"]):
                best = r
        cheapest[f"{tol:g}"] = best
    table = ConvergenceTable(
        quantity=quantity.text, unit=quantity.unit, scene_name=scene_name,
        reference=None if ref is None else ref.value,
        reference_kind=None if ref is None else ref.kind,
        reference_note="" if ref is None else ref.note, resolution=resolution,
        observed_orders=[None if not math.isfinite(o) else o for o in orders],
        fitted_order=fit if math.isfinite(fit) else None,
        richardson=rich if math.isfinite(rich) else None,
        richardson_order=rich_p if math.isfinite(rich_p) else None,
        rows=rows, cheapest=cheapest,
        measured_at=time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()))
    return table


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
                value = measure(rec["h5"], q)
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
                    progress: bool = True, warm_up: bool = True) -> ConvergenceTable:
    """Run a ladder (:func:`run_ladder`), measure and analyse ``quantity``
    (:func:`tabulate`) and write the outputs into ``out_dir``; returns the table.
    ``scene``: an ``engine.Scene``, a dict or JSON text."""
    import engine

    q = parse_quantity(quantity) if isinstance(quantity, str) else quantity
    if not isinstance(scene, engine.Scene):
        scene = engine.parse_scene(scene)
    if reference not in ("auto", "analytic", "richardson", "finest"):
        raise ConvergenceError(f"reference {reference!r}: auto, analytic, richardson or finest")
    levels, records = run_ladder(scene, out_dir, n_nodes=n_nodes, dt_factors=dt_factors,
                                 serial=serial, scheduler=scheduler, workers=workers,
                                 progress=progress, warm_up=warm_up)
    table = tabulate(scene, q, levels, records, reference)
    write_outputs(table, out_dir, scene_json=scene.to_json())
    return table


# ============================================================================ outputs
def _num(v) -> str:
    return "nan" if v is None else repr(float(v))


def write_outputs(table: ConvergenceTable, out_dir, scene_json: str = "") -> None:
    """convergence.csv, convergence.json, convergence.h5 (group /convergence) and
    convergence.png into ``out_dir``; each written to a temporary name and renamed."""
    import h5py

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = out_dir / ".convergence.csv.tmp"
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(CSV_COLUMNS)
        for r in table.rows:
            w.writerow([r["level"], "" if r["n_nodes"] is None else r["n_nodes"],
                        _num(r["dt"]), _num(r["quantity"]), _num(r["error"]),
                        _num(r["wall_s"])])
    tmp.replace(out_dir / "convergence.csv")
    data = {"format": FORMAT, "format_version": 1, **table.to_dict()}
    tmp = out_dir / ".convergence.json.tmp"
    tmp.write_text(json.dumps(data, indent=1, allow_nan=False) + "\n")
    tmp.replace(out_dir / "convergence.json")
    tmp = out_dir / ".convergence.h5.tmp"
    with h5py.File(tmp, "w") as f:
        g = f.create_group("convergence")
        n = len(table.rows)

        def col(key, fill=math.nan):
            return np.array([fill if r[key] is None else r[key] for r in table.rows], float)

        g.create_dataset("level", data=np.arange(n, dtype=np.int64))
        g.create_dataset("n_nodes", data=np.array(
            [-1 if r["n_nodes"] is None else r["n_nodes"] for r in table.rows], np.int64))
        for key in ("dt", "dt_factor", "quantity", "error", "wall_s"):
            g.create_dataset(key, data=col(key))
        g.create_dataset("status", data=np.array([r["status"] for r in table.rows],
                                                 dtype=h5py.string_dtype()))
        g.create_dataset("run_id", data=np.array([r["run_id"] for r in table.rows],
                                                 dtype=h5py.string_dtype()))
        g.attrs["quantity"] = table.quantity
        g.attrs["unit"] = table.unit
        g.attrs["reference"] = math.nan if table.reference is None else table.reference
        g.attrs["reference_kind"] = table.reference_kind or ""
        g.attrs["reference_note"] = table.reference_note
        g.attrs["observed_order"] = math.nan if table.fitted_order is None else table.fitted_order
        g.attrs["richardson"] = math.nan if table.richardson is None else table.richardson
        g.attrs["richardson_order"] = (math.nan if table.richardson_order is None
                                       else table.richardson_order)
        g.attrs["resolution"] = table.resolution
        g.attrs["analysis"] = json.dumps(data, allow_nan=False)
        g.attrs["scene"] = scene_json
    tmp.replace(out_dir / "convergence.h5")
    plot_convergence(table, out_dir / "convergence.png")


def plot_convergence(table: ConvergenceTable, png_path, ax=None) -> None:
    """Log-log |relative error| against wall time, each point labelled with its level."""
    import matplotlib

    if ax is None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
    pts = [r for r in table.rows if r["error"] not in (None, 0) and r["wall_s"]]
    x = [r["wall_s"] for r in pts]
    y = [abs(r["error"]) for r in pts]
    ax.loglog(x, y, "o-", color="tab:blue")
    for r, xi, yi in zip(pts, x, y):
        label = f"n={r['n_nodes']}" if r["n_nodes"] is not None else ""
        if r["dt_factor"] is not None:
            label += f" dt×{r['dt_factor']:g}"
        ax.annotate(label.strip(), (xi, yi), textcoords="offset points", xytext=(4, 4),
                    fontsize=8)
    for tol, style in zip(TOLERANCES, (":", "--")):
        ax.axhline(tol, color="grey", ls=style, lw=0.8, label=f"{100 * tol:g} %")
    ax.set_xlabel("wall time of the run [s]")
    ax.set_ylabel(f"|relative error| vs {table.reference_kind or '?'} reference")
    ax.set_title(f"{table.scene_name}: {table.quantity}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    if own:
        fig.tight_layout()
        fig.savefig(png_path, dpi=120)
        plt.close(fig)


def load_convergence(out_dir) -> ConvergenceTable:
    """Read a finished convergence study back from its folder (``convergence.json``; the
    studio shows it as a table and a plot)."""
    path = Path(out_dir) / "convergence.json"
    if not path.exists():
        raise FileNotFoundError(f"{path}: not a convergence study folder (no convergence.json)")
    data = json.loads(path.read_text())
    if data.get("format") != FORMAT:
        raise ValueError(f"{path}: not a convergence study (format {data.get('format')!r})")
    data.pop("format", None)
    data.pop("format_version", None)
    return ConvergenceTable(**data)


# ============================================================================ command line
def _err(msg: str) -> None:
    print(msg, file=sys.stderr)


@dataclass
class Options:
    """``brush-studio convergence``: ``scene`` (a scene file) run at a ladder of
    resolutions (``ladder`` "n_nodes=3,5,9" and/or ``dt_factor`` "1,0.5"), ``quantity``
    measured in each against ``reference``."""

    scene: str
    quantity: str
    ladder: Optional[str] = None
    dt_factor: Optional[str] = None
    reference: str = "auto"          # auto | analytic | richardson | finest
    serial: bool = False             # the levels one after another in this process
    scheduler: Optional[str] = None
    workers: Optional[int] = None
    quiet: bool = False              # no progress bar

    @classmethod
    def from_args(cls, args) -> "Options":
        import dataclasses

        return cls(**{f.name: getattr(args, f.name) for f in dataclasses.fields(cls)})

    def to_dict(self) -> dict:
        import dataclasses

        return dataclasses.asdict(self)


def run(options: Options, out_dir, *, progress=None, cancel=None):
    """The convergence study of ``options`` into ``out_dir``: a ``StudyResult``."""
    from studio.studies import api

    return api.run_body("convergence", _run_study, options, out_dir, progress, cancel)


def _cmd_convergence(args) -> int:
    return run(Options.from_args(args), args.output).exit_code


def _run_study(options: Options, out: Path) -> int:
    import engine

    try:
        q = parse_quantity(options.quantity)
        n_nodes = parse_ladder(options.ladder) if options.ladder else None
        factors = parse_factors(options.dt_factor) if options.dt_factor else None
        if n_nodes is None and factors is None:
            raise ConvergenceError("give --ladder n_nodes=... and/or --dt-factor ...")
        scene = engine.load_scene(options.scene)
    except ConvergenceError as exc:
        _err(f"error: {exc}")
        return EXIT_BAD_INPUT
    except engine.SceneError as exc:
        _err(f"invalid scene {options.scene}: {len(exc.problems)} problem(s)")
        for p in exc.problems:
            _err(f"  {p}")
        return EXIT_BAD_INPUT
    try:
        table = run_convergence(scene, q, out, n_nodes=n_nodes, dt_factors=factors,
                                reference=options.reference, serial=options.serial,
                                scheduler=options.scheduler, workers=options.workers,
                                progress=not options.quiet)
    except ConvergenceError as exc:
        _err(f"error: {exc}")
        return EXIT_BAD_INPUT
    except engine.SceneError as exc:
        _err(f"invalid level scene: {len(exc.problems)} problem(s)")
        for p in exc.problems:
            _err(f"  {p}")
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        _err("cancelled: finished levels are kept in the runs folder and reused next time")
        return EXIT_CANCELLED
    print(table.text())
    print(f"wrote {Path(out) / 'convergence.csv'}, convergence.h5, convergence.json, "
          "convergence.png")
    return EXIT_OK if all(r["status"] in ("completed", "stopped") for r in table.rows) \
        else EXIT_FAILED


def register(subparsers) -> None:
    import argparse
    import textwrap

    p = subparsers.add_parser(
        "convergence", help="error against wall time for a ladder of resolutions",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
                    "Run a scene at a ladder of resolutions (nodes per bristle, time-step "
                    "factor) in parallel through the studies' Dask layer, measure a quantity "
                    "of interest in each, and report its error against a reference (analytic "
                    "where one exists, else Richardson/finest level), the observed order and "
                    "the wall time. Writes DIR/convergence.csv "
                    "(level,n_nodes,dt,quantity,error,wall_s), convergence.h5, "
                    "convergence.json and convergence.png (log-log error vs wall time).", 90),
        epilog=QUANTITY_HELP + "\n\nexample:\n  brush-studio convergence rod.json --quantity "
               "tip_deflection --ladder n_nodes=3,5,9,17,33 -o rod-convergence")
    p.add_argument("scene", metavar="SCENE.json")
    p.add_argument("--quantity", "-Q", required=True, metavar="NAME",
                   help="quantity of interest (below)")
    p.add_argument("--ladder", metavar="n_nodes=N1,N2,...",
                   help="nodes per bristle of each level (every brush), increasing")
    p.add_argument("--dt-factor", metavar="F1,F2,...",
                   help="run.dt = factor x the level's automatic dt, decreasing; one value "
                        "applies to every level, several pair up with --ladder")
    p.add_argument("-o", "--output", metavar="DIR", required=True, help="output folder")
    p.add_argument("--reference", choices=("auto", "analytic", "richardson", "finest"),
                   default="auto", help="what the errors are measured against (default auto: "
                                        "analytic, else Richardson, else the finest level)")
    p.add_argument("--serial", action="store_true",
                   help="run the levels one after another in this process, without Dask "
                        "(wall times undisturbed by parallel levels)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="an existing Dask scheduler (tcp://host:port); default a local cluster")
    p.add_argument("--workers", type=int, metavar="N",
                   help="local cluster workers (default one per core)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_convergence)
