"""Bad output paths (issue 13, item 8): one clear line and exit code 2, before anything
runs, never a traceback; an unwritable --summary is found before the run, not after it."""
from __future__ import annotations

import time

import pytest

from studio.cli import main


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
