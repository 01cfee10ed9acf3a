"""Bad output paths (issue 13, item 8): one clear line and exit code 2, before anything
runs, never a traceback; an unwritable --summary is found before the run, not after it."""
from __future__ import annotations

import time

import pytest

from studio.cli.main import main


@pytest.mark.parametrize("case", ["under_a_file", "proc", "a_directory", "summary"])
def test_a_bad_output_path_is_one_line_and_exit_2(case, tmp_path, write_scene, tiny_scene,
                                                  capsys):
    scene = str(write_scene(tiny_scene()))
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    output, extra = str(tmp_path / "run.h5"), []
    if case == "under_a_file":
        output = str(a_file / "run.h5")
    elif case == "proc":
        output = "/proc/run.h5"
    elif case == "a_directory":
        output = str(tmp_path)
    else:
        extra = ["--summary", str(a_file / "summary.json")]
    t0 = time.perf_counter()
    code = main(["run", scene, "-o", output, "-q", *extra])
    err = capsys.readouterr().err
    assert code == 2, err
    assert time.perf_counter() - t0 < 5.0  # checked before the run (no build, no compile)
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert ("--summary" if case == "summary" else "-o/--output") in err
    assert not (tmp_path / "run.h5").exists()  # the probe leaves nothing behind


def test_demo_into_a_file_is_exit_2(tmp_path, capsys):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    assert main(["demo", "-o", str(a_file)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "-o/--output" in err


# ------------------------------------------------- issue 28, items 1 and 9: special files
def _run_cli(args, timeout=120):
    """The CLI in a subprocess with a time limit: opening a named pipe for writing blocks
    for ever, which in-process would hang the test run instead of failing it."""
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "studio.cli", *args], capture_output=True,
                          text=True, timeout=timeout)


@pytest.mark.parametrize("which", ["output", "summary", "demo"])
def test_a_named_pipe_is_refused_before_the_run(which, tmp_path, write_scene, tiny_scene):
    # bug caught: `-o FIFO` hung for ever opening the pipe; `-o /dev/full` (a device: a FIFO
    # stands in for it here) exited 0 with the device node replaced by an HDF5 file
    import os
    import stat

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    scene = str(write_scene(tiny_scene()))
    args = {"output": ["run", scene, "-o", str(fifo), "-q"],
            "summary": ["run", scene, "-o", str(tmp_path / "r.h5"), "--summary", str(fifo),
                        "-q"],
            "demo": ["demo", "-o", str(fifo)]}[which]
    proc = _run_cli(args)
    assert proc.returncode == 2, proc.stderr
    assert "named pipe" in proc.stderr and "Traceback" not in proc.stderr
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert not (tmp_path / "r.h5").exists()


def test_a_missing_folder_is_refused_unless_parents(tmp_path, write_scene, tiny_scene,
                                                    capsys):
    # bug caught: `-o /nonexistent/dir/x.h5` silently created /nonexistent/dir
    scene = str(write_scene(tiny_scene()))
    out = tmp_path / "no" / "such" / "x.h5"
    assert main(["run", scene, "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and "--parents" in err
    assert not (tmp_path / "no").exists()
    assert main(["run", scene, "-o", str(out), "-q", "--parents", "--until", "1e-4"]) == 0
    assert out.is_file()


def test_an_output_without_extension_gets_a_notice(tmp_path, write_scene, tiny_scene, capsys):
    scene = str(write_scene(tiny_scene()))
    assert main(["run", scene, "-o", str(tmp_path / "out"), "-q", "--until", "1e-4"]) == 0
    assert "written as an HDF5 result file" in capsys.readouterr().err


def test_a_study_into_a_named_pipe_is_refused(tmp_path, capsys):
    # a study's -o names a folder: a named pipe (or a device) there is refused before any run
    import os

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert main(["study", "rod", "-o", str(fifo), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert "named pipe" in err and "Traceback" not in err
    assert main(["study", "rod", "-o", str(tmp_path / "no" / "such"), "--workers", "1"]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert not (tmp_path / "no").exists()
