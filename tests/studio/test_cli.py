"""The ``brush-studio`` command line, called in-process through ``studio.cli.main`` (fast)
and once through the installed console script."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import engine
import studio
from studio.cli.main import main

SUMMARY_KEYS = {"dt", "dt_limited_by", "steps", "wall_s", "node_steps_per_s", "stages",
                "status"}


def test_run_tiny_scene_writes_result_and_summary(tiny_scene, write_scene, tmp_path, capsys):
    scene = write_scene(tiny_scene())
    out, summary_path = tmp_path / "out" / "tiny.h5", tmp_path / "tiny-summary.json"
    # --parents: the output's folder does not exist yet (refused without it, issue 28)
    code = main(["run", str(scene), "-o", str(out), "--summary", str(summary_path),
                 "--parents"])
    printed = capsys.readouterr().out
    assert code == 0
    with engine.open_result(out) as res:
        assert res.status == "completed"
        # 4 ms recorded every 0.5 ms (rounded to whole steps), the frame at t = 0 and one at
        # the end
        assert res.n_frames in (9, 10)
        assert (res.time[1:] > res.time[:-1]).all()
        assert res.time[-1] == pytest.approx(0.004, rel=1e-3)  # within one dt of the end
    summary = json.loads(summary_path.read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["status"] == "completed"
    assert summary["steps"] > 0 and summary["node_steps_per_s"] > 0
    assert summary["dt"] > 0 and isinstance(summary["dt_limited_by"], str)
    assert set(summary["stages"]) >= {"bonds", "bristle_body"}
    assert Path(summary["result"]) == out
    # the summary table names the numbers a user looks for
    for word in ("completed", "dt", "limited by", "steps", "wall time", "node-steps/s",
                 "stages", "bristle_body", "warnings"):
        assert word in printed, word


def test_run_quiet_prints_one_line(tiny_scene, write_scene, tmp_path, capsys):
    out = tmp_path / "q.h5"
    assert main(["run", str(write_scene(tiny_scene())), "-o", str(out), "--quiet",
                 "--until", "0.001"]) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == f"completed: {out}"
    assert "simulating" not in captured.err  # no progress bar
    with engine.open_result(out) as res:
        assert res.time[-1] == pytest.approx(0.001, rel=1e-2)  # --until, not run.duration


def test_validate_ok_describes_the_scene(tiny_scene, write_scene, capsys):
    assert main(["validate", str(write_scene(tiny_scene()))]) == 0
    out = capsys.readouterr().out
    assert out.startswith("OK")
    assert "1 brush," in out and "4 bristles" in out and "16 nodes" in out and "1 body" in out


def test_validate_bad_scene_names_every_field(tiny_scene, write_scene, capsys):
    scene = tiny_scene()
    scene["brushes"][0]["root_radius"] = -0.001
    scene["materials"]["pla"]["density"] = 0.0
    assert main(["validate", str(write_scene(scene))]) == 2
    err = capsys.readouterr().err
    assert "brushes.0.root_radius = -0.001" in err
    assert "materials.pla.density = 0.0" in err
    # one problem per line: field = value: allowed
    lines = [ln.strip() for ln in err.splitlines() if " = " in ln]
    assert len(lines) == 2 and all(": " in ln for ln in lines)


def test_run_bad_input_exits_2(tiny_scene, write_scene, tmp_path, capsys):
    scene = tiny_scene()
    scene["brushes"][0]["root_radius"] = -0.001
    out = tmp_path / "never.h5"
    assert main(["run", str(write_scene(scene)), "-o", str(out)]) == 2
    assert "brushes.0.root_radius" in capsys.readouterr().err
    assert not out.exists()
    assert main(["run", str(tmp_path / "missing.json"), "-o", str(out)]) == 2
    assert "missing.json" in capsys.readouterr().err


def test_run_unstable_scene_exits_1_and_keeps_frames(tiny_scene, write_scene, tmp_path,
                                                     capsys):
    dt_stable = engine.build(engine.parse_scene(tiny_scene())).dt_stable
    dt = 100 * dt_stable
    # the engine caps dt at record_interval: record every step so the 100x dt is used
    scene = tiny_scene(dt=dt, record_interval=dt, duration=20 * dt)
    out, summary_path = tmp_path / "unstable.h5", tmp_path / "unstable.json"
    code = main(["run", str(write_scene(scene)), "-o", str(out), "--summary",
                 str(summary_path)])
    captured = capsys.readouterr()
    assert code == 1
    assert "instability" in captured.err
    assert "warning:" in captured.err  # build warned that run.dt exceeds the limit
    with engine.open_result(out) as res:
        assert res.status == "failed"
        assert res.n_frames >= 1  # at least the frame at t = 0 is kept
        assert "instability" in res.error["message"]
    summary = json.loads(summary_path.read_text())
    assert summary["status"] == "failed"
    assert "instability" in summary["error"]["message"]
    assert SUMMARY_KEYS <= set(summary)


def test_info_prints_status_and_channels(tiny_scene, write_scene, tmp_path, capsys):
    out = tmp_path / "info.h5"
    assert main(["run", str(write_scene(tiny_scene())), "-o", str(out), "-q"]) == 0
    capsys.readouterr()
    with engine.open_result(out) as res:
        n_frames = res.n_frames
    assert main(["info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "status    completed" in printed
    assert f"frames    {n_frames}\n" in printed
    assert "brushes/brush/root_force  [3]" in printed
    assert "node-steps/s" in printed  # the summary table


def test_info_on_missing_file_exits_2(tmp_path, capsys):
    assert main(["info", str(tmp_path / "nope.h5")]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_and_sigterm_cancel_cleanly(sig, tiny_scene, write_scene, tmp_path, capsys):
    # 10 s simulated would take minutes; the cancel must end it within a chunk
    scene = write_scene(tiny_scene(duration=10.0, record_interval=0.001))
    out = tmp_path / "cancel.h5"

    def interrupt_when_running():
        deadline = time.monotonic() + 120  # allows for numba compiling on a cold cache
        while not out.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.3)
        os.kill(os.getpid(), sig)

    # a terminal's default handlers (an earlier test in this worker process may have left
    # SIGINT ignored: a cold CI run found SIG_IGN here), put back as found at the end
    found = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threading.Thread(target=interrupt_when_running, daemon=True).start()
    t0 = time.monotonic()
    try:
        code = main(["run", str(scene), "-o", str(out)])
        # the CLI put the default handlers back
        restored = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    finally:
        for s, h in found.items():
            signal.signal(s, h)
    assert restored == (signal.default_int_handler, signal.SIG_DFL)
    assert code == 130
    assert time.monotonic() - t0 < 150
    assert "cancelling" in capsys.readouterr().err
    with engine.open_result(out) as res:
        assert res.status == "cancelled"
        assert 0 < res.time[-1] < 10.0


def test_console_script_version():
    exe = Path(sys.executable).with_name("brush-studio")
    cmd = str(exe) if exe.exists() else shutil.which("brush-studio")
    assert cmd, "the brush-studio console script is not installed (pip install -e .)"
    proc = subprocess.run([cmd, "--version"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"brush-studio {studio.__version__}"
    proc = subprocess.run([sys.executable, "-m", "studio.cli", "--version"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip().startswith("brush-studio ")


def test_bad_command_line_exits_2(capsys):
    assert main(["run"]) == 2
    assert "usage" in capsys.readouterr().err


@pytest.mark.slow
def test_demo_writes_result_summary_and_plot(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    h5, summary, png = out / "demo.h5", out / "summary.json", out / "root_force.png"
    for f in (h5, summary, png):
        assert f.is_file(), f
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    with engine.open_result(h5) as res:
        assert res.status == "completed"
    assert json.loads(summary.read_text())["status"] == "completed"
    assert f"open {png}" in printed and "engine.open_result" in printed
