"""``/api/runs``: scene jobs: submit, list, state, cancel, result file, channel series."""
# (no ``from __future__ import annotations``: FastAPI reads the route functions' annotations,
# which must be the classes imported inside the router functions, not their names)

import json
from typing import Literal, Optional, Union

from studio.service.jobs import FINAL_STATUSES, STATUSES, JobInfo, JobManager, jsonable
from studio.service.server.common import json_body, non_finite_paths, not_found_job, scene_error
from studio.service.server.models import ChannelList, PurgeAnswer, Series, error_responses

Status = Literal[STATUSES]  # a query's status: one of these, else pydantic's 422

MAX_SERIES_POINTS = 1_000_000                # numbers in one /series answer


def runs_router(jobs: JobManager, guarded: list, *, allow_files: bool = False):
    """The routes of scene jobs (``guarded``: the dependencies of every route)."""
    import anyio
    from fastapi import APIRouter, Header, HTTPException, Query, Request
    from fastapi.responses import FileResponse, JSONResponse, Response

    import engine

    router = APIRouter()

    def job_or_404(job_id: str):
        return not_found_job(jobs, job_id)

    @router.post("/api/runs", status_code=201, dependencies=guarded, tags=["runs"],
              summary="Submit a scene to run", response_model=JobInfo,
              responses={200: {"model": JobInfo, "description": "a submit repeated with the "
                                                                "same Idempotency-Key: the "
                                                                "first one's run"},
                         **error_responses(429, 507)},
              openapi_extra={"requestBody": {"required": True, "content": {
                  "application/json": {"schema": {
                      "type": "object", "required": ["materials", "run"],
                      "properties": {"materials": {"type": "object"}, "run": {"type": "object"}},
                      "description": "a scene (docs/scene.md); what a JSON schema cannot say "
                                     "(names that refer to each other, ranges that depend on "
                                     "other fields) is checked at submit and named in the "
                                     "422"}}}}})
    async def submit_run(request: Request,
                         name: Optional[str] = Query(None, max_length=200,
                                                     description="a label for the run "
                                                                 "(default: the scene's name)"),
                         idempotency_key: Optional[str] = Header(
                             None, max_length=200,
                             description="a key of the client's choice: a submit repeated "
                                         "with the same key returns the first one's run "
                                         "(200) instead of queueing another")):
        """The body is a scene as JSON (docs/scene.md). Returns the new run (its ``id``);
        the run is queued and starts when a worker is free. A mesh shape names an uploaded
        mesh as ``"file": "mesh:<id>"`` (see ``POST /api/meshes``)."""
        if idempotency_key:
            known = jobs.job_for_key(idempotency_key)
            if known is not None:
                return JSONResponse(status_code=200, content=jobs.get(known).to_dict(),
                                    headers={"Location": f"/api/runs/{known}"})
        raw = await request.body()
        try:
            data = json_body(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            return scene_error(engine.SceneError.single("(body)", None,
                                                        f"must be a JSON object: {exc}"))
        if not isinstance(data, dict):
            return scene_error(engine.SceneError.single("(body)", type(data).__name__,
                                                        "must be a JSON object (a scene)"))
        bad = non_finite_paths(data)
        if bad:
            from engine.errors import FieldProblem

            return scene_error(engine.SceneError(
                [FieldProblem(p, "NaN/Infinity", "must be a finite number") for p in bad]))
        try:
            job_id = await anyio.to_thread.run_sync(
                lambda: jobs.submit(data, name=name, allow_files=allow_files,
                                    idempotency_key=idempotency_key or None))
        except engine.SceneError as exc:
            return scene_error(exc)
        info = jobs.get(job_id).to_dict()
        return JSONResponse(status_code=201, content=info,
                            headers={"Location": f"/api/runs/{job_id}"})

    @router.get("/api/runs", dependencies=guarded, tags=["runs"], summary="List runs",
                response_model=list[JobInfo], responses=error_responses())
    def list_runs(status: Optional[Status] = Query(None, description="only runs with this "
                                                                     "status"),
                  limit: Optional[int] = Query(None, ge=1, le=100_000)):
        """Every run, newest first (optionally only those with ``status``)."""
        return [i.to_dict() for i in jobs.list(status=status, limit=limit, kind="run")]

    @router.get("/api/runs/{job_id}", dependencies=guarded, tags=["runs"], summary="One run",
                response_model=JobInfo, responses=error_responses(404))
    def get_run(job_id: str):
        """Status (queued, running, completed, stopped, failed, cancelled), progress (0..1),
        simulated time, steps/s, ETA, dt and what limits it, stage timings, the engine's
        summary and the error message of a failed run."""
        return job_or_404(job_id).to_dict()

    @router.delete("/api/runs/{job_id}", dependencies=guarded, tags=["runs"],
                summary="Cancel a run, or delete it and its files (purge=true)",
                   response_model=Union[JobInfo, PurgeAnswer], responses=error_responses(404, 409))
    def cancel_run(job_id: str, purge: bool = Query(False, description="also delete the "
                                                    "run and its files (result, scene)")):
        """A queued run is cancelled at once; a running one stops within a second and its
        result file keeps the frames recorded so far. A finished run is left as it is.
        With ``purge=true`` the run is then deleted with its files: ``{id, purged,
        freed_bytes}``; its id is unknown (404) afterwards."""
        job_or_404(job_id)
        if purge:
            try:
                return jobs.purge(job_id)
            except RuntimeError as exc:
                raise HTTPException(409, str(exc)) from None
        return jobs.cancel(job_id).to_dict()

    @router.get("/api/runs/{job_id}/result", dependencies=guarded, tags=["runs"],
             summary="Download the HDF5 result file",
             response_class=FileResponse,
             responses={200: {"content": {"application/x-hdf5": {
                 "schema": {"type": "string", "format": "binary"}}},
                 "description": "the HDF5 result file (docs/results.md)"},
                 **error_responses(404, 409)})
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

    @router.get("/api/runs/{job_id}/export", dependencies=guarded, tags=["runs"],
             summary="The run for ParaView and Python tools (.pvd + .vtu series, zip)",
             response_class=Response,
             responses={200: {"content": {"application/zip": {
                 "schema": {"type": "string", "format": "binary"}}},
                 "description": "NAME-ID/NAME-ID.pvd and one .vtu per exported frame "
                                "(engine/io/vtk_export.py)"},
                 **error_responses(404, 409)})
    def get_export(job_id: str,
                   every: int = Query(1, ge=1, le=1_000_000,
                                      description="export every N-th recorded frame")):
        info = job_or_404(job_id)
        if info.status not in FINAL_STATUSES:
            raise HTTPException(409, f"run {job_id} is {info.status}: it can be exported "
                                     f"when it has finished")
        path = jobs.result_path(job_id)
        if not path.is_file():
            raise HTTPException(404, f"run {job_id} ({info.status}) has no result file")
        from engine.io.vtk_export import export_vtk_zip

        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in info.name)[:80]
        stem = f"{safe or 'run'}-{job_id}"
        try:
            data = export_vtk_zip(path, stem, every=every)
        except engine.BrushStudioError as exc:
            raise HTTPException(409, f"run {job_id}: {exc}") from None
        return Response(data, media_type="application/zip", headers={
            "Content-Disposition": f'attachment; filename="{stem}.zip"'})

    @router.get("/api/runs/{job_id}/scene", dependencies=guarded, tags=["runs"],
             summary="The scene a run runs", response_model=dict,
             responses=error_responses(404))
    def get_run_scene(job_id: str):
        info = job_or_404(job_id)
        try:
            return json.loads(jobs.scene_path(job_id).read_text())
        except FileNotFoundError:  # a study job: its scenes are presets, named in options
            raise HTTPException(404, f"{info.kind} {job_id} has no scene file"
                                + (" (a study: GET /api/studies/{id})"
                                   if info.kind == "study" else "")) from None

    @router.get("/api/runs/{job_id}/series", dependencies=guarded, tags=["runs"],
             summary="Recorded channels as JSON arrays",
             response_model=Union[Series, ChannelList], responses=error_responses(404, 409))
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
                return {"id": job_id, "status": info.status, "file_status": res.status,
                        "n_frames": res.n_frames, "channels": channels}
            unknown = [c for c in channel if c not in channels]
            if unknown:
                raise HTTPException(422, f"unknown channel(s) {unknown}: this run records "
                                         f"{channels}")
            frames = slice(start, stop, step)
            time_ = res.time[frames]
            # one status: the job's (a killed worker's file still says "running");
            # the file's own is file_status
            out = {"id": job_id, "status": info.status, "file_status": res.status,
                   "n_frames": res.n_frames,
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
            # as it is (a million numbers through the response model would take seconds)
            return JSONResponse(out)

    return router
