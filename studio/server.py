"""The HTTP job service: Brush Studio's engine behind a documented JSON API (FastAPI).

``create_app(jobs)`` builds the app over a :class:`studio.jobs.JobManager`; the headless
server (``brush-studio serve --headless``, in ``studio.serve_cli``) runs it under uvicorn and
the 3D studio serves the same app beside viser. Endpoints (OpenAPI at ``/docs``)::

    POST   /api/runs                     scene JSON -> 201 {id, status, ...}; 422 names fields
    GET    /api/runs                     every run (scene job), newest first
    GET    /api/runs/{id}                status, progress, sim time, dt, stages, timings, error
    DELETE /api/runs/{id}                cancel (a running run stops within a second)
    GET    /api/runs/{id}/result         the HDF5 result file (finished runs)
    GET    /api/runs/{id}/series         ?channel=...: time and values as JSON arrays
    GET    /api/runs/{id}/scene          the scene the run ran
    POST   /api/studies                  {study, options, name} -> 201 {id, kind: "study", ...}
    GET    /api/studies                  every study job, newest first
    GET    /api/studies/{id}             status, progress, message, files, error
    DELETE /api/studies/{id}             cancel (finished runs of the study are kept)
    GET    /api/studies/{id}/files       the study's output files (names)
    GET    /api/studies/{id}/files/{name}  download one of them (names from that list only)
    GET    /api/study-types              the studies and the options each accepts
    GET    /api/presets                  the preset scenes: name, title, description
    GET    /api/presets/{name}           one preset's scene JSON
    POST   /api/meshes                   upload STL/OBJ/PLY -> {id, ref: "mesh:<id>", ...}
    GET    /api/meshes                   uploaded meshes
    GET    /api/health                   liveness, version, workers, jobs per status

Clients name runs and meshes by id only, never a server file path: a scene's mesh shape
names an uploaded mesh as ``"file": "mesh:<id>"``. Safety: bearer-token auth when a token is
given (``/api/health`` and the OpenAPI pages stay open), request-body and upload size limits
(413), a triangle limit for meshes (413), CORS only for the origins given.
"""
import json
import math
import secrets
from typing import Iterable, Optional

from .jobs import (FINAL_STATUSES, STATUSES, STUDIES, JobManager, MeshError,
                   StudyOptionError, jsonable, study_options)

DEFAULT_MAX_BODY_BYTES = 8 * 1024 * 1024     # a scene JSON; far above any real scene
DEFAULT_MAX_UPLOAD_BYTES = 64 * 1024 * 1024  # a mesh file (200 000 triangles as binary STL: 10 MB)
MAX_SERIES_POINTS = 1_000_000                # numbers in one /series answer


def _problem_detail(problems: list[dict]) -> list[dict]:
    """SceneError problems in FastAPI's 422 shape (``loc``, ``msg``, ``type``) plus the
    engine's own ``field``, ``value``, ``allowed``."""
    out = []
    for p in problems:
        loc = ["body"] + [int(x) if x.isdigit() else x for x in str(p["field"]).split(".")]
        out.append({"loc": loc, "msg": p["allowed"], "type": "scene_error",
                    "field": p["field"], "value": p["value"], "allowed": p["allowed"]})
    return out


def _non_finite_paths(value, path: str = "") -> list[str]:
    """Dotted paths of NaN/infinite numbers in parsed JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return [path or "(scene)"]
    if isinstance(value, dict):
        return [p for k, v in value.items()
                for p in _non_finite_paths(v, f"{path}.{k}" if path else str(k))]
    if isinstance(value, list):
        return [p for i, v in enumerate(value)
                for p in _non_finite_paths(v, f"{path}.{i}" if path else str(i))]
    return []


class _BodyLimit:
    """Pure ASGI middleware: refuse request bodies above a limit with 413 before the app
    reads them (by Content-Length, and by counting for chunked bodies)."""

    def __init__(self, app, max_body: int, max_upload: int, upload_paths: tuple[str, ...]):
        self.app = app
        self.max_body = max_body
        self.max_upload = max_upload
        self.upload_paths = upload_paths

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] in ("GET", "HEAD", "OPTIONS", "DELETE"):
            return await self.app(scope, receive, send)
        limit = self.max_upload if scope["path"] in self.upload_paths else self.max_body
        length = None
        for k, v in scope.get("headers", ()):
            if k == b"content-length":
                try:
                    length = int(v)
                except ValueError:
                    return await self._reply(send, 400, "bad Content-Length header")
        if length is not None and length > limit:
            return await self._too_large(send, limit, length)
        # read the body here (at most limit + 1 bytes) and replay it to the app
        chunks, size = [], 0
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                return await self._too_large(send, limit, None)
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        sent = False

        async def replay():
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        return await self.app(scope, replay, send)

    async def _too_large(self, send, limit: int, length: Optional[int]):
        got = f" ({length} bytes)" if length is not None else ""
        return await self._reply(send, 413, f"request body too large{got}: at most "
                                            f"{limit} bytes are accepted here")

    @staticmethod
    async def _reply(send, status: int, message: str):
        body = json.dumps({"detail": message}).encode()
        await send({"type": "http.response.start", "status": status,
                    "headers": [(b"content-type", b"application/json"),
                                (b"content-length", str(len(body)).encode()),
                                (b"connection", b"close")]})
        await send({"type": "http.response.body", "body": body})


def create_app(jobs: JobManager, *, token: Optional[str] = None,
               cors_origins: Iterable[str] = (),
               max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
               max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES,
               allow_files: bool = False):
    """The FastAPI app over ``jobs``. ``token``: require ``Authorization: Bearer <token>``
    on every ``/api`` route but ``/api/health``. ``cors_origins``: origins allowed to call
    the API from a browser (none by default). ``allow_files``: let scenes name server-side
    mesh files (off: only ``mesh:<id>`` references to uploads)."""
    import anyio
    from fastapi import Depends, FastAPI, File, HTTPException, Query, Request, UploadFile
    from fastapi.responses import FileResponse, JSONResponse
    from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

    import engine

    from . import __version__

    app = FastAPI(
        title="Brush Studio API",
        version=__version__,
        description="Run Brush Studio scenes as jobs: submit a scene, watch its progress, "
                    "download its HDF5 result or plot its channels. Scenes are the JSON of "
                    "docs/scene.md; result files are described in docs/results.md.")
    app.state.jobs = jobs
    bearer = HTTPBearer(auto_error=False)

    def auth(credentials: Optional[HTTPAuthorizationCredentials] = Depends(bearer)) -> None:
        if token is None:
            return
        given = credentials.credentials if credentials is not None else ""
        if not secrets.compare_digest(given.encode(), token.encode()):
            raise HTTPException(401, "missing or wrong bearer token "
                                     "(send 'Authorization: Bearer <token>')",
                                headers={"WWW-Authenticate": "Bearer"})

    guarded = [Depends(auth)]

    def job_or_404(job_id: str):
        try:
            return jobs.get(job_id)
        except KeyError:
            raise HTTPException(404, f"no run with id {job_id!r}") from None

    def scene_error(exc) -> JSONResponse:
        problems = exc.as_dicts()
        return JSONResponse(status_code=422, content={
            "detail": _problem_detail(problems),
            "message": f"invalid scene: {len(problems)} problem(s): " +
                       "; ".join(f"{p['field']} = {p['value']!r}: {p['allowed']}"
                                 for p in problems)})

    # ------------------------------------------------------------------ runs
    @app.post("/api/runs", status_code=201, dependencies=guarded, tags=["runs"],
              summary="Submit a scene to run",
              responses={422: {"description": "invalid scene: every bad field, with its value "
                                              "and what is allowed"},
                         413: {"description": "request body too large"}},
              openapi_extra={"requestBody": {"required": True, "content": {
                  "application/json": {"schema": {"type": "object",
                                                  "description": "a scene (docs/scene.md)"}}}}})
    async def submit_run(request: Request,
                         name: Optional[str] = Query(None, max_length=200,
                                                     description="a label for the run "
                                                                 "(default: the scene's name)")):
        """The body is a scene as JSON (docs/scene.md). Returns the new run (its ``id``);
        the run is queued and starts when a worker is free. A mesh shape names an uploaded
        mesh as ``"file": "mesh:<id>"`` (see ``POST /api/meshes``)."""
        raw = await request.body()
        try:
            data = json.loads(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            return scene_error(engine.SceneError.single("(body)", None,
                                                        f"must be a JSON object: {exc}"))
        if not isinstance(data, dict):
            return scene_error(engine.SceneError.single("(body)", type(data).__name__,
                                                        "must be a JSON object (a scene)"))
        bad = _non_finite_paths(data)
        if bad:
            from engine.errors import FieldProblem

            return scene_error(engine.SceneError(
                [FieldProblem(p, "NaN/Infinity", "must be a finite number") for p in bad]))
        try:
            job_id = await anyio.to_thread.run_sync(
                lambda: jobs.submit(data, name=name, allow_files=allow_files))
        except engine.SceneError as exc:
            return scene_error(exc)
        info = jobs.get(job_id).to_dict()
        return JSONResponse(status_code=201, content=info,
                            headers={"Location": f"/api/runs/{job_id}"})

    @app.get("/api/runs", dependencies=guarded, tags=["runs"], summary="List runs")
    def list_runs(status: Optional[str] = Query(None, description=f"one of {STATUSES}"),
                  limit: Optional[int] = Query(None, ge=1, le=100_000)):
        """Every run, newest first (optionally only those with ``status``)."""
        if status is not None and status not in STATUSES:
            raise HTTPException(422, f"status = {status!r}: must be one of {list(STATUSES)}")
        return [i.to_dict() for i in jobs.list(status=status, limit=limit, kind="run")]

    @app.get("/api/runs/{job_id}", dependencies=guarded, tags=["runs"], summary="One run")
    def get_run(job_id: str):
        """Status (queued, running, completed, stopped, failed, cancelled), progress (0..1),
        simulated time, steps/s, ETA, dt and what limits it, stage timings, the engine's
        summary and the error message of a failed run."""
        return job_or_404(job_id).to_dict()

    @app.delete("/api/runs/{job_id}", dependencies=guarded, tags=["runs"],
                summary="Cancel a run")
    def cancel_run(job_id: str):
        """A queued run is cancelled at once; a running one stops within a second and its
        result file keeps the frames recorded so far. A finished run is left as it is."""
        job_or_404(job_id)
        return jobs.cancel(job_id).to_dict()

    @app.get("/api/runs/{job_id}/result", dependencies=guarded, tags=["runs"],
             summary="Download the HDF5 result file",
             responses={200: {"content": {"application/x-hdf5": {}}},
                        409: {"description": "the run has not finished"}})
    def get_result(job_id: str):
        info = job_or_404(job_id)
        if info.status not in FINAL_STATUSES:
            raise HTTPException(409, f"run {job_id} is {info.status}: its result file can be "
                                     f"downloaded when it has finished (GET "
                                     f"/api/runs/{job_id}/series reads it live)")
        path = jobs.result_path(job_id)
        if not path.is_file():
            raise HTTPException(404, f"run {job_id} ({info.status}) has no result file"
                                     + (f": {info.error}" if info.error else ""))
        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in info.name)[:80]
        return FileResponse(path, media_type="application/x-hdf5",
                            filename=f"{safe or 'run'}-{job_id}.h5")

    @app.get("/api/runs/{job_id}/scene", dependencies=guarded, tags=["runs"],
             summary="The scene a run runs")
    def get_run_scene(job_id: str):
        job_or_404(job_id)
        return json.loads(jobs.scene_path(job_id).read_text())

    @app.get("/api/runs/{job_id}/series", dependencies=guarded, tags=["runs"],
             summary="Recorded channels as JSON arrays")
    def get_series(job_id: str,
                   channel: Optional[list[str]] = Query(
                       None, description="channel name(s), e.g. brushes/brush/root_force; "
                                         "repeat for several; none: list the channels"),
                   start: int = Query(0, ge=0, description="first frame"),
                   stop: Optional[int] = Query(None, ge=0, description="frame to stop before"),
                   step: int = Query(1, ge=1, description="every step-th frame")):
        """``time`` (s) and, per channel, ``values``: one row per frame (a number, or a list
        for vector channels; non-finite numbers as null). Works while the run is running
        (the frames recorded so far). Without ``channel``: the list of channels."""
        info = job_or_404(job_id)
        path = jobs.result_path(job_id)
        if not path.is_file():
            raise HTTPException(409 if info.status in ("queued", "running") else 404,
                                f"run {job_id} is {info.status} and has no result file yet")
        try:
            res = engine.open_result(path)
        except engine.BrushStudioError as exc:
            raise HTTPException(409, f"result file of run {job_id} cannot be read yet: "
                                     f"{exc}") from None
        with res:
            channels = list(res.channels())
            if not channel:
                return {"id": job_id, "status": res.status, "n_frames": res.n_frames,
                        "channels": channels}
            unknown = [c for c in channel if c not in channels]
            if unknown:
                raise HTTPException(422, f"unknown channel(s) {unknown}: this run records "
                                         f"{channels}")
            frames = slice(start, stop, step)
            time_ = res.time[frames]
            out = {"id": job_id, "status": res.status, "n_frames": res.n_frames,
                   "frames": {"start": start, "stop": stop, "step": step},
                   "time": jsonable(time_), "series": {}}
            total = len(time_)
            for c in channel:
                values = res.series(c, frames)
                total += values.size
                if total > MAX_SERIES_POINTS:
                    raise HTTPException(413, f"more than {MAX_SERIES_POINTS} numbers: ask for "
                                             f"fewer channels or frames (start/stop/step)")
                out["series"][c] = {"shape": list(values.shape[1:]),
                                    "values": jsonable(values)}
            return out

    # ------------------------------------------------------------------ studies
    def study_or_404(job_id: str):
        try:
            info = jobs.get(job_id)
        except KeyError:
            info = None
        if info is None or info.kind != "study":
            raise HTTPException(404, f"no study with id {job_id!r}")
        return info

    def option_error(exc: StudyOptionError) -> JSONResponse:
        top = ("study", "options", "name", "(body)")
        detail = [{"loc": ["body", o] if o in top else ["body", "options", o], "msg": m,
                   "type": "study_option_error", "option": o, "value": jsonable(v)}
                  for o, v, m in exc.problems]
        return JSONResponse(status_code=422, content={"detail": detail,
                                                      "message": str(exc)})

    @app.post("/api/studies", status_code=201, dependencies=guarded, tags=["studies"],
              summary="Submit a study",
              responses={422: {"description": "unknown study, unknown or bad option, an "
                                              "option the server sets itself (output, "
                                              "scheduler, workers) or a file path where a "
                                              "preset name belongs"}},
              openapi_extra={"requestBody": {"required": True, "content": {
                  "application/json": {"schema": {"type": "object", "properties": {
                      "study": {"type": "string", "enum": list(STUDIES)},
                      "options": {"type": "object", "description": "the study's command-line "
                                  "options by name, e.g. {\"preset\": \"wedge_60\", "
                                  "\"depth_mm\": 2, \"nodes\": 3} (GET /api/study-types)"},
                      "name": {"type": "string"}}, "required": ["study"]}}}}})
    async def submit_study(request: Request):
        """Queue a study (docs/studies.md) as a job; its files go to the job's own folder
        (``GET /api/studies/{id}/files``). Scenes are preset names only."""
        raw = await request.body()
        try:
            data = json.loads(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            return option_error(StudyOptionError([("(body)", None,
                                                   f"must be a JSON object: {exc}")]))
        if not isinstance(data, dict) or not isinstance(data.get("study"), str):
            return option_error(StudyOptionError([(
                "study", None, f"the body must be a JSON object with 'study' (one of "
                               f"{list(STUDIES)}), 'options' and 'name'")]))
        extra = sorted(set(data) - {"study", "options", "name"})
        if extra:
            return option_error(StudyOptionError([(
                "(body)", extra, "unknown key(s): the body holds 'study', 'options' (the "
                                 "study's options) and 'name'")]))
        name = data.get("name")
        if name is not None and not isinstance(name, str):
            return option_error(StudyOptionError([("name", name, "must be text")]))
        try:
            job_id = await anyio.to_thread.run_sync(
                lambda: jobs.submit_study(data["study"], data.get("options") or {},
                                          name=name))
        except StudyOptionError as exc:
            return option_error(exc)
        return JSONResponse(status_code=201, content=jobs.get(job_id).to_dict(),
                            headers={"Location": f"/api/studies/{job_id}"})

    @app.get("/api/studies", dependencies=guarded, tags=["studies"], summary="List studies")
    def list_studies(status: Optional[str] = Query(None, description=f"one of {STATUSES}"),
                     limit: Optional[int] = Query(None, ge=1, le=100_000)):
        """Every study job, newest first (scene runs are under ``/api/runs``)."""
        if status is not None and status not in STATUSES:
            raise HTTPException(422, f"status = {status!r}: must be one of {list(STATUSES)}")
        return [i.to_dict() for i in jobs.list(status=status, limit=limit, kind="study")]

    @app.get("/api/study-types", dependencies=guarded, tags=["studies"],
             summary="The studies and their options")
    def study_types():
        """For each study, the options ``POST /api/studies`` accepts: name, kind (flag,
        value, list), help, default, required, choices, and whether it names a preset."""
        return {s: study_options(s) for s in STUDIES}

    @app.get("/api/studies/{job_id}", dependencies=guarded, tags=["studies"],
             summary="One study")
    def get_study(job_id: str):
        """Status, progress (0..1) and ``message`` (the study's progress text), its
        ``files`` so far, ``summary`` (exit code, wall time, runs) and ``error``."""
        return study_or_404(job_id).to_dict()

    @app.delete("/api/studies/{job_id}", dependencies=guarded, tags=["studies"],
                summary="Cancel a study")
    def cancel_study(job_id: str):
        """Stops the study like Ctrl-C: its finished runs keep their files."""
        study_or_404(job_id)
        return jobs.cancel(job_id).to_dict()

    @app.get("/api/studies/{job_id}/files", dependencies=guarded, tags=["studies"],
             summary="A study's output files")
    def list_study_files(job_id: str):
        """Names (paths relative to the study's folder, e.g. ``force_depth.csv``,
        ``runs/wedge_60.h5``) with their sizes."""
        info = study_or_404(job_id)
        folder = jobs.study_dir(job_id)
        files = [{"name": n, "bytes": (folder / n).stat().st_size} for n in info.files]
        return {"id": job_id, "status": info.status, "files": files}

    @app.get("/api/studies/{job_id}/files/{name:path}", dependencies=guarded,
             tags=["studies"], summary="Download one output file of a study")
    def get_study_file(job_id: str, name: str):
        """Only names listed by ``GET /api/studies/{id}/files`` are served."""
        study_or_404(job_id)
        try:
            path = jobs.study_file(job_id, name)
        except KeyError:
            raise HTTPException(404, f"study {job_id} has no file {name!r} (GET "
                                     f"/api/studies/{job_id}/files lists them)") from None
        media = {".csv": "text/csv", ".png": "image/png", ".json": "application/json",
                 ".h5": "application/x-hdf5", ".txt": "text/plain"}.get(path.suffix.lower(),
                                                                    "application/octet-stream")
        return FileResponse(path, media_type=media, filename=path.name)

    # ------------------------------------------------------------------ presets
    def presets_module():
        try:
            from . import presets
        except ImportError as exc:
            raise HTTPException(503, f"presets are not available: {exc}") from None
        return presets

    @app.get("/api/presets", dependencies=guarded, tags=["presets"], summary="List presets")
    def list_presets():
        """The preset scenes (the seed's experiments and others): name, title, description."""
        return presets_module().list_presets()

    @app.get("/api/presets/{name}", dependencies=guarded, tags=["presets"],
             summary="One preset's scene")
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
    @app.post("/api/meshes", status_code=201, dependencies=guarded, tags=["meshes"],
              summary="Upload a mesh (STL, OBJ or PLY)",
              responses={413: {"description": "file too large or too many triangles"},
                         422: {"description": "not a readable triangle mesh"}})
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

    @app.get("/api/meshes", dependencies=guarded, tags=["meshes"],
             summary="List uploaded meshes")
    def list_meshes():
        return jobs.list_meshes()

    # ------------------------------------------------------------------ health
    @app.get("/api/health", tags=["service"], summary="Liveness and load")
    def health():
        """Open without a token (for health checks): version, workers, jobs per status."""
        alive = jobs.workers_info()
        return {"status": "ok", "version": __version__, "workers": jobs.n_workers,
                "threads_per_worker": jobs.threads_per_worker, "workers_alive": len(alive),
                "worker_processes": [{k: w[k] for k in ("pid", "ready", "numba_threads")}
                                     for w in alive],
                "jobs": jobs.counts()}

    app.add_middleware(_BodyLimit, max_body=int(max_body_bytes),
                       max_upload=int(max_upload_bytes) + 64 * 1024,  # + multipart framing
                       upload_paths=("/api/meshes",))
    origins = [o for o in cors_origins if o]
    if origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(CORSMiddleware, allow_origins=origins, allow_methods=["*"],
                           allow_headers=["*"], allow_credentials=False)
    return app
