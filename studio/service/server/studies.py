"""``/api/studies`` and ``/api/study-types``: study jobs (a study run by the job layer) and
their output files."""
# (no ``from __future__ import annotations``: FastAPI reads the route functions' annotations,
# which must be the classes imported inside the router functions, not their names)

from typing import Optional, Union

from studio.service.jobs import (STUDIES, JobInfo, JobManager, StudyOptionError, jsonable, study_options,
                    study_schema)
from studio.service.server.common import json_body
from studio.service.server.models import ErrorAnswer, PurgeAnswer, StudyFiles, StudyOption, error_responses
from studio.service.server.runs import Status

# a study file's media type by its extension
MEDIA_TYPES = {".csv": "text/csv", ".png": "image/png", ".json": "application/json",
               ".h5": "application/x-hdf5", ".txt": "text/plain"}
DEFAULT_MEDIA = "application/octet-stream"


def studies_router(jobs: JobManager, guarded: list):
    """The routes of study jobs (``guarded``: the dependencies of every route)."""
    import anyio
    from fastapi import APIRouter, HTTPException, Query, Request
    from fastapi.responses import FileResponse, JSONResponse

    router = APIRouter()

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
        from studio.service.server.common import short_text, short_value

        # values and messages shortened: a huge value was echoed in full, twice
        detail = [{"loc": ["body", o] if o in top else ["body", "options", o],
                   "msg": short_text(m), "type": "study_option_error", "option": o,
                   "value": short_value(jsonable(v))}
                  for o, v, m in exc.problems]
        return JSONResponse(status_code=422, content={"detail": detail,
                                                      "message": short_text(str(exc), 2000)})

    @router.post("/api/studies", status_code=201, dependencies=guarded, tags=["studies"],
              summary="Submit a study", response_model=JobInfo,
              responses={**error_responses(429, 507), 422: {
                  "model": ErrorAnswer,
                  "description": "unknown study, unknown or bad option, an option the "
                                 "server sets itself (output, scheduler, workers) or a file "
                                 "path where a preset name belongs"}},
              openapi_extra={"requestBody": {"required": True, "content": {
                  "application/json": {"schema": {"type": "object",
                                                  "additionalProperties": False,
                                                  "properties": {
                      "study": {"type": "string", "enum": list(STUDIES)},
                      "options": {"type": ["object", "null"], "description": "the study's command-line "
                                  "options by name, e.g. {\"preset\": \"wedge_60\", "
                                  "\"depth_mm\": 2, \"nodes\": 3} (GET /api/study-types)"},
                      "name": {"type": ["string", "null"]}}, "required": ["study"]}}}}})
    async def submit_study(request: Request):
        """Queue a study (docs/studies.md) as a job; its files go to the job's own folder
        (``GET /api/studies/{id}/files``). Scenes are preset names only."""
        raw = await request.body()
        try:
            data = json_body(raw)
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
        if not isinstance(data.get("options"), (dict, type(None))):
            return option_error(StudyOptionError([(
                "options", data["options"], "must be an object of the study's options "
                                            "(GET /api/study-types), or null")]))
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

    @router.get("/api/studies", dependencies=guarded, tags=["studies"], summary="List studies",
                response_model=list[JobInfo], responses=error_responses())
    def list_studies(status: Optional[Status] = Query(None, description="only studies with "
                                                                        "this status"),
                     limit: Optional[int] = Query(None, ge=1, le=100_000)):
        """Every study job, newest first (scene runs are under ``/api/runs``)."""
        return [i.to_dict() for i in jobs.list(status=status, limit=limit, kind="study")]

    @router.get("/api/study-types", dependencies=guarded, tags=["studies"],
             summary="The studies and their options",
             response_model=dict[str, list[StudyOption]], responses=error_responses())
    def study_types():
        """For each study, the options ``POST /api/studies`` accepts (from the study's
        options model): name, kind (flag, value, list), type, help, default, required,
        choices, unit, bounds, and whether it names a preset."""
        return {s: study_options(s) for s in STUDIES}

    @router.get("/api/study-types/{study}/schema", dependencies=guarded, tags=["studies"],
                summary="The JSON schema of a study's options", response_model=dict,
                responses=error_responses(404))
    def study_type_schema(study: str):
        """The JSON schema of the study's options model (the one declaration its command
        line, the studio's form and ``POST /api/studies`` are checked by; ``scheduler``,
        ``workers`` and ``no_progress`` are set by the server)."""
        if study not in STUDIES:
            raise HTTPException(404, f"no study {study!r}; one of {list(STUDIES)}")
        return study_schema(study)

    @router.get("/api/studies/{job_id}", dependencies=guarded, tags=["studies"],
             summary="One study", response_model=JobInfo,
             responses=error_responses(404))
    def get_study(job_id: str):
        """Status, progress (0..1) and ``message`` (the study's progress text), its
        ``files`` so far, ``summary`` (exit code, wall time, runs) and ``error``."""
        return study_or_404(job_id).to_dict()

    @router.delete("/api/studies/{job_id}", dependencies=guarded, tags=["studies"],
                summary="Cancel a study", response_model=Union[JobInfo, PurgeAnswer],
                   responses=error_responses(404, 409))
    def cancel_study(job_id: str, purge: bool = Query(False, description="also delete the "
                                                      "study and all its files")):
        """Stops the study like Ctrl-C: its finished runs keep their files. With
        ``purge=true`` the study is then deleted with its files."""
        study_or_404(job_id)
        if purge:
            try:
                return jobs.purge(job_id, wait=jobs.study_cancel_grace_s)
            except RuntimeError as exc:
                raise HTTPException(409, str(exc)) from None
        return jobs.cancel(job_id).to_dict()

    @router.get("/api/studies/{job_id}/files", dependencies=guarded, tags=["studies"],
             summary="A study's output files", response_model=StudyFiles,
             responses=error_responses(404))
    def list_study_files(job_id: str):
        """Names (paths relative to the study's folder, e.g. ``force_depth.csv``,
        ``runs/wedge_60.h5``) with their sizes."""
        info = study_or_404(job_id)
        folder = jobs.study_dir(job_id)
        files = [{"name": n, "bytes": (folder / n).stat().st_size} for n in info.files]
        return {"id": job_id, "status": info.status, "files": files}

    @router.get("/api/studies/{job_id}/files/{name:path}", dependencies=guarded,
             tags=["studies"], summary="Download one output file of a study",
             response_class=FileResponse, responses={200: {
                 "content": {m: {"schema": {"type": "string", "format": "binary"}}
                             for m in sorted(set(MEDIA_TYPES.values()) | {DEFAULT_MEDIA})},
                 "description": "the file (CSV, PNG, JSON, HDF5 or text)"},
                 **error_responses(404)})
    def get_study_file(job_id: str, name: str):
        """Only names listed by ``GET /api/studies/{id}/files`` are served."""
        study_or_404(job_id)
        try:
            path = jobs.study_file(job_id, name)
        except KeyError:
            raise HTTPException(404, f"study {job_id} has no file {name!r} (GET "
                                     f"/api/studies/{job_id}/files lists them)") from None
        media = MEDIA_TYPES.get(path.suffix.lower(), DEFAULT_MEDIA)
        return FileResponse(path, media_type=media, filename=path.name)

    return router
