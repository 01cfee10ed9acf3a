"""A chaser's brush detumbles a spinning upper stage (shortened)
===============================================================

The mission preset ``static_presets/detumble_upper_stage.json`` (docs/mission.md): a
130 kg cylindrical upper stage spins at 10 deg/s in a 400 km orbit; a chaser, held at a
fixed offset by its controller, rubs the stage's side with a silicone brush until the spin
is gone. The preset costs about a minute of CPU (85 bristles, detumbled at 11.2 s); this
example keeps its bodies, orbit and controller but gives the brush 2 x 17 bristles of 3
nodes and runs 4 s: the approach, the first touch (at about 0.8 s) and the start of the
spin-down. It prints the stage's angular speed |omega| against time and the change over
the run.
``brush-studio study detumble`` sweeps such runs (spin rate, target size, brush design).

Run it from the repository root, with the package installed (``pip install -e .``)::

    python examples/05_mission_detumble.py [OUT_DIR]

It writes ``OUT_DIR/detumble.h5`` and ``OUT_DIR/omega.csv`` (time, |omega| in deg/s;
default OUT_DIR: ``./example_output/05_mission_detumble``).
"""
import json
import sys
from pathlib import Path

import numpy as np

import engine

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "example_output/05_mission_detumble")
out_dir.mkdir(parents=True, exist_ok=True)
preset = Path(__file__).resolve().parents[1] / "static_presets" / "detumble_upper_stage.json"

# The preset with a smaller, coarser brush and a shorter run.
scene_dict = json.loads(engine.load_scene(preset).to_json())
for brush in scene_dict["brushes"]:
    brush.update(rows=2, columns=17, n_nodes=3)
scene_dict["run"].update(duration=4.0, record_interval=0.05)
scene_dict["run"]["channels"] = ["bodies", "root_force"]   # what this example reads
scene = engine.parse_scene(scene_dict)

system = engine.build(scene)
print(f"{system.n_bristles} bristles, {system.n_nodes} nodes, dt {system.dt:.3g} s "
      f"({system.dt_limited_by})")
result = engine.run(system, output=out_dir / "detumble.h5")
print(f"{result.status}: {result.summary['steps']} steps, {result.summary['wall_s']:.1f} s wall")

with engine.open_result(result.path) as res:
    t = res.time
    omega = res.series("bodies/target/angular_velocity")   # (n_frames, 3) rad/s, world
speed_deg = np.degrees(np.linalg.norm(omega, axis=1))
np.savetxt(out_dir / "omega.csv", np.column_stack([t, speed_deg]), delimiter=",",
           header="time_s,omega_deg_per_s", comments="")

print(f"{'t [s]':>6} {'|omega| [deg/s]':>16}")
for ti in np.arange(0.0, t[-1] + 1e-9, 0.5):
    i = int(np.argmin(np.abs(t - ti)))
    print(f"{t[i]:6.2f} {speed_deg[i]:16.4f}")
print(f"|omega| from {speed_deg[0]:.4f} to {speed_deg[-1]:.4f} deg/s "
      f"({speed_deg[-1] - speed_deg[0]:+.4f}) in {t[-1]:.2f} s")
