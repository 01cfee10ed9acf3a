"""The mesh geometry cache lives in the user's cache folder, overridable, never inside the
package (issue 28, item 9); the engine's own mesh loader refuses parse bombs from their
byte counts (item 7)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import engine
from engine.model.meshes import load_mesh_file

PACKAGE = Path(engine.__file__).parent


def _cache_dir(env: dict) -> Path:
    out = subprocess.run([sys.executable, "-c", "import engine.model.meshes as m; print(m._CACHE_DIR)"],
                         env={**os.environ, **env}, capture_output=True, text=True, check=True)
    return Path(out.stdout.strip())


def test_the_geometry_cache_is_the_users_and_overridable(tmp_path):
    # bug caught: .npz files written into engine/__pycache__/geometry (read-only or shared
    # for an installed package), with no setting to move them
    env = {k: "" for k in ("BRUSH_STUDIO_CACHE_DIR",)}
    assert _cache_dir({**env, "BRUSH_STUDIO_CACHE_DIR": str(tmp_path / "own")}) == \
        tmp_path / "own" / "geometry"
    assert _cache_dir({**env, "XDG_CACHE_HOME": str(tmp_path / "xdg")}) == \
        tmp_path / "xdg" / "brush-studio" / "geometry"
    default = _cache_dir({**env, "XDG_CACHE_HOME": ""})
    assert PACKAGE not in default.parents


def test_the_engine_loader_refuses_a_face_of_millions_of_indices(tmp_path, monkeypatch):
    import trimesh

    bomb = tmp_path / "bomb.obj"
    bomb.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf " + b"1 2 3 " * 1_000_000 + b"\n")

    def no_parsing(*args, **kwargs):
        raise AssertionError("trimesh was asked to parse a parse bomb")

    monkeypatch.setattr(trimesh, "load", no_parsing)
    with pytest.raises(engine.SceneError, match="triangles"):
        load_mesh_file(bomb)
