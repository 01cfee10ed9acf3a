"""Outputs are only ever written as regular files (issue 28, item 1): the recorder never
renames a result onto a device, a named pipe, a socket or a folder, and never opens a named
pipe (which would hang). Devices are stood in for by a FIFO and a socket made in a temporary
folder: the tests never write to real /dev nodes."""
from __future__ import annotations

import os
import socket
import stat
import tempfile
from pathlib import Path

import pytest

from engine.io.output_paths import (OutputPathError, check_output_dir, check_output_file,
                                 output_dir_problem, output_file_problem)
from engine.io.recorder import Recorder

SCENE = '{"name": "t"}'
CHANNELS = {"time": ((), "f8")}


@pytest.fixture
def specials():
    """A FIFO, a bound Unix socket and a folder, in a short temporary folder (a socket's
    path is limited to about 100 bytes)."""
    d = Path(tempfile.mkdtemp(prefix="bs-op-", dir="/tmp"))
    fifo = d / "fifo.h5"
    os.mkfifo(fifo)
    sock_path = d / "sock.h5"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    folder = d / "folder.h5"
    folder.mkdir()
    link = d / "link.h5"
    link.symlink_to(fifo)  # a link is followed: a link to a device is a device
    yield {"fifo": fifo, "socket": sock_path, "folder": folder, "link": link}
    sock.close()
    for p in (fifo, sock_path, link):
        p.unlink()
    folder.rmdir()
    d.rmdir()


@pytest.mark.parametrize("kind", ["fifo", "socket", "folder", "link"])
def test_the_recorder_refuses_a_path_that_is_not_a_regular_file(kind, specials):
    # bug caught: the temporary result renamed over a device node (/dev/full became an
    # HDF5 file), or a named pipe opened for writing (hangs with no reader)
    path = specials[kind]
    mode = os.stat(path).st_mode
    with pytest.raises(OutputPathError, match="regular file|directory"):
        Recorder(path, SCENE, CHANNELS, {})
    assert os.stat(path).st_mode == mode  # still the same kind of thing
    assert not (path.parent / f".{path.name}.creating").exists()


def test_the_recorder_refuses_a_named_pipe_as_its_temporary_file(tmp_path):
    os.mkfifo(tmp_path / ".r.h5.creating")
    with pytest.raises(OutputPathError, match="named pipe"):
        Recorder(tmp_path / "r.h5", SCENE, CHANNELS, {})
    assert stat.S_ISFIFO(os.stat(tmp_path / ".r.h5.creating").st_mode)


def test_a_regular_file_is_replaced_and_a_missing_one_created(tmp_path):
    old = tmp_path / "old.h5"
    old.write_text("not hdf5")
    for p in (old, tmp_path / "new.h5"):
        with Recorder(p, SCENE, CHANNELS, {}) as rec:
            rec.append({"time": 0.0})
        assert p.is_file() and p.read_bytes()[:4] == b"\x89HDF"


def test_file_checks_name_the_kind_and_missing_folders(specials, tmp_path):
    assert "named pipe" in output_file_problem(specials["fifo"], "-o")
    assert "socket" in output_file_problem(specials["socket"], "-o")
    assert "directory" in output_file_problem(specials["folder"], "-o")
    missing = tmp_path / "no" / "such" / "x.h5"
    assert "--parents" in output_file_problem(missing, "-o")
    with pytest.raises(OutputPathError):
        check_output_file(missing)
    assert not (tmp_path / "no").exists()  # refused: nothing created
    assert check_output_file(missing, parents=True) == missing
    assert missing.parent.is_dir() and not missing.exists()
    under_a_file = tmp_path / "f"
    under_a_file.write_text("x")
    assert "not a folder" in output_file_problem(under_a_file / "x.h5", "-o", parents=True)


def test_folder_checks(specials, tmp_path):
    assert "not a folder" in output_dir_problem(specials["fifo"])
    assert output_dir_problem(specials["folder"]) is None
    assert "does not exist" in output_dir_problem(tmp_path / "a" / "b")
    assert check_output_dir(tmp_path / "c").is_dir()  # the folder itself is created
