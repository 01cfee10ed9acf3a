"""Force against depth of a wedge pressed into a brush
=====================================================

The 60 degree wedge of the seed's experiment (``static_presets/wedge_60.json``, seed 4.2)
pressed in 1 mm parabolic steps into a smaller, coarser brush than the preset's (9 x 5
bristles of 5 nodes, 4 steps, loading only), so that it runs in seconds. The run writes an
HDF5 result file; ``engine.open_result`` reads it back: the wedge's position gives the depth,
its contact force the load the brush puts on it. The curve is plotted to a PNG and the force
at the end of each step's dwell is printed.

This is the preset's dynamic protocol (a 50 ms dwell after each step), so the printed
forces still carry some of the bristles' ringing; ``brush-studio study wedge`` holds each
step until the brush is in equilibrium (docs/studies.md).

Run it from the repository root, with the package installed (``pip install -e .``)::

    python examples/02_force_depth.py [OUT_DIR]

It writes ``OUT_DIR/wedge.h5`` and ``OUT_DIR/force_depth.png`` (default OUT_DIR:
``./example_output/02_force_depth``); an existing ``wedge.h5`` from an earlier run is read
again rather than recomputed.
"""
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")   # write files only, no window
import matplotlib.pyplot as plt
import numpy as np

import engine

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "example_output/02_force_depth")
out_dir.mkdir(parents=True, exist_ok=True)
h5_path = out_dir / "wedge.h5"
preset = Path(__file__).resolve().parents[1] / "static_presets" / "wedge_60.json"

# The preset, made smaller: edit its dict and validate it again.
scene_dict = json.loads(engine.load_scene(preset).to_json())
brush = scene_dict["brushes"][0]
brush.update(rows=9, columns=5, n_nodes=5)
profile = scene_dict["bodies"][0]["motion"]["profile"]   # the wedge's stepped_parabolic
profile.update(n_steps=4, unload=False)
step_time = (6 * profile["step"] / profile["max_acceleration"]) ** 0.5  # seed eq. 4.3: t_d
scene_dict["run"]["duration"] = profile["n_steps"] * (step_time + profile["dwell"])
scene_dict["run"]["record_interval"] = 0.005
scene = engine.parse_scene(scene_dict)

# Run it, unless a finished result of this very scene is already there.
reuse = False
if h5_path.exists():
    try:
        with engine.open_result(h5_path) as res:
            reuse = res.status == "completed" and res.scene == scene
    except engine.BrushStudioError:
        reuse = False
if reuse:
    print(f"reusing {h5_path}")
else:
    system = engine.build(scene)
    result = engine.run(system, output=h5_path)
    print(f"ran {result.summary['steps']} steps of {result.summary['dt']:.3g} s "
          f"in {result.summary['wall_s']:.1f} s wall: {result.status}")

with engine.open_result(h5_path) as res:
    t = res.time                                           # (n_frames,) s
    z = res.series("bodies/wedge/position")[:, 2]          # (n_frames,) m
    force = res.series("bodies/wedge/contact_force")[:, 2]  # bristles pushing the wedge up, N
depth = z[0] - z                                           # m, positive into the brush

# The force at the end of each step's dwell: the last frame at each whole-millimetre depth.
step = profile["step"]
ends = [np.flatnonzero(np.abs(depth - k * step) < 1e-3 * step)[-1]
        for k in range(1, profile["n_steps"] + 1)]
for i in ends:
    print(f"depth {depth[i] * 1e3:.2f} mm (t = {t[i]:.3f} s): force {force[i]:.6g} N")

fig, ax = plt.subplots(figsize=(6, 4))
ax.plot(depth * 1e3, force * 1e3, label="during the run")
ax.plot(depth[ends] * 1e3, force[ends] * 1e3, "o", label="end of each dwell")
ax.set_xlabel("wedge depth [mm]")
ax.set_ylabel("vertical force on the wedge [mN]")
ax.set_title("60 deg wedge, 9 x 5 brush, 5 nodes per bristle")
ax.legend()
fig.tight_layout()
fig.savefig(out_dir / "force_depth.png", dpi=120)
print(f"wrote {out_dir / 'force_depth.png'}")
