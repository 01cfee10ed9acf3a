"""Recorder (writer) and results (reader): round trips, errors, live reading, killed writers.

Every comparison of recorded data is exact (``np.array_equal`` / ``==``): the recorder copies
values into the file and the reader copies them out, no arithmetic happens in between, and the
test values are exactly representable in each channel's dtype (float32 values are float32 to
begin with; ``0.1 * i`` is computed by the same expression in writer and checker).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from engine.errors import BrushStudioError, InstabilityError, RunCancelled
from engine.io.recorder import FORMAT_VERSION, Recorder
from engine.io.results import open_result

REPO = Path(__file__).resolve().parents[2]

SCENE = json.dumps({
    "name": "recorder-test",
    "materials": {"nylon": {"youngs_modulus": 3e9, "density": 1140.0}},
    "run": {"duration": 0.01, "record_interval": 0.001},
})

N_NODES = 5
CHANNELS = {
    "time": ((), "f8"),
    "nodes/positions": ((N_NODES, 3), "f8"),
    "energy/kinetic": ((), "f8"),
    "contacts/bristle_body": ((), "i8"),
    "bonds/bending_moment": ((4,), "f4"),
    "flags/any": ((), "bool"),
    "small/u8": ((2, 3), "u1"),
    "small/i4": ((2,), "i4"),
}


def frame_values(i: int) -> dict:
    """Frame i of the test channels; every value exact in its dtype."""
    return {
        "time": 0.1 * i,
        "nodes/positions": np.arange(N_NODES * 3, dtype=float).reshape(N_NODES, 3) + 1000.0 * i,
        "energy/kinetic": 0.5 * i,
        "contacts/bristle_body": i * 3,
        "bonds/bending_moment": np.arange(4, dtype=np.float32) * np.float32(0.25) - i,
        "flags/any": i % 2 == 1,
        "small/u8": np.full((2, 3), i % 256, dtype=np.uint8),
        "small/i4": np.array([i, -i], dtype=np.int32),
    }


STATIC = {
    "nodes/radius": np.linspace(1e-4, 2e-4, N_NODES),
    "bristles/first_node": np.array([0, N_NODES], dtype=np.int64),
    "bonds/nodes": np.array([[0, 1], [1, 2], [2, 3], [3, 4]], dtype=np.int64),
    "labels": np.array(["root", "tip"]),
}


def new_recorder(path, **kw) -> Recorder:
    kw.setdefault("attrs", {"dt": 1e-6, "brush_names": ["main"], "dt_limited_by": "bond axial"})
    return Recorder(path, SCENE, CHANNELS, STATIC, **kw)


def assert_frames(result, n):
    """Every channel of ``result`` holds exactly frames 0..n-1 of frame_values."""
    for name in CHANNELS:
        got = result.series(name)
        want = np.array([frame_values(i)[name] for i in range(n)],
                        dtype=CHANNELS[name][1]).reshape((n, *CHANNELS[name][0]))
        assert got.dtype == np.dtype(CHANNELS[name][1]), name
        assert np.array_equal(got, want), name


def run_python(code: str, *args, **kw):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code), *map(str, args)],
                          env=env, capture_output=True, text=True, timeout=30, **kw)


# ----------------------------------------------------------------------------- round trip
def test_round_trip_all_dtypes_shapes_attrs_statics(tmp_path):
    path = tmp_path / "run.h5"
    rec = new_recorder(path, flush_every=3)
    for i in range(7):
        rec.append(frame_values(i))
    rec.set_attrs(stages=json.dumps({"build": 0.5}), note="text", count=3, ok=True,
                  table={"a": [1, 2]})
    rec.close("completed", summary={"steps": 70, "wall_s": 1.25, "bad": float("nan")})

    with open_result(path) as r:
        assert r.n_frames == 7  # 7 appended; close commits the last one (7 % 3 != 0)
        assert r.status == "completed" and not r.interrupted
        assert r.channels() == list(CHANNELS)
        assert r.statics() == list(STATIC)
        assert_frames(r, 7)
        assert np.array_equal(r.time, 0.1 * np.arange(7))
        for name, value in STATIC.items():
            got = r.static(name)
            if value.dtype.kind == "U":
                assert list(got) == list(value)
            else:
                assert got.dtype == value.dtype and np.array_equal(got, value), name
        assert r.attrs["format_version"] == FORMAT_VERSION
        assert r.attrs["dt"] == 1e-6 and r.attrs["dt_limited_by"] == "bond axial"
        assert r.json_attr("brush_names") == ["main"]
        assert r.json_attr("stages") == {"build": 0.5}
        assert r.attrs["note"] == "text" and r.attrs["count"] == 3 and r.attrs["ok"] is True
        assert r.json_attr("table") == {"a": [1, 2]}
        assert r.summary == {"steps": 70, "wall_s": 1.25, "bad": "nan"}  # strict JSON
        assert r.error is None
        assert r.scene_json == SCENE
        assert r.scene.name == "recorder-test" and r.scene.run.duration == 0.01
        assert np.array_equal(r.frame("small/i4", 3), [3, -3])
        assert np.array_equal(r.frame("nodes/positions", -1), frame_values(6)["nodes/positions"])
        assert r.frame("contacts/bristle_body", 2) == 6
        assert np.array_equal(r.series("time", slice(1, 6, 2)), 0.1 * np.array([1, 3, 5]))
        assert np.array_equal(r.series("time", slice(None, None, -3)), 0.1 * np.array([6, 3, 0]))
        assert np.array_equal(r.series("contacts/bristle_body", [5, 0, 5]), [15, 0, 15])
    with pytest.raises(BrushStudioError, match="closed"):
        r.series("time")


def test_text_attributes_are_fixed_length_utf8_up_to_32_kib(tmp_path):
    # Fixed-length text lives in the object header, which SWMR keeps consistent; a
    # variable-length string's global-heap entry can dangle after a kill (docs/results.md).
    path = tmp_path / "t.h5"
    long_text = "x" * 40_000  # over 32 KiB: stored variable-length, still round-trips
    with Recorder(path, SCENE, {"time": ((), "f8")}, {}) as rec:
        rec.set_attrs(unit="µm → m", stages={"contacts": 0.25}, long=long_text)
        rec.close("completed", summary={"wall_s": 2.0})
    with h5py.File(path, "r") as f:
        for name in ("format", "scene", "status", "unit", "stages", "summary"):
            assert not f.attrs.get_id(name).get_type().is_variable_str(), name
        assert f.attrs.get_id("long").get_type().is_variable_str()
    with open_result(path) as r:
        assert r.attrs["unit"] == "µm → m" and r.attrs["long"] == long_text
        assert r.json_attr("stages") == {"contacts": 0.25} and r.summary == {"wall_s": 2.0}


def test_chunks_are_about_a_mebibyte_for_big_rows_and_bounded_for_scalars(tmp_path):
    n = 20_000  # a row of (n, 3) float64 is 480 kB: 2 rows make a ~1 MiB chunk
    with Recorder(tmp_path / "c.h5", SCENE, {"time": ((), "f8"), "p": ((n, 3), "f8")}, {}) as rec:
        rec.append({"time": 0.0, "p": np.zeros((n, 3))})
        assert rec._datasets["p"].chunks == (2, n, 3)
        assert rec._datasets["time"].chunks == (1024,)


def test_zero_frames_and_empty_rows(tmp_path):
    path = tmp_path / "empty.h5"
    with Recorder(path, SCENE, {"time": ((), "f8"), "nodes/positions": ((0, 3), "f8")}, {}) as rec:
        pass
    with open_result(path) as r:
        assert r.n_frames == 0 and r.status == "completed"
        assert r.time.shape == (0,) and r.series("nodes/positions").shape == (0, 0, 3)
        with pytest.raises(IndexError):
            r.frame("time", 0)
    path2 = tmp_path / "rows0.h5"
    with Recorder(path2, SCENE, {"time": ((), "f8"), "nodes/positions": ((0, 3), "f8")}, {}) as rec:
        rec.append({"time": 1.5, "nodes/positions": np.zeros((0, 3))})
    with open_result(path2) as r:
        assert r.n_frames == 1 and r.series("nodes/positions").shape == (1, 0, 3)


# ----------------------------------------------------------------------------- writer errors
def test_bad_frames_name_the_channel_and_write_nothing(tmp_path):
    rec = new_recorder(tmp_path / "bad.h5")
    rec.append(frame_values(0))
    bad = frame_values(1)
    bad["nodes/positions"] = np.zeros((N_NODES, 2))
    with pytest.raises(ValueError, match=r"'nodes/positions'.*shape \(5, 2\), expected \(5, 3\)"):
        rec.append(bad)
    missing = frame_values(1)
    del missing["energy/kinetic"]
    with pytest.raises(ValueError, match=r"missing channels \['energy/kinetic'\]"):
        rec.append(missing)
    with pytest.raises(ValueError, match=r"unknown channels \['extra'\]"):
        rec.append({**frame_values(1), "extra": 1.0})
    floaty = frame_values(1)
    floaty["contacts/bristle_body"] = 2.5  # a float into an int64 count is refused
    with pytest.raises(ValueError, match="'contacts/bristle_body'.*does not cast safely"):
        rec.append(floaty)
    scalar_as_vector = frame_values(1)
    scalar_as_vector["time"] = [0.1]
    with pytest.raises(ValueError, match=r"'time'.*shape \(1,\), expected \(\)"):
        rec.append(scalar_as_vector)
    rec.close("completed")
    with open_result(tmp_path / "bad.h5") as r:
        assert r.n_frames == 1  # none of the bad frames left a row
        assert_frames(r, 1)
        for name in CHANNELS:
            assert r._file[name].shape[0] == 1, name


def test_reserved_attributes_and_bad_arguments_are_refused(tmp_path):
    with pytest.raises(ValueError, match="n_frames"):
        Recorder(tmp_path / "a.h5", SCENE, {"time": ((), "f8")}, {}, attrs={"n_frames": 3})
    with pytest.raises(ValueError, match="flush_every"):
        Recorder(tmp_path / "b.h5", SCENE, {"time": ((), "f8")}, {}, flush_every=0)
    with pytest.raises(ValueError, match="both as channel and static"):
        Recorder(tmp_path / "c.h5", SCENE, {"x": ((), "f8")}, {"x": np.zeros(2)})
    with Recorder(tmp_path / "d.h5", SCENE, {"time": ((), "f8")}, {}) as rec:
        with pytest.raises(ValueError, match="status"):
            rec.set_attrs(status="completed")
        with pytest.raises(ValueError, match="status must be one of"):
            rec.close("finished")


def test_close_is_idempotent_and_final(tmp_path):
    path = tmp_path / "c.h5"
    rec = new_recorder(path)
    rec.append(frame_values(0))
    rec.close("stopped", summary={"reason": "kinetic_energy"})
    rec.close("failed", error={"message": "ignored"})  # no effect, no error
    assert rec.closed
    with pytest.raises(ValueError, match="closed"):
        rec.append(frame_values(1))
    with open_result(path) as r:
        assert r.status == "stopped" and r.summary == {"reason": "kinetic_energy"}
        assert r.error is None and r.n_frames == 1


# ----------------------------------------------------------------------------- context manager
def test_context_manager_marks_failed_and_keeps_frames(tmp_path):
    path = tmp_path / "f.h5"
    with pytest.raises(InstabilityError):
        with new_recorder(path, flush_every=10) as rec:
            for i in range(3):
                rec.append(frame_values(i))
            raise InstabilityError("bond strain", "bristle 4 node 7", 0.25, "reduce dt")
    with open_result(path) as r:
        assert r.status == "failed" and not r.interrupted
        assert r.n_frames == 3  # uncommitted (flush_every=10) frames are committed by close
        assert_frames(r, 3)
        assert r.error["type"] == "InstabilityError"
        assert r.error["quantity"] == "bond strain" and r.error["where"] == "bristle 4 node 7"
        assert "Traceback" in r.error["traceback"]


def test_context_manager_cancelled_and_completed(tmp_path):
    with pytest.raises(RunCancelled):
        with new_recorder(tmp_path / "x.h5") as rec:
            rec.append(frame_values(0))
            raise RunCancelled("cancel flag set")
    with new_recorder(tmp_path / "y.h5") as rec:
        rec.append(frame_values(0))
    with open_result(tmp_path / "x.h5") as x, open_result(tmp_path / "y.h5") as y:
        assert (x.status, x.n_frames, x.error["type"]) == ("cancelled", 1, "RunCancelled")
        assert (y.status, y.n_frames) == ("completed", 1)


# ----------------------------------------------------------------------------- live reading
def test_read_while_writer_is_open_same_process(tmp_path):
    path = tmp_path / "live.h5"
    rec = new_recorder(path)
    for i in range(4):
        rec.append(frame_values(i))
    r = open_result(path)
    assert r.n_frames == 4 and r.status == "running" and r.interrupted
    assert_frames(r, 4)
    for i in range(4, 6):
        rec.append(frame_values(i))
    assert r.n_frames == 4  # a snapshot until refresh()
    r.refresh()
    assert r.n_frames == 6
    assert_frames(r, 6)
    r.close()  # closing the reader must not disturb the writer
    rec.append(frame_values(6))
    rec.close("completed")
    with open_result(path) as r:
        assert r.n_frames == 7 and r.status == "completed"
        assert_frames(r, 7)


def test_series_never_returns_uncommitted_rows(tmp_path):
    path = tmp_path / "tail.h5"
    rec = new_recorder(path, flush_every=4)
    for i in range(4):  # committed
        rec.append(frame_values(i))
    # a writer killed inside a commit, after its rows reached the datasets and before it
    # bumped n_frames: 2 rows written but not counted
    for name, ds in rec._datasets.items():
        ds.resize(6, axis=0)
        ds[4:6] = np.stack([np.asarray(frame_values(i)[name], ds.dtype) for i in (4, 5)])
    rec._file.flush()
    with open_result(path) as r:
        assert r._file["time"].shape[0] == 6  # the rows exist in the dataset...
        assert r.n_frames == 4                 # ...but only committed ones are shown
        assert r.series("time").shape == (4,)
        assert r.series("nodes/positions", slice(0, 100)).shape == (4, N_NODES, 3)
        assert r.series("time", slice(3, None)).shape == (1,)
        with pytest.raises(IndexError):
            r.frame("time", 4)
        with pytest.raises(IndexError):
            r.series("time", [5])
    rec.close("completed")


READER = """
    import json, sys
    from engine.io.results import open_result
    with open_result(sys.argv[1]) as r:
        print(json.dumps({"n": r.n_frames, "status": r.status, "interrupted": r.interrupted,
                          "time": r.time.tolist(),
                          "contacts": r.series("contacts/bristle_body").tolist()}))
"""


def test_read_while_writer_is_open_from_another_process(tmp_path):
    path = tmp_path / "live2.h5"
    rec = new_recorder(path)
    for i in range(5):
        rec.append(frame_values(i))
    out = run_python(READER, path)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got == {"n": 5, "status": "running", "interrupted": True,
                   "time": [0.1 * i for i in range(5)], "contacts": [3 * i for i in range(5)]}
    rec.close("completed")


# ----------------------------------------------------------------------------- killed writer
WRITER = """
    import sys, time
    sys.path.insert(0, sys.argv[2])
    from engine.io.recorder import Recorder
    from tests.engine.test_recorder import new_recorder, frame_values
    rec = new_recorder(sys.argv[1], flush_every=3)
    i = 0
    while True:  # until SIGKILLed
        rec.append(frame_values(i))
        i += 1
        time.sleep(0.002)
"""


def test_sigkilled_writer_leaves_a_readable_file(tmp_path):
    path = tmp_path / "killed.h5"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(WRITER), str(path), str(REPO)],
                            env=env, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 15
        seen = []
        while True:  # poll with the reader while the writer writes
            assert time.monotonic() < deadline, "writer did not reach 5 frames"
            assert proc.poll() is None, proc.stderr.read()
            if path.exists():
                try:
                    with open_result(path) as live:
                        seen.append(live.n_frames)
                        assert_frames(live, live.n_frames)
                except BrushStudioError:
                    pass  # the file is being created (before SWMR mode starts)
                if seen and seen[-1] >= 5:
                    break
            time.sleep(0.01)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    assert seen == sorted(seen)  # n_frames only grows

    with open_result(path) as r:
        assert r.status == "running" and r.interrupted
        assert r.n_frames >= 5 and r.n_frames % 3 == 0  # commits happen every 3 frames
        assert r.n_frames >= seen[-1]
        assert r._file["time"].shape[0] >= r.n_frames  # rows past n_frames may exist: hidden
        assert_frames(r, r.n_frames)
        assert np.array_equal(r.time, 0.1 * np.arange(r.n_frames))
        assert r.scene.name == "recorder-test" and r.json_attr("brush_names") == ["main"]
        assert r.summary is None and r.error is None


def test_writer_killed_while_creating_the_file_leaves_the_old_file_intact(tmp_path):
    # The file is built under a temporary name and renamed into place once in SWMR mode;
    # kill the writer at the last moment before that rename: the target keeps its old file.
    path = tmp_path / "run.h5"
    with new_recorder(path) as rec:
        rec.append(frame_values(0))
    code = """
        import os, signal, sys
        import engine.io.recorder as recorder
        from tests.engine.test_recorder import new_recorder
        recorder.os.replace = lambda *a: os.kill(os.getpid(), signal.SIGKILL)
        new_recorder(sys.argv[1])
    """
    assert run_python(code, path).returncode == -signal.SIGKILL
    with open_result(path) as r:  # the previous, finished run
        assert r.status == "completed" and r.n_frames == 1
    leftover = tmp_path / ".run.h5.creating"  # what the killed writer leaves: no frames
    with open_result(leftover) as r:
        assert r.n_frames == 0 and r.interrupted


def test_file_left_open_for_writing_outside_swmr_gives_a_clear_error(tmp_path):
    # A latest-format file whose (non-SWMR) writer died is marked "open for write" and HDF5
    # refuses to open it; the recorder never leaves one, but the reader must say what it is.
    path = tmp_path / "half.h5"
    code = """
        import os, signal, sys, h5py
        f = h5py.File(sys.argv[1], "w", libver="latest")
        f.attrs["format"] = "brush-studio-result"
        f.flush()
        os.kill(os.getpid(), signal.SIGKILL)
    """
    assert run_python(code, path).returncode == -signal.SIGKILL
    with pytest.raises(BrushStudioError, match="open-for-writing.*h5clear"):
        open_result(path)


def test_failure_while_creating_removes_the_temporary_file(tmp_path):
    with pytest.raises(ValueError, match="static 'bad'"):
        Recorder(tmp_path / "x.h5", SCENE, {"time": ((), "f8")}, {"bad": np.array([object()])})
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- reader errors
def test_reader_rejects_missing_foreign_and_newer_files(tmp_path):
    with pytest.raises(BrushStudioError, match="does not exist"):
        open_result(tmp_path / "nope.h5")
    text = tmp_path / "text.h5"
    text.write_text("not hdf5")
    with pytest.raises(BrushStudioError, match="not a readable HDF5 file"):
        open_result(text)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(BrushStudioError, match="not a Brush Studio result"):
        open_result(foreign)
    newer = tmp_path / "newer.h5"
    with new_recorder(newer) as rec:
        rec.append(frame_values(0))
    with h5py.File(newer, "r+") as f:
        f.attrs["format_version"] = FORMAT_VERSION + 1
    with pytest.raises(BrushStudioError, match=f"format_version {FORMAT_VERSION + 1}"):
        open_result(newer)


def test_reader_names_unknown_channels_and_statics(tmp_path):
    path = tmp_path / "n.h5"
    with new_recorder(path) as rec:
        rec.append(frame_values(0))
    with open_result(path) as r:
        with pytest.raises(BrushStudioError, match="no channel 'nodes/velocity'"):
            r.series("nodes/velocity")
        with pytest.raises(BrushStudioError, match="no static 'nodes/positions'"):
            r.static("nodes/positions")


STEPPED_WRITER = """
    import sys, time
    from pathlib import Path
    sys.path.insert(0, sys.argv[2])
    from tests.engine.test_recorder import new_recorder, frame_values
    rec = new_recorder(sys.argv[1], flush_every=1)
    for i in range(3):
        rec.append(frame_values(i))
    Path(sys.argv[1] + ".first").touch()
    while not Path(sys.argv[1] + ".go").exists():
        time.sleep(0.01)
    for i in range(3, 7):
        rec.append(frame_values(i))
    rec.close("completed")
"""


def test_refresh_sees_frames_another_process_wrote_since(tmp_path):
    path = tmp_path / "stepped.h5"
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(STEPPED_WRITER), str(path),
                             str(REPO)], env=dict(os.environ, PYTHONPATH=str(REPO)))
    try:
        deadline = time.time() + 30
        while not Path(str(path) + ".first").exists():
            assert time.time() < deadline and proc.poll() is None
            time.sleep(0.01)
        res = open_result(path)
        assert (res.n_frames, res.status) == (3, "running")
        Path(str(path) + ".go").touch()
        assert proc.wait(timeout=30) == 0
        res.refresh()  # the same object, no new open_result
        assert (res.n_frames, res.status) == (7, "completed")
        assert_frames(res, 7)
        res.close()
    finally:
        proc.kill()


def test_rows_wait_in_memory_until_a_commit_by_count_size_or_time(tmp_path, monkeypatch):
    """The run loop's policy: rows are written at a commit only, which comes after
    ``flush_every`` frames, once the waiting rows hold ``buffer_bytes``, or ``commit_seconds``
    after the last commit; what was appended is what is written, even if the caller reuses
    its arrays."""
    import engine.io.recorder as recorder_module

    clock = [100.0]
    monkeypatch.setattr(recorder_module.time, "monotonic", lambda: clock[0])

    def committed(path):
        with open_result(path) as r:
            return r.n_frames, r._file["time"].shape[0]

    # by time: nothing reaches the file before commit_seconds have passed (the run loop's
    # flush_every=None: never by count)
    path = tmp_path / "time.h5"
    rec = new_recorder(path, flush_every=None, commit_seconds=1.0)
    reused = frame_values(0)
    for i in range(3):
        fr = frame_values(i)
        reused["nodes/positions"][:] = fr["nodes/positions"]  # one array, refilled each frame
        rec.append({**fr, "nodes/positions": reused["nodes/positions"]})
    assert committed(path) == (0, 0)
    clock[0] += 1.0
    rec.append(frame_values(3))
    assert committed(path) == (4, 4)
    rec.close("completed")
    with open_result(path) as r:
        assert_frames(r, 4)  # each frame's own positions, not the reused array's last ones

    # by size: two frames' worth of bytes commit every second frame
    path = tmp_path / "size.h5"
    one = sum(np.asarray(v).nbytes for v in frame_values(0).values())
    rec = new_recorder(path, flush_every=1000, buffer_bytes=2 * one)
    rec.append(frame_values(0))
    assert committed(path) == (0, 0)
    rec.append(frame_values(1))
    assert committed(path) == (2, 2)
    rec.close("completed")

    with pytest.raises(ValueError, match="commit_seconds"):
        new_recorder(tmp_path / "bad.h5", commit_seconds=0.0)
