"""Uploaded meshes: STL/OBJ/PLY files stored under ``DATA/meshes/`` by content hash, listed
in the job database, and named by scenes as ``"file": "mesh:<id>"`` (resolved here before a
scene is validated)."""
from __future__ import annotations

import hashlib
import io
import json
import os
import re
import sqlite3
import threading
import time
from pathlib import Path

from studio.service.jobs.store import StorageError, jsonable, storage_reason

MESH_FORMATS = ("stl", "obj", "ply")
MESH_PREFIX = "mesh:"
DEFAULT_MAX_TRIANGLES = 200_000  # the engine's own limit (docs/scene.md)
_MESH_ID = re.compile(r"^[0-9a-f]{16}$")


class MeshError(ValueError):
    """An uploaded mesh that cannot be used: ``status`` is the HTTP status that fits
    (413 too large, 422 unreadable or invalid)."""

    def __init__(self, message: str, status: int = 422):
        super().__init__(message)
        self.status = status


class MeshStore:
    """The uploaded meshes of ``meshes_dir``, listed in ``store``'s database."""

    def __init__(self, meshes_dir: Path, store, max_triangles: int = DEFAULT_MAX_TRIANGLES):
        self.meshes_dir = Path(meshes_dir)
        self._store, self._lock = store, store.lock
        self.max_triangles = int(max_triangles)

    def add_mesh(self, data: bytes, filename: str) -> dict:
        """Store an uploaded STL/OBJ/PLY mesh; returns its description with ``id`` and
        ``ref`` (``"mesh:<id>"``, what a scene's mesh shape names as ``file``). Raises
        :class:`MeshError` for an unknown format, an unreadable or empty mesh, non-finite
        coordinates, or more than ``max_triangles`` triangles."""
        fmt = Path(str(filename or "")).suffix.lower().lstrip(".")
        if fmt not in MESH_FORMATS:
            raise MeshError(f"file name {filename!r}: the format is taken from the extension, "
                            f"one of {', '.join('.' + f for f in MESH_FORMATS)}")
        if not data:
            raise MeshError("the uploaded file is empty")
        from engine.model.mesh_limits import mesh_bytes_problem

        # counts read from the bytes before trimesh parses anything: face arity, vertices,
        # any-case STL facets, the PLY header (a parse bomb costs seconds and gigabytes)
        problem = mesh_bytes_problem(data, fmt, self.max_triangles)
        if problem:
            raise MeshError(problem, status=413 if ("at most" in problem or "longer" in problem)
                            else 422)
        import numpy as np
        import trimesh

        try:
            loaded = trimesh.load(io.BytesIO(data), file_type=fmt, force="mesh",
                                  process=False)
        except Exception as exc:  # trimesh raises many kinds on garbage
            raise MeshError(f"cannot be read as a {fmt.upper()} triangle mesh: "
                            f"{type(exc).__name__}: {exc}") from None
        if not isinstance(loaded, trimesh.Trimesh):
            raise MeshError(f"holds no triangle mesh (read as {type(loaded).__name__})")
        vertices = np.asarray(loaded.vertices, dtype=np.float64)
        faces = np.asarray(loaded.faces)
        if faces.ndim != 2 or len(faces) == 0 or len(vertices) == 0:
            raise MeshError("holds no triangles")
        if len(faces) > self.max_triangles:
            raise MeshError(f"has {len(faces)} triangles; at most {self.max_triangles} are "
                            f"allowed (decimate the mesh)", status=413)
        if not np.isfinite(vertices).all():
            raise MeshError("has vertices with NaN or infinite coordinates")
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise MeshError("has triangles referring to missing vertices")
        mesh_id = hashlib.sha256(fmt.encode() + b"\0" + data).hexdigest()[:16]
        info = {"id": mesh_id, "ref": MESH_PREFIX + mesh_id, "filename": str(filename)[:200],
                "format": fmt, "triangles": int(len(faces)), "vertices": int(len(vertices)),
                "bounds": jsonable(np.array([vertices.min(axis=0), vertices.max(axis=0)])),
                "watertight": bool(trimesh.Trimesh(vertices, faces).is_watertight),
                "bytes": len(data)}
        path = self.meshes_dir / f"{mesh_id}.{fmt}"
        tmp = path.with_suffix(f".tmp{os.getpid()}.{threading.get_ident()}")
        try:
            if not path.exists():
                tmp.write_bytes(data)
                os.replace(tmp, path)
            with self._lock:
                self._store.db.execute(
                    "INSERT OR IGNORE INTO meshes (id, filename, format, created, info) "
                    "VALUES (?, ?, ?, ?, ?)",
                    (mesh_id, info["filename"], fmt, time.time(), json.dumps(info)))
        except (OSError, sqlite3.Error) as exc:
            tmp.unlink(missing_ok=True)
            raise StorageError(f"the mesh could not be stored: {storage_reason(exc)}") from exc
        return info

    def list_meshes(self) -> list[dict]:
        with self._lock:
            rows = self._store.db.execute("SELECT info FROM meshes ORDER BY created DESC").fetchall()
        return [json.loads(r[0]) for r in rows]

    def mesh_path(self, mesh_id: str) -> Path:
        """The stored file of an uploaded mesh; KeyError if unknown."""
        if not isinstance(mesh_id, str) or not _MESH_ID.match(mesh_id):
            raise KeyError(mesh_id)
        with self._lock:
            row = self._store.db.execute("SELECT format FROM meshes WHERE id = ?",
                                   (mesh_id,)).fetchone()
        if row is None:
            raise KeyError(mesh_id)
        path = self.meshes_dir / f"{mesh_id}.{row[0]}"
        if not path.is_file():
            raise KeyError(mesh_id)
        return path

    def triangles_of(self, file: str):
        """Triangles of a stored upload named by its path (None for other files)."""
        path = Path(file)
        if path.parent != self.meshes_dir:
            return None
        with self._lock:
            row = self._store.db.execute("SELECT info FROM meshes WHERE id = ?",
                                         (path.stem,)).fetchone()
        return json.loads(row[0]).get("triangles") if row else None

    # ------------------------------------------------------------------ internals
    def resolve_scene(self, scene, *, allow_files: bool):
        import engine

        if isinstance(scene, engine.Scene):
            scene = scene.model_copy(deep=True)
        else:
            scene = engine.parse_scene(scene)
        problems = []
        for i, body in enumerate(scene.bodies):
            if body.shape.type != "mesh":
                continue
            ref = body.shape.file
            fieldname = f"bodies.{i}.shape.file"
            if ref.startswith(MESH_PREFIX):
                try:
                    path = self.mesh_path(ref[len(MESH_PREFIX):])
                except KeyError:
                    problems.append((fieldname, ref, "names no uploaded mesh (upload it "
                                     "first: POST /api/meshes gives its 'mesh:<id>')"))
                    continue
                body.shape = body.shape.model_copy(update={"file": str(path)})
            elif not allow_files:
                problems.append((fieldname, ref, "must name an uploaded mesh as "
                                 "'mesh:<id>' (POST /api/meshes); file paths are not "
                                 "accepted here"))
        if problems:
            from engine.errors import FieldProblem

            raise engine.SceneError([FieldProblem(*p) for p in problems])
        return scene
