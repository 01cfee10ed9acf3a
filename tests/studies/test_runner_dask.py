"""The Dask layer: a real scheduler and two worker processes (the ``dask`` CLI), a small sweep
through them, a failing run reported with its parameters, and a restart that skips what is
complete."""
from __future__ import annotations

import json

import pytest

import engine
from sweeps import modulus_sweep
from studio.studies.run_files import failures_text, run_paths
from studio.studies.runner import RunSpec, run_many

MODULI = (2.0e6, 2.7e6, 3.5e6)


def _sweep(tiny_scene) -> list[RunSpec]:
    return modulus_sweep(tiny_scene, MODULI)


def test_sweep_on_external_dask_cluster(dask_cluster, tiny_scene, tmp_path):
    addr, procs = dask_cluster
    out = tmp_path / "study"
    specs = _sweep(tiny_scene)
    outcomes = run_many(specs, out, scheduler=addr, progress=False)

    assert [o.run_id for o in outcomes] == [s.run_id for s in specs]
    good, bad = outcomes[:3], outcomes[3]
    assert all(o.status == "completed" and not o.skipped for o in good)
    forces = []
    for o in good:
        with engine.open_result(o.h5) as res:  # each task wrote its own HDF5
            assert res.status == "completed"
            forces.append(res.series("brushes/brush/root_force")[-1, 2])
        assert o.summary["root_force_z.brush"] == pytest.approx(forces[-1])
    # the box compresses the bristles by a fixed 0.8 mm, slowly against their axial period:
    # the force scales with the stiffness, i.e. with E (bond and contact stiffness both ∝ E);
    # 5 % leaves room for the small dynamic part of the force
    for o, f in zip(good[1:], forces[1:]):
        E = o.params["youngs_modulus"]
        assert f / forces[0] == pytest.approx(E / MODULI[0], rel=0.05)

    assert bad.status == "failed" and bad.params == {"youngs_modulus": "broken radius"}
    assert "root_radius" in bad.error
    text = failures_text(outcomes)
    assert "bad: failed" in text and "broken radius" in text and "E0" not in text
    stored = json.loads(run_paths(out, "bad")[1].read_text())
    assert stored["status"] == "failed" and stored["params"] == bad.params

    # restart: completed runs are skipped, the failed one runs again; a run whose outcome
    # file is gone (killed before it was written) runs again too
    run_paths(out, "E2")[1].unlink()
    again = run_many(specs, out, scheduler=addr, progress=False)
    assert [o.skipped for o in again] == [True, True, False, False]
    assert [o.status for o in again] == ["completed"] * 3 + ["failed"]
    assert again[0].summary == good[0].summary

    # a changed scene is not mistaken for the finished run of the same id
    specs[0].scene["materials"]["silicone"]["youngs_modulus"] = 3.0e6
    third = run_many(specs[:1], out, scheduler=addr, progress=False)
    assert not third[0].skipped and third[0].status == "completed"
    assert all(p.poll() is None for p in procs)  # the cluster is still up: run_many left it


def test_run_ids_are_checked(tmp_path, tiny_scene):
    with pytest.raises(ValueError, match="run_id"):
        run_many([RunSpec("../escape", tiny_scene())], tmp_path, progress=False)
    with pytest.raises(ValueError, match="unique"):
        run_many([RunSpec("a", tiny_scene()), RunSpec("a", tiny_scene())], tmp_path,
                 progress=False)


def test_a_script_without_a_main_guard_is_told_why_dask_cannot_start(tmp_path):
    """Dask spawns its local workers, and each imports the calling script again: a script that
    runs a study at import time makes them fail to start. The error must say so (Dask's own
    is "Nanny failed to start."): catches the hint being lost or the guard advice being wrong."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    script = tmp_path / "no_guard.py"
    script.write_text(
        "import json\n"
        "from studio.presets import preset_path\n"
        "from studio.studies.runner import RunSpec, run_many\n"
        "scene = json.loads(preset_path('rod_weight_static').read_text())\n"
        "scene['brushes'][0]['n_nodes'] = 3\n"
        "scene['run']['duration'] = 0.01\n"
        "run_many([RunSpec(run_id=f'r{i}', scene=scene, params={}) for i in range(2)],\n"
        f"         {str(tmp_path / 'out')!r}, n_workers=2, progress=False)\n")
    env = dict(os.environ, PYTHONPATH=str(root))
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0
    assert 'if __name__ == "__main__":' in proc.stderr, proc.stderr[-2000:]
