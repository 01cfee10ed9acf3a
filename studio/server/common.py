"""What the routers share: the shapes of 422 answers and the size limit on request bodies."""
from __future__ import annotations

import json
import math
from typing import Optional

def problem_detail(problems: list[dict]) -> list[dict]:
    """SceneError problems in FastAPI's 422 shape (``loc``, ``msg``, ``type``) plus the
    engine's own ``field``, ``value``, ``allowed``."""
    out = []
    for p in problems:
        loc = ["body"] + [int(x) if x.isdigit() else x for x in str(p["field"]).split(".")]
        out.append({"loc": loc, "msg": p["allowed"], "type": "scene_error",
                    "field": p["field"], "value": p["value"], "allowed": p["allowed"]})
    return out


def non_finite_paths(value, path: str = "") -> list[str]:
    """Dotted paths of NaN/infinite numbers in parsed JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return [path or "(scene)"]
    if isinstance(value, dict):
        return [p for k, v in value.items()
                for p in non_finite_paths(v, f"{path}.{k}" if path else str(k))]
    if isinstance(value, list):
        return [p for i, v in enumerate(value)
                for p in non_finite_paths(v, f"{path}.{i}" if path else str(i))]
    return []


class BodyLimit:
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


def not_found_job(jobs, job_id: str):
    """The job ``job_id`` of ``jobs``, or HTTP 404."""
    from fastapi import HTTPException

    try:
        return jobs.get(job_id)
    except KeyError:
        raise HTTPException(404, f"no run with id {job_id!r}") from None


def scene_error(exc):
    """An engine SceneError as a 422 answer naming every bad field."""
    from fastapi.responses import JSONResponse

    problems = exc.as_dicts()
    return JSONResponse(status_code=422, content={
        "detail": problem_detail(problems),
        "message": f"invalid scene: {len(problems)} problem(s): " +
                   "; ".join(f"{p['field']} = {p['value']!r}: {p['allowed']}"
                             for p in problems)})
