"""``/api/presets``, ``/api/meshes`` and ``/api/health``: the preset scenes, uploaded meshes
and the service's liveness."""
# (no ``from __future__ import annotations``: FastAPI reads the route functions' annotations,
# which must be the classes imported inside the router functions, not their names)

import json

from studio.service.jobs import JobManager, MeshError
from studio.service.server.models import Health, MeshInfo, PresetInfo, error_responses


def library_router(jobs: JobManager, guarded: list, *, max_upload_bytes: int):
    """Presets and meshes (``guarded``), and the open health check."""
    import anyio
    from fastapi import APIRouter, File, HTTPException, Request, UploadFile
    from fastapi.responses import JSONResponse

    import engine

    from studio import __version__

    router = APIRouter()

    def presets_module():
        try:
            from studio import presets
        except ImportError as exc:
            raise HTTPException(503, f"presets are not available: {exc}") from None
        return presets

    @router.get("/api/presets", dependencies=guarded, tags=["presets"], summary="List presets",
                response_model=list[PresetInfo], responses=error_responses(503))
    def list_presets():
        """The preset scenes (the seed's experiments and others): name, title, description."""
        return presets_module().list_presets()

    @router.get("/api/presets/{name}", dependencies=guarded, tags=["presets"],
             summary="One preset's scene", response_model=dict,
             responses=error_responses(404, 503))
    def get_preset(name: str):
        """The preset's scene JSON, ready to edit and ``POST /api/runs``."""
        presets = presets_module()
        try:
            scene = presets.load_preset(name)
        except KeyError:
            raise HTTPException(404, f"no preset named {name!r}") from None
        except engine.SceneError as exc:
            raise HTTPException(500, f"preset {name!r} is invalid: {exc}") from None
        return json.loads(scene.to_json())


    # ------------------------------------------------------------------ meshes
    @router.post("/api/meshes", status_code=201, dependencies=guarded, tags=["meshes"],
              summary="Upload a mesh (STL, OBJ or PLY)", response_model=MeshInfo,
              responses=error_responses(507))
    async def upload_mesh(file: UploadFile = File(..., description="an .stl, .obj or .ply "
                                                                    "file")):
        """Stores the mesh and returns its ``id`` and ``ref`` (``"mesh:<id>"``): put the
        ref in a scene's mesh shape, ``{"type": "mesh", "file": "mesh:<id>", "scale": ...}``.
        The same file uploaded twice gets the same id."""
        data = await file.read()
        if len(data) > max_upload_bytes:
            raise HTTPException(413, f"file too large: at most {max_upload_bytes} bytes")
        try:
            info = await anyio.to_thread.run_sync(lambda: jobs.add_mesh(data, file.filename))
        except MeshError as exc:
            raise HTTPException(exc.status, f"mesh {file.filename!r}: {exc}") from None
        return JSONResponse(status_code=201, content=info)

    @router.get("/api/meshes", dependencies=guarded, tags=["meshes"],
             summary="List uploaded meshes", response_model=list[MeshInfo],
             responses=error_responses())
    def list_meshes():
        return jobs.list_meshes()


    # ------------------------------------------------------------------ health
    @router.get("/api/health", tags=["service"], summary="Liveness and load",
                response_model=Health, responses=error_responses())
    def health(request: Request):
        """Open without a token (for health checks): status and version; with the token (or
        on a server without one) also the problems, disk figures, workers and jobs."""
        state = jobs.health()
        token = getattr(request.app.state, "token", None)
        if token is not None:
            import secrets

            scheme, _, given = request.headers.get("authorization", "").partition(" ")
            if scheme.lower() != "bearer" or not secrets.compare_digest(
                    given.strip().encode(), token.encode()):
                return {"status": state["status"], "version": __version__}
        alive = jobs.workers_info()
        return {"status": state["status"], "problems": state["problems"],
                "free_bytes": state["free_bytes"], "used_bytes": state["used_bytes"],
                "quota_bytes": state["quota_bytes"], "version": __version__, "workers": jobs.n_workers,
                "threads_per_worker": jobs.threads_per_worker, "workers_alive": len(alive),
                "worker_processes": [{k: w[k] for k in ("pid", "ready", "numba_threads")}
                                     for w in alive],
                "jobs": jobs.counts()}

    return router
