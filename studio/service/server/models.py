"""The shapes of the API's answers, as pydantic models: what the OpenAPI document (``/docs``,
``/openapi.json``) says each route returns, and what FastAPI checks the routes' answers
against.

A job is :class:`studio.service.jobs.JobInfo` itself (a dataclass: one source for its fields); the
rest are the dicts the job layer and the routes build, written down here. Errors all carry
``detail``: a sentence, or for 422 a list of problems each naming its place (``loc``), its
message (``msg``) and its kind (``type``), with the engine's ``field``, ``value``, ``allowed``
or a limit's ``limit``, ``value``, ``allowed`` besides.
"""
from __future__ import annotations

from typing import Any, Optional, Union

from pydantic import BaseModel, ConfigDict, Field


class Problem(BaseModel):
    """One problem of a refused request."""

    model_config = ConfigDict(extra="allow")

    loc: list[Union[str, int]] = Field(description="where: ['body', field, ...], "
                                                   "['query', name], ...")
    msg: str = Field(description="what is wrong, or what is allowed")
    type: str = Field(description="scene_error, study_option_error, limit_error, or "
                                  "pydantic's own kinds")


class ErrorAnswer(BaseModel):
    """Every error answer: ``detail`` is a sentence, or the list of problems (422, 413 and
    429 for a limit); ``message`` sums them up; ``limit`` names the server's limit hit."""

    model_config = ConfigDict(extra="allow")

    detail: Union[str, list[Problem]]
    message: Optional[str] = None
    limit: Optional[str] = Field(None, description="the limit a 413/422/429 hit (its "
                                                   "server option without '--')")


def error_responses(*codes: int) -> dict:
    """The ``responses`` of a route: the refusals any route may answer
    (:data:`COMMON_ERRORS`) and these status codes, all :class:`ErrorAnswer`."""
    return {c: {"model": ErrorAnswer, "description": _WHAT.get(c, "error")}
            for c in sorted(set(COMMON_ERRORS) | set(codes))}


_WHAT = {
    400: "malformed request (a bad Content-Length)",
    401: "missing or wrong bearer token (servers started with --token)",
    403: "cross-site request: Origin is not this server's nor an allowed one",
    404: "no such run, study, preset, mesh or file",
    409: "not possible in the job's state (not finished yet, still running)",
    413: "too large: request body, upload, triangles, or the scene's estimated cost",
    415: "this endpoint takes application/json",
    421: "Host does not name this server (DNS rebinding)",
    422: "invalid request: every problem, with its place and what is allowed",
    429: "the queue is full: submit again after Retry-After seconds",
    503: "presets are not available on this server",
    507: "the server's storage is full (or over its quota): the job was not stored",
}
# what any route may answer: the middleware's refusals (RequestGuard, BodyLimit)
COMMON_ERRORS = (400, 401, 403, 413, 415, 421, 422)


class PurgeAnswer(BaseModel):
    """``DELETE ...?purge=true``: the job is gone with its files."""

    id: str
    purged: bool
    freed_bytes: int


class ChannelList(BaseModel):
    """``GET /api/runs/{id}/series`` without ``channel``: what the run records."""

    id: str
    status: str = Field(description="the job's status")
    file_status: Optional[str] = Field(description="the result file's own status attribute")
    n_frames: int
    channels: list[str]


class SeriesValues(BaseModel):
    shape: list[int] = Field(description="the shape of one frame's value ([] for a number)")
    values: list[Any] = Field(description="one entry per frame: a number, or nested lists; "
                                          "non-finite numbers as null")


class Series(BaseModel):
    """``GET /api/runs/{id}/series?channel=...``: time and the channels' values."""

    id: str
    status: str
    file_status: Optional[str]
    n_frames: int
    frames: dict[str, Optional[int]] = Field(description="start, stop, step as asked")
    time: list[Optional[float]]
    series: dict[str, SeriesValues]


class StudyOption(BaseModel):
    """One option a study accepts (``GET /api/study-types``)."""

    name: str
    kind: str = Field(description="flag, value or list")
    type: Optional[str] = Field(None, description="bool, int, float, str, choice or list")
    item: Optional[str] = Field(None, description="a list's item type")
    help: str
    default: Any = None
    required: bool
    choices: Optional[list[Any]] = None
    unit: Optional[str] = Field(None, description="the unit the value is given in")
    ge: Optional[float] = None
    gt: Optional[float] = None
    le: Optional[float] = None
    lt: Optional[float] = None
    preset: bool = Field(description="it names a preset (GET /api/presets)")


class StudyFile(BaseModel):
    name: str = Field(description="path relative to the study's folder")
    bytes: int


class StudyFiles(BaseModel):
    id: str
    status: str
    files: list[StudyFile]


class PresetInfo(BaseModel):
    name: str
    title: str
    description: str


class MeshInfo(BaseModel):
    """An uploaded mesh: put ``ref`` in a scene's mesh shape."""

    model_config = ConfigDict(extra="allow")

    id: str
    ref: str = Field(description='"mesh:<id>"')
    filename: str
    format: str
    triangles: int
    vertices: int
    bounds: list[list[Optional[float]]] = Field(description="[[xmin, ymin, zmin], "
                                                            "[xmax, ymax, zmax]]")
    watertight: bool
    bytes: int


class WorkerProcess(BaseModel):
    pid: Optional[int]
    ready: bool
    numba_threads: Optional[int]


class Health(BaseModel):
    """``GET /api/health``. Open without a token; when the server has one, a request
    without it gets ``status`` and ``version`` only (no worker PIDs, disk figures or
    problems)."""

    status: str = Field(description="ok, or degraded (see problems)")
    version: str
    problems: Optional[list[str]] = None
    free_bytes: Optional[int] = Field(None, description="free space in the data folder")
    used_bytes: Optional[int] = Field(None, description="bytes of job files in the data "
                                                        "folder (with --max-storage-gb)")
    quota_bytes: Optional[int] = Field(None, description="--max-storage-gb, in bytes")
    workers: Optional[int] = None
    threads_per_worker: Optional[int] = None
    workers_alive: Optional[int] = None
    worker_processes: Optional[list[WorkerProcess]] = None
    jobs: Optional[dict[str, int]] = Field(None, description="number of jobs per status")
