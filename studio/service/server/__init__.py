"""The HTTP job service: Brush Studio's engine behind a documented JSON API (FastAPI).

``create_app(jobs)`` builds the app over a :class:`studio.service.jobs.JobManager`; the headless
server (``brush-studio serve --headless``, in ``studio.cli.serve``) runs it under uvicorn and
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
import secrets
from typing import Iterable, Optional

from studio.service.jobs import JobManager
from studio.service.server.common import BodyLimit, RequestGuard
from studio.service.server.library import library_router
from studio.service.server.runs import MAX_SERIES_POINTS, runs_router  # noqa: F401  (the series limit)
from studio.service.server.studies import studies_router

DEFAULT_MAX_BODY_BYTES = 8 * 1024 * 1024     # a scene JSON; far above any real scene
DEFAULT_MAX_UPLOAD_BYTES = 64 * 1024 * 1024  # a mesh file (200 000 triangles as binary STL: 10 MB)


def create_app(jobs: JobManager, *, token: Optional[str] = None,
               cors_origins: Iterable[str] = (),
               max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
               max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES,
               allow_files: bool = False,
               allowed_hosts: Optional[Iterable[str]] = None):
    """The FastAPI app over ``jobs``. ``token``: require ``Authorization: Bearer <token>``
    on every ``/api`` route but ``/api/health``. ``cors_origins``: origins allowed to call
    the API from a browser (none by default). ``allow_files``: let scenes name server-side
    mesh files (off: only ``mesh:<id>`` references to uploads). ``allowed_hosts``: the
    names a request's ``Host`` may give (the bound address and its loopback aliases; None:
    not checked). Requests that change something from a browser page of another origin
    are refused (403), and JSON endpoints take ``application/json`` only (415): see
    :class:`~.common.RequestGuard`."""
    from fastapi import Depends, FastAPI, HTTPException
    from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

    from studio import __version__

    app = FastAPI(
        title="Brush Studio API",
        version=__version__,
        description="Run Brush Studio scenes as jobs: submit a scene, watch its progress, "
                    "download its HDF5 result or plot its channels. Scenes are the JSON of "
                    "docs/scene.md; result files are described in docs/results.md.")
    app.state.jobs = jobs
    app.state.token = token  # (``/api/health`` shows its details only with it)
    bearer = HTTPBearer(auto_error=False)

    def auth(credentials: Optional[HTTPAuthorizationCredentials] = Depends(bearer)) -> None:
        if token is None:
            return
        given = credentials.credentials if credentials is not None else ""
        if not secrets.compare_digest(given.encode(), token.encode()):
            raise HTTPException(401, "missing or wrong bearer token "
                                     "(send 'Authorization: Bearer <token>')",
                                headers={"WWW-Authenticate": "Bearer"})

    # the token's route dependency (and its security scheme in the OpenAPI document) only
    # when there is a token: without one the document must not ask clients for one
    guarded = [Depends(auth)] if token is not None else []

    from fastapi.responses import JSONResponse

    from studio.service.jobs import StorageError

    @app.exception_handler(StorageError)
    async def storage_error(request, exc: StorageError):
        # 507 Insufficient Storage: the request was fine, the server's disk was not
        return JSONResponse(status_code=507, content={"detail": str(exc)})

    from fastapi.exception_handlers import http_exception_handler
    from starlette.exceptions import HTTPException as StarletteHTTPException

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request, exc: StarletteHTTPException):
        if exc.status_code == 405:  # Allow: every method of the path (Starlette names one
            # route's only: "Allow: POST" for /api/runs, which GET also serves)
            from starlette.routing import Match

            methods = [m for m in ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")
                       if any(r.matches({**request.scope, "method": m})[0] == Match.FULL
                              for r in app.router.routes)]
            exc.headers = {**(exc.headers or {}), "Allow": ", ".join(methods)}
        return await http_exception_handler(request, exc)

    from fastapi.exceptions import RequestValidationError

    from studio.service.server.common import short_value

    @app.exception_handler(RequestValidationError)
    async def validation_error(request, exc: RequestValidationError):
        # FastAPI's own 422, with each echoed input shortened (it echoed a 6 MB body twice)
        errors = [{**e, "input": short_value(e.get("input"))} if "input" in e else e
                  for e in exc.errors()]
        errors = [{k: (str(v) if k == "ctx" else v) for k, v in e.items()} for e in errors]
        return JSONResponse(status_code=422, content={"detail": errors})

    from studio.service.jobs import LimitError

    @app.exception_handler(LimitError)
    async def limit_error(request, exc: LimitError):
        # 413: the scene does not fit; 422: it would not end in time; 429: the queue is full
        headers = {"Retry-After": str(exc.retry_after)} if exc.retry_after else None
        return JSONResponse(status_code=exc.status, headers=headers,
                            content={"detail": [exc.as_dict()], "message": str(exc),
                                     "limit": exc.limit})

    app.include_router(runs_router(jobs, guarded, allow_files=allow_files))
    app.include_router(studies_router(jobs, guarded))
    app.include_router(library_router(jobs, guarded, max_upload_bytes=max_upload_bytes))

    app.add_middleware(BodyLimit, max_body=int(max_body_bytes),
                       max_upload=int(max_upload_bytes) + 64 * 1024,  # + multipart framing
                       upload_paths=("/api/meshes",))
    origins = [o for o in cors_origins if o]
    app.add_middleware(RequestGuard, allowed_hosts=allowed_hosts, cors_origins=origins,
                       json_paths=("/api/runs", "/api/studies"), token=token,
                       open_paths=("/api/health",))
    if origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(CORSMiddleware, allow_origins=origins, allow_methods=["*"],
                           allow_headers=["*"], allow_credentials=False)
    return app
