"""The stability cases (DESIGN §3 "Integration and stability", §6 "Stability on stiff and
extreme cases"), shared by ``tests/engine/test_stability.py`` and
``benchmarks/dt_margins.py``.

Every case is a scene (a dict) built by ``build_case(name, folder, full=False)``; ``full``
gives the full-size variant (17 x 5 brushes, longer runs), the default a reduced quick one.
A case runs in a separate worker process (:class:`CaseRunner`) so that a hang is caught by a
wall-clock bound, and its result file is then judged by :func:`judge`:

- the run either completes (stable with the automatic dt) or stops with a clear
  ``engine.InstabilityError`` (quantity, where, time, advice all set);
- every recorded node and body state is finite (no silent NaN);
- no bristle node is ever inside a body, nor on the far side of it (a body never passes
  through the bristles).

Run this file as a script (``python stability_cases.py --worker``) to get the worker; the
protocol is one JSON request per line on stdin and one JSON answer per line on stdout.
"""
from __future__ import annotations

import json
import math
import os
import queue
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.model.layout import quat_to_matrix

# --------------------------------------------------------------------------- materials
SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1100.0}  # seed 4.2
PLA = {"youngs_modulus": 3.5e9, "poisson_ratio": 0.36, "density": 1240.0}
STEEL = {"youngs_modulus": 200e9, "poisson_ratio": 0.3, "density": 7640.0}  # seed 4.1
SILICONE_FRICTION = math.radians(44.0)  # seed 4.2
PLA_FRICTION = math.radians(24.0)  # seed 4.2

LENGTH = 0.033  # m, the seed's 33 mm bristles
ROOT_RADIUS = 0.001
TIP_RADIUS = 0.0005
PITCH = 0.003

SPACE_FUR_SPEED = 50.0  # m/s per component: 50 sqrt(2) m/s at 45 degrees (seed fig. 5.1)
CUBE_SPEED = 0.5  # m/s, the near-rigid cube
TIP_STD = 0.0005  # m, large tip randomness: 25 x the seed's (its variance 4e-10 m^2)


def _brush(material="silicone", rows=3, columns=3, n_nodes=6, length=LENGTH,
           root_radius=ROOT_RADIUS, tip_radius=TIP_RADIUS, pitch=PITCH, **extra) -> dict:
    d = {"name": "brush", "material": material, "rows": rows, "columns": columns,
         "pitch": [pitch, pitch], "bristle_length": length, "root_radius": root_radius,
         "tip_radius": tip_radius, "n_nodes": n_nodes}
    d.update(extra)
    return d


def _scene(name, description, materials, brushes, bodies, duration, record_interval,
           contact_pairs=(), **run_extra) -> dict:
    return {"schema_version": 1, "name": name, "description": description,
            "materials": materials, "contact_pairs": list(contact_pairs),
            "brushes": brushes, "bodies": bodies,
            "environment": {"gravity": [0.0, 0.0, 0.0]},
            "run": {"duration": duration, "record_interval": record_interval, **run_extra}}


def _press(speed: float, depth: float) -> dict:
    """Kinematic motion: straight down at ``speed`` for ``depth``, then hold."""
    return {"type": "kinematic",
            "profile": {"kind": "constant", "velocity": [0.0, 0.0, -speed],
                        "duration": depth / speed},
            "after": "hold"}


def _wedge(z_apex: float, speed: float, depth: float, angle: float = math.pi / 3) -> dict:
    """The seed's wedge (4.2): apex edge along x, 0.5 mm to the side of the middle row."""
    return {"name": "wedge", "material": "pla",
            "shape": {"type": "wedge", "angle": angle, "height": 0.02, "length": 0.02},
            "pose": {"position": [0.0, 0.0005, z_apex]}, "motion": _press(speed, depth)}


def _silicone_pressed(name, description, brush, *, speed=0.5, depth=0.003, gap=1e-4,
                      hold=0.002, tip_radius=None, **run_extra) -> dict:
    """A silicone brush pressed ``depth`` by the PLA wedge at ``speed``, then held."""
    r_tip = brush["tip_radius"] if tip_radius is None else tip_radius
    return _scene(name, description, {"silicone": SILICONE, "pla": PLA},
                  [brush], [_wedge(brush["bristle_length"] + r_tip + gap, speed, depth)],
                  duration=depth / speed + hold, record_interval=(depth / speed + hold) / 40,
                  contact_pairs=[
                      {"materials": ["silicone", "silicone"], "friction_angle": SILICONE_FRICTION},
                      {"materials": ["silicone", "pla"], "friction_angle": PLA_FRICTION}],
                  **run_extra)


# --------------------------------------------------------------------------- the cases
def steel_bristles(folder: Path, full: bool = False) -> dict:
    rows, cols = (17, 5) if full else (3, 3)
    speed, depth = 0.5, (0.002 if full else 0.001)
    return _scene(
        "stability_steel_bristles",
        f"steel bristles (E 200 GPa) in a {rows} x {cols} brush, pressed {depth * 1e3:g} mm "
        f"by a PLA wedge at {speed:g} m/s",
        {"steel": STEEL, "pla": PLA}, [_brush("steel", rows, cols)],
        [_wedge(LENGTH + TIP_RADIUS + 1e-4, speed, depth)],
        duration=depth / speed + 5e-4, record_interval=(depth / speed + 5e-4) / 40,
        contact_pairs=[{"materials": ["steel", "steel"], "friction_angle": 0.3},
                       {"materials": ["steel", "pla"], "friction_angle": 0.3}])


def near_rigid_body(folder: Path, full: bool = False) -> dict:
    """A free steel cube (E 200 GPa, 74 000 x the bristles') strikes soft silicone bristles."""
    rows, cols = (17, 5) if full else (3, 3)
    size = 0.012 if full else 0.006
    return _scene(
        "stability_near_rigid_body",
        f"a free steel cube ({size * 1e3:g} mm, E 200 GPa) strikes a {rows} x {cols} silicone "
        f"brush at {CUBE_SPEED:g} m/s",
        {"silicone": SILICONE, "steel": STEEL}, [_brush("silicone", rows, cols)],
        [{"name": "cube", "material": "steel", "shape": {"type": "box", "size": [size] * 3},
          "mass_properties": {"density": STEEL["density"]}, "motion": {"type": "free"},
          "pose": {"position": [0.0003, 0.0002, LENGTH + TIP_RADIUS + 1e-4 + size / 2]},
          "velocity": [0.0, 0.0, -CUBE_SPEED]}],
        duration=0.04, record_interval=0.0005,
        contact_pairs=[{"materials": ["silicone", "silicone"], "friction_angle": SILICONE_FRICTION},
                       {"materials": ["silicone", "steel"], "friction_angle": PLA_FRICTION}])


def space_fur(folder: Path, full: bool = False) -> dict:
    """The seed's space fur (fig. 5.1), as in ``static_presets/space_fur.json`` but smaller: a
    PLA sphere at 50 sqrt(2) m/s, 45 degrees off the normal, into a fur of thin steel
    bristles on a fixed steel plate."""
    rows, cols = (15, 15) if full else (5, 5)
    length, r_root, r_tip, pitch, radius = 0.02, 0.0003, 0.0002, 0.002, 0.003
    n_nodes = 6 if full else 4
    # the sphere's surface starts 0.5 mm above the tips, aimed at the middle of the fur
    z0 = length + r_root + r_tip + 0.0005 + radius
    x0 = -(z0 - length / 2)  # it would reach x = 0 half-way down the bristles
    return _scene(
        "stability_space_fur",
        f"space fur ({rows} x {cols} steel bristles, 20 mm, 0.3 -> 0.2 mm radius, 2 mm pitch, "
        f"on a fixed steel plate) hit by a 3 mm PLA sphere at 50 sqrt(2) m/s, 45 degrees off "
        f"the normal",
        {"steel": STEEL, "pla": PLA},
        [_brush("steel", rows, cols, n_nodes, length, r_root, r_tip, pitch,
                base={"position": [0.0, 0.0, r_root]})],
        [{"name": "sphere", "material": "pla",
          "shape": {"type": "sphere", "radius": radius},
          "mass_properties": {"density": PLA["density"]}, "motion": {"type": "free"},
          "pose": {"position": [x0, 0.0002, z0]},
          "velocity": [SPACE_FUR_SPEED, 0.0, -SPACE_FUR_SPEED]},
         # the plate's top face at z = 0, where the root nodes' surfaces are (as in the preset)
         {"name": "plate", "material": "steel",
          "shape": {"type": "box", "size": [0.06, 0.06, 0.004]},
          "pose": {"position": [0.0, 0.0, -0.002]}}],
        duration=0.0006 if full else 0.0004, record_interval=1e-5,
        contact_pairs=[{"materials": ["steel", "pla"], "friction_angle": math.radians(20.0)},
                       {"materials": ["steel", "steel"], "friction_angle": math.radians(20.0)}])


def coarse_bristles(folder: Path, full: bool = False) -> dict:
    rows, cols = (17, 5) if full else (3, 3)
    return _silicone_pressed("stability_coarse_bristles",
                             f"{rows} x {cols} silicone brush of 2-node bristles (one segment "
                             f"each) pressed 3 mm by the wedge",
                             _brush("silicone", rows, cols, n_nodes=2))


def fine_bristles(folder: Path, full: bool = False) -> dict:
    rows, cols = (17, 5) if full else (1, 2)
    n = 96 if full else 64
    return _silicone_pressed("stability_fine_bristles",
                             f"{rows} x {cols} silicone brush of {n}-node bristles (nodes "
                             f"{LENGTH / (n - 1) * 1e3:.2f} mm apart, radius up to 1 mm: far "
                             f"beyond the seed's node-overlap ceiling) pressed by the wedge",
                             _brush("silicone", rows, cols, n_nodes=n),
                             speed=1.0, depth=0.002 if full else 0.001,
                             hold=0.001 if full else 0.0002)


def extreme_taper(folder: Path, full: bool = False) -> dict:
    rows, cols = (17, 5) if full else (3, 3)
    r_tip = 0.05 * ROOT_RADIUS
    return _silicone_pressed("stability_extreme_taper",
                             f"{rows} x {cols} silicone brush tapering from 1 mm to 0.05 mm "
                             f"radius, pressed 3 mm by the wedge",
                             _brush("silicone", rows, cols, tip_radius=r_tip))


def tip_randomness(folder: Path, full: bool = False, std: float = TIP_STD) -> dict:
    rows, cols = (17, 5) if full else (3, 3)
    return _silicone_pressed("stability_tip_randomness",
                             f"{rows} x {cols} silicone brush whose tips are scattered with a "
                             f"standard deviation of {std * 1e3:g} mm (the seed used 0.02 mm), "
                             f"pressed 3 mm by the wedge",
                             _brush("silicone", rows, cols, tip_variance=std ** 2, seed=3))


def crossing_bristles(folder: Path, full: bool = False) -> dict:
    """Tip randomness so large (1.5 mm, half the pitch) that bristles start out crossing."""
    return tip_randomness(folder, full, std=0.0015)


def _slab_with_slivers(half: float, height: float, n_strips: int):
    """A closed box ``2 half x 2 half x height`` (bottom at z = 0) whose faces are all strips
    of sliver triangles ``2 half / n_strips`` wide (aspect ratio up to ``n_strips``)."""
    xs = np.linspace(-half, half, n_strips + 1)
    verts = []
    for z in (0.0, height):
        for y in (-half, half):
            verts.extend((x, y, z) for x in xs)
    m = n_strips + 1

    def v(zi, yi, i):  # vertex index: layer zi (bottom/top), side yi (-y/+y), strip edge i
        return (2 * zi + yi) * m + i

    faces = []
    for i in range(n_strips):
        j = i + 1
        # bottom (normal -z), top (+z), the y = -half side (-y), the y = +half side (+y)
        faces += [(v(0, 0, i), v(0, 1, i), v(0, 1, j)), (v(0, 0, i), v(0, 1, j), v(0, 0, j))]
        faces += [(v(1, 0, i), v(1, 0, j), v(1, 1, j)), (v(1, 0, i), v(1, 1, j), v(1, 1, i))]
        faces += [(v(0, 0, i), v(0, 0, j), v(1, 0, j)), (v(0, 0, i), v(1, 0, j), v(1, 0, i))]
        faces += [(v(0, 1, i), v(1, 1, i), v(1, 1, j)), (v(0, 1, i), v(1, 1, j), v(0, 1, j))]
    for i, (a, b, c, d) in ((0, (v(0, 0, 0), v(1, 0, 0), v(1, 1, 0), v(0, 1, 0))),
                            (n_strips, (v(0, 0, n_strips), v(0, 1, n_strips), v(1, 1, n_strips),
                                        v(1, 0, n_strips)))):
        faces += [(a, b, c), (a, c, d)]  # the two x ends
    return np.array(verts, float), np.array(faces, np.int64)


def sliver_mesh(folder: Path, full: bool = False) -> dict:
    """A closed slab made only of sliver triangles (aspect ratio 500) pressed onto the brush."""
    import trimesh
    rows, cols = (17, 5) if full else (3, 3)
    half = 0.03 if full else 0.008
    verts, faces = _slab_with_slivers(half, 0.004, 500)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    path = Path(folder) / "sliver_slab.stl"
    mesh.export(path)
    scene = _silicone_pressed("stability_sliver_mesh",
                              f"{rows} x {cols} silicone brush pressed 3 mm by a flat slab "
                              f"whose every face is a strip of sliver triangles "
                              f"({2 * half / 500 * 1e6:.0f} um x {2 * half * 1e3:g} mm)",
                              _brush("silicone", rows, cols))
    body = scene["bodies"][0]
    body.update(name="plate", shape={"type": "mesh", "file": str(path)})
    body["pose"]["position"] = [0.0, 0.0, LENGTH + TIP_RADIUS + 1e-4]
    return scene


def open_mesh(folder: Path, full: bool = False) -> dict:
    """A non-watertight body: a box without its bottom face (a cup upside down) lowered over
    the brush, so that the tips enter through the hole and press on the inside of its top."""
    import trimesh
    rows, cols = (17, 5) if full else (3, 3)
    half_x = 0.5 * (cols - 1) * PITCH + 0.003
    half_y = 0.5 * (rows - 1) * PITCH + 0.003
    height = 0.008
    box = trimesh.creation.box(extents=[2 * half_x, 2 * half_y, height])
    keep = box.face_normals[:, 2] > -0.5  # drop the bottom face
    cup = trimesh.Trimesh(box.vertices, box.faces[keep], process=False)
    assert not cup.is_watertight
    path = Path(folder) / "open_cup.stl"
    cup.export(path)
    scene = _silicone_pressed("stability_open_mesh",
                              f"{rows} x {cols} silicone brush; a bottomless box (open mesh) "
                              f"comes down over it and presses the tips 3 mm from inside",
                              _brush("silicone", rows, cols))
    body = scene["bodies"][0]
    body.update(name="target", shape={"type": "mesh", "file": str(path)})
    # the inside of the top face 0.1 mm above the tips: the walls already surround them
    body["pose"]["position"] = [0.0, 0.0, LENGTH + TIP_RADIUS + 1e-4 - height / 2]
    return scene


def long_run(folder: Path, full: bool = False, steps=None) -> dict:
    """Energy conservation over many steps: a 2 x 2 brush, no friction, no damping, no
    gravity; the tips of one column are pushed into the other column for 2 ms, then the
    bristles swing and collide freely. 1e6 steps (full) or 1e5."""
    n_steps = steps or (1_000_000 if full else 100_000)
    scene = _scene("stability_long_run",
                   f"{n_steps:.0e} steps of a 2 x 2 silicone brush swinging and colliding "
                   f"without friction or damping",
                   {"silicone": SILICONE}, [_brush("silicone", 2, 2, n_nodes=4)], [],
                   duration=1.0, record_interval=1.0, channels=["energy", "nodes"])
    scene["loads"] = [{"brush": "brush", "bristles": [0, 2], "node": -1,
                       "force": [2e-3, 0.0, 0.0],
                       "profile": {"times": [0.0, 0.002, 0.0021], "values": [1.0, 1.0, 0.0]}}]
    scene["_steps"] = n_steps  # resolved against the automatic dt by set_steps()
    return scene


def set_steps(scene: dict, dt: float) -> dict:
    """A long-run scene lasts its ``_steps`` steps of ``dt`` and records 200 frames."""
    n = scene.pop("_steps", None)
    if n is not None:
        scene["run"]["duration"] = n * dt
        scene["run"]["record_interval"] = n * dt / 200
    return scene


CASES = {
    "steel_bristles": steel_bristles,
    "near_rigid_body": near_rigid_body,
    "space_fur": space_fur,
    "coarse_bristles": coarse_bristles,
    "fine_bristles": fine_bristles,
    "extreme_taper": extreme_taper,
    "tip_randomness": tip_randomness,
    "crossing_bristles": crossing_bristles,
    "sliver_mesh": sliver_mesh,
    "open_mesh": open_mesh,
    "long_run": long_run,
}


def build_case(name: str, folder: Path, full: bool = False) -> dict:
    """The scene dict of case ``name``; mesh files it needs are written into ``folder``."""
    Path(folder).mkdir(parents=True, exist_ok=True)
    return CASES[name](Path(folder), full)


# --------------------------------------------------------------------------- the worker
def _worker_main() -> int:
    """Serve requests ``{"scene": path, "output": path, "dt_factor": float | null}``: run the
    scene (with ``run.dt = dt_factor x`` the automatic dt if given) and answer with the
    outcome."""
    out = os.fdopen(os.dup(1), "w", buffering=1)
    sys.stdout = sys.stderr  # nothing else may write on the protocol channel
    root = str(Path(__file__).resolve().parents[2])
    if root not in sys.path:
        sys.path.append(root)  # the repository, as tests/conftest.py does
    import engine
    _warm_up(engine)
    out.write(json.dumps({"ready": True}) + "\n")
    for line in sys.stdin:
        if not line.strip():
            continue
        req = json.loads(line)
        try:
            answer = _run_request(engine, req)
        except Exception as exc:  # reported, judged by the caller
            answer = {"status": "error", "error": f"{type(exc).__name__}: {exc}"}
        out.write(json.dumps(answer) + "\n")
    return 0


def _warm_up(engine) -> None:
    """Compile (or load) every kernel with a tiny scene that has all stages, so that the
    per-case wall-clock bound does not count numba's compilation."""
    import tempfile
    d = space_fur(Path("."))
    d["brushes"][0].update(rows=2, columns=2, material="pla")
    d["bodies"].append({"name": "box", "material": "pla",
                        "shape": {"type": "box", "size": [0.004, 0.004, 0.004]},
                        "pose": {"position": [0.02, 0.02, 0.04]},
                        "mass_properties": {"density": 1000.0}, "motion": {"type": "free"}})
    d["run"].update(duration=2e-5, record_interval=1e-5)
    d["bodies"][0]["velocity"] = [0.0, 0.0, -1.0]
    d["loads"] = [{"brush": "brush", "force": [1e-4, 0.0, 0.0]}]
    d["environment"] = {"gravity": [0.0, 0.0, -9.81], "local_damping": 0.1}
    with tempfile.TemporaryDirectory() as tmp:
        engine.run(engine.build(engine.parse_scene(d)), output=Path(tmp) / "warm.h5")


def _run_request(engine, req: dict) -> dict:
    scene = json.loads(Path(req["scene"]).read_text())
    steps = scene.get("_steps")
    probe = json.loads(json.dumps(scene))
    probe.pop("_steps", None)
    try:
        system = engine.build(engine.parse_scene(probe))
    except engine.SceneError as exc:  # a clear refusal of the scene: judged by the caller
        return {"status": "scene_error", "problems": [str(p) for p in exc.problems],
                "output": req["output"]}
    auto_dt = system.dt_stable * system.scene.run.dt_safety
    auto_limited_by = system.dt_limited_by
    factor = req.get("dt_factor")
    if steps is not None:
        set_steps(scene, auto_dt)
    if factor is not None:
        scene["run"]["dt"] = factor * auto_dt
        scene["run"]["record_interval"] = max(scene["run"]["record_interval"],
                                              scene["run"]["dt"])
    system = engine.build(engine.parse_scene(scene))
    answer = {"auto_dt": auto_dt, "auto_limited_by": auto_limited_by, "dt": system.dt,
              "dt_stable": system.dt_stable,
              "dt_limited_by": system.dt_limited_by, "n_nodes": system.n_nodes,
              "warnings": list(system.warnings), "output": req["output"]}
    t0 = time.perf_counter()
    try:
        result = engine.run(system, output=req["output"])
        answer.update(status=result.status, summary=_small(result.summary))
    except engine.InstabilityError as exc:
        answer.update(status="instability", instability=exc.as_dict(),
                      summary=_small(exc.result.summary if exc.result else {}))
    answer["wall_s"] = time.perf_counter() - t0
    return answer


def _small(summary: dict) -> dict:
    keep = ("status", "steps", "time", "wall_s", "steps_per_s", "frames",
            "max_overlap_ratio", "neighbour_rebuilds")
    return {k: summary[k] for k in keep if k in summary}


@dataclass
class Outcome:
    """What a case did: ``status`` is ``completed``/``stopped`` (stable), ``instability``
    (a clear InstabilityError: ``instability`` is its ``as_dict()``), ``scene_error`` (build
    refused the scene with a SceneError: ``problems``), ``hang`` (no answer within the
    wall-clock bound), ``error`` (any other exception in the worker)."""
    status: str
    wall_s: float
    answer: dict = field(default_factory=dict)

    @property
    def stable(self) -> bool:
        return self.status in ("completed", "stopped")

    @property
    def instability(self) -> dict | None:
        return self.answer.get("instability")

    @property
    def output(self) -> Path:
        return Path(self.answer["output"])


class CaseRunner:
    """A worker process that runs cases one at a time, each under a wall-clock bound; a case
    that overruns its bound is a hang: the worker is killed and a fresh one started for the
    next case. Use as a context manager."""

    def __init__(self, startup_timeout: float = 900.0):
        self.startup_timeout = startup_timeout
        self.proc: subprocess.Popen | None = None
        self.lines: queue.Queue = queue.Queue()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _start(self) -> None:
        env = dict(os.environ)
        env.setdefault("NUMBA_NUM_THREADS", "1")
        # the worker imports this checkout's engine, whichever checkout an install points at
        root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [root, env.get("PYTHONPATH")]))
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--worker"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True, env=env)
        self.lines = queue.Queue()
        threading.Thread(target=self._read, args=(self.proc, self.lines), daemon=True).start()
        first = self._answer(self.startup_timeout)
        if first is None or not first.get("ready"):
            self.close()
            raise RuntimeError(f"the stability worker did not start: {first!r}")

    @staticmethod
    def _read(proc, lines) -> None:
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    def _answer(self, timeout: float):
        try:
            line = self.lines.get(timeout=timeout)
        except queue.Empty:
            return None
        return None if line is None else json.loads(line)

    def run(self, scene: dict, folder: Path, timeout: float, dt_factor: float | None = None,
            tag: str = "run") -> Outcome:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        scene_path = folder / f"{tag}.json"
        scene_path.write_text(json.dumps(scene, indent=1))
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        req = {"scene": str(scene_path), "output": str(folder / f"{tag}.h5"),
               "dt_factor": dt_factor}
        t0 = time.perf_counter()
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        answer = self._answer(timeout)
        wall = time.perf_counter() - t0
        if answer is None:
            crashed = self.proc.poll() is not None
            self.close()
            return Outcome("error" if crashed else "hang", wall,
                           {"output": req["output"],
                            "error": "the worker died" if crashed else
                            f"no answer within {timeout:g} s"})
        return Outcome(answer["status"], wall, answer)

    def close(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
            self.proc = None


# --------------------------------------------------------------------------- judging
def _rot(q) -> np.ndarray:
    return quat_to_matrix(np.asarray(q, float) / np.linalg.norm(q))


def judge(outcome: Outcome) -> list[str]:
    """Every way the case went wrong (an empty list: it is fine)."""
    import engine
    problems: list[str] = []
    if outcome.status == "hang":
        return [f"hang: {outcome.answer.get('error')}"]
    if outcome.status == "scene_error":
        return [] if outcome.answer.get("problems") else ["a SceneError without problems"]
    if outcome.status == "error":
        return ["the run raised something other than InstabilityError: "
                + str(outcome.answer.get("error"))]
    if outcome.status == "instability":
        e = outcome.instability
        if not (e["quantity"] and e["where"] and e["where"] != "?" and e["advice"]
                and math.isfinite(e["time"]) and e["time"] >= 0
                and e["message"].startswith("instability:")
                and not e["quantity"].startswith("unknown")):
            problems.append(f"unclear instability error: {e}")
    elif not outcome.stable:
        problems.append(f"unexpected status {outcome.status!r}")
    with engine.open_result(outcome.output) as res:
        expected = "failed" if outcome.status == "instability" else outcome.status
        if res.status != expected:
            problems.append(f"result file status {res.status!r}, expected {expected!r}")
        if res.n_frames < 1:
            return problems + ["no frame recorded"]
        problems += _check_finite(res)
        if "nodes/positions" in res.channels():
            problems += _check_bodies(res)
    return problems


def _check_finite(res) -> list[str]:
    bad = []
    for ch in res.channels():
        data = res.series(ch)
        if data.dtype.kind == "f" and not np.all(np.isfinite(data)):
            frame = int(np.argmax(~np.isfinite(data.reshape(len(data), -1)).all(axis=1)))
            bad.append(f"non-finite values in {ch} (frame {frame}, t = {res.time[frame]:.4g} s)")
    return bad


def _body_frame(res, name: str, frame: int, x_nodes: np.ndarray) -> np.ndarray:
    """Node centres in the frame of body ``name``'s recorded vertices."""
    p = res.frame(f"bodies/{name}/position", frame)
    R = _rot(res.frame(f"bodies/{name}/orientation", frame))
    return (x_nodes - p) @ R  # world -> body (R maps body -> world)


class BodyCheck:
    """Whether bristle nodes are inside body ``name`` or have gone through it.

    A node's side of the body is taken at the first frame; afterwards a node must never be
    inside the body, nor have crossed to the other side of it where the body is (the body
    passed through the bristle, or the bristle through the body):

    - sphere: inside = centre closer than the radius; crossed = in the sphere's shadow
      (less than 0.9 radius off the line of its initial velocity) and behind it, having
      been ahead of it;
    - wedge: inside = within the wedge's cross-section; crossed = above its faces (the
      wedge comes from above), having been below them;
    - box and mesh: in the body's frame, across its axis nearest world z, the footprint is
      the box of its vertices; inside = within the footprint and between its lowest and
      highest vertex; crossed = within the footprint and on the other side of the body's
      mid-plane than at the start. An open (not watertight) mesh has no inside: crossed =
      on the other side of its highest face (a bottomless cup keeps what it covers below
      its top).
    """

    def __init__(self, res, body, x0: np.ndarray):
        self.name = body.name
        self.shape = body.shape.model_dump()
        self.kind = self.shape["type"]
        self.open = False
        if self.kind == "mesh":
            import trimesh
            self.open = not trimesh.load(self.shape["file"], force="mesh").is_watertight
        if self.kind != "sphere":
            self.verts = res.static(f"bodies/{body.name}/vertices")
        if self.kind == "sphere":
            v = np.asarray(res.frame(f"bodies/{body.name}/velocity", 0), float)
            self.direction = v / np.linalg.norm(v) if np.linalg.norm(v) > 0 else None
        self.start = self._side(res, 0, x0)

    def _side(self, res, frame: int, x: np.ndarray):
        """(inside, side, in_shadow): per-node booleans and a per-node side (+1/-1)."""
        local = _body_frame(res, self.name, frame, x)
        if self.kind == "sphere":
            R = self.shape["radius"]
            inside = np.linalg.norm(local, axis=1) < R
            if self.direction is None:
                return inside, np.ones(len(x)), np.zeros(len(x), bool)
            along = local @ self.direction
            off = np.linalg.norm(local - np.outer(along, self.direction), axis=1)
            return inside, np.sign(along), off < 0.9 * R
        lo, hi = self.verts.min(axis=0), self.verts.max(axis=0)
        if self.kind == "wedge":
            y = local[:, 1] - 0.5 * (lo[1] + hi[1])
            z = local[:, 2] - lo[2]  # above the apex
            in_length = np.abs(local[:, 0]) < 0.5 * self.shape["length"]
            within = in_length & (z > 0) & (np.abs(y) < z * math.tan(0.5 * self.shape["angle"]))
            inside = within & (z < self.shape["height"])
            return inside, np.where(within, 1.0, -1.0), in_length
        R = _rot(res.frame(f"bodies/{self.name}/orientation", frame))
        up = int(np.argmax(np.abs(R[2, :])))  # the body axis nearest world z
        footprint = np.ones(len(local), bool)
        for a in range(3):
            if a != up:
                footprint &= (local[:, a] > lo[a]) & (local[:, a] < hi[a])
        h = local[:, up]
        world_up = 1.0 if R[2, up] > 0 else -1.0  # sides are told in the world's up sense
        if self.open:
            top = hi[up] if world_up > 0 else lo[up]
            return np.zeros(len(local), bool), np.sign((h - top) * world_up), footprint
        inside = footprint & (h > lo[up]) & (h < hi[up])
        return inside, np.sign((h - 0.5 * (lo[up] + hi[up])) * world_up), footprint

    def violations(self, res, frame: int, x: np.ndarray) -> int:
        inside, side, shadow = self._side(res, frame, x)
        crossed = shadow & (side != self.start[1]) & (self.start[1] != 0)
        if self.kind == "sphere":  # only a node that was ahead can be passed through
            crossed &= self.start[1] > 0
        return int(np.sum(inside | crossed))


def _check_bodies(res) -> list[str]:
    bad = []
    x = res.series("nodes/positions")
    for body in res.scene.bodies:
        if f"bodies/{body.name}/position" not in res.channels():
            continue
        check = BodyCheck(res, body, x[0])
        for f in range(res.n_frames):
            n = check.violations(res, f, x[f])
            if n:
                bad.append(f"{n} bristle node(s) inside or through body {body.name!r} at "
                           f"t = {res.time[f]:.4g} s (frame {f})")
                break
    return bad


def contacts_happened(res, body: str) -> bool:
    """Whether the body ever met the bristles: a non-zero recorded contact force, or bristle
    nodes pushed more than their radius from rest (the light tips of an extremely tapered
    bristle bounce off a fast body between two recorded frames, so a contact can be real and
    never recorded)."""
    ch = f"bodies/{body}/contact_force"
    if ch in res.channels() and bool(np.any(np.linalg.norm(res.series(ch), axis=1) > 0)):
        return True
    if "nodes/positions" not in res.channels():
        return False
    x = res.series("nodes/positions")
    moved = np.linalg.norm(x - x[0], axis=2).max(axis=0)
    return bool(np.any(moved > res.static("nodes/radius")))


if __name__ == "__main__":
    if "--worker" in sys.argv:
        sys.exit(_worker_main())
    print(__doc__)
