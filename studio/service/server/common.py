"""What the routers share: the shapes of 422 answers and the size limit on request bodies."""
from __future__ import annotations

import json
import math
from typing import Optional

MAX_ECHO_CHARS = 200  # a bad value is echoed in a 422 up to this length


def short_value(value):
    """``value`` as it is echoed in an error answer: itself when its JSON is short, else
    the start of its JSON text and its length (a 6 MB list was echoed twice: a 15 MB
    422)."""
    try:
        text = json.dumps(value, default=str)
    except (TypeError, ValueError):
        text = repr(value)
    if len(text) <= MAX_ECHO_CHARS:
        return value
    return f"{text[:MAX_ECHO_CHARS]}... ({len(text)} characters)"


def short_text(text: str, limit: int = 4 * MAX_ECHO_CHARS) -> str:
    """A message cut to ``limit`` characters (saying how long it was)."""
    text = str(text)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def problem_detail(problems: list[dict]) -> list[dict]:
    """SceneError problems in FastAPI's 422 shape (``loc``, ``msg``, ``type``) plus the
    engine's own ``field``, ``value`` (shortened: :func:`short_value`), ``allowed``."""
    out = []
    problems = [{**p, "value": short_value(p["value"])} for p in problems]
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

    problems = [{**p, "value": short_value(p["value"])} for p in exc.as_dicts()]
    return JSONResponse(status_code=422, content={
        "detail": problem_detail(problems),
        "message": f"invalid scene: {len(problems)} problem(s): " +
                   "; ".join(f"{p['field']} = {p['value']!r}: {p['allowed']}"
                             for p in problems)})


def host_name(value: str) -> str:
    """The host of a ``Host`` header or of an origin's authority, lower case, without the
    port and without IPv6 brackets."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1:value.find("]")] if "]" in value else value[1:]
    return value.rsplit(":", 1)[0] if value.count(":") == 1 else value


LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})


def _split_authority(value: str) -> tuple[str, str]:
    """(host, port) of ``host[:port]`` (IPv6 in brackets), lower case; port '' if none."""
    value = value.strip().lower()
    if value.startswith("["):
        end = value.find("]")
        host = value[1:end] if end >= 0 else value[1:]
        rest = value[end + 1:] if end >= 0 else ""
        return host, rest[1:] if rest.startswith(":") else ""
    if value.count(":") == 1:
        host, port = value.split(":")
        return host, port
    return value, ""


def host_allowed(host: str, allowed_hosts) -> bool:
    """Whether a request's ``Host`` header names this server (``allowed_hosts``: names
    without ports, as :func:`host_name` gives them; None: anything)."""
    return allowed_hosts is None or host_name(host) in allowed_hosts


def same_origin(origin: str, host: str, cors_origins=()) -> bool:
    """Whether a browser's ``Origin`` is this server's own origin (its authority equal to
    ``Host``, or both loopback names, ``localhost``/``127.0.0.1``/``[::1]`` in any
    combination, with the same port) or one of ``cors_origins`` (lower case, no trailing
    slash). The one rule of the headless service, the studio's API and its WebSocket."""
    o = origin.strip().rstrip("/").lower()
    if o in cors_origins:
        return True
    if "://" not in o:
        return False  # "null" (a sandboxed page, a file://) and the like
    authority = o.split("://", 1)[1]
    if authority == host.strip().lower():
        return True
    (o_host, o_port), (h_host, h_port) = _split_authority(authority), _split_authority(host)
    return o_host in LOOPBACK_NAMES and h_host in LOOPBACK_NAMES and o_port == h_port


class RequestGuard:
    """Pure ASGI middleware against cross-site requests from a browser page (CSRF) and DNS
    rebinding, in front of every route:

    * ``Host`` must name this server (``allowed_hosts``; ``None``: not checked), so that a
      page on a rebound name (``http://evil.example:8000``) cannot read the API: 421;
    * a request that changes something (POST, PUT, PATCH, DELETE) sent with an ``Origin``
      must come from this server's own origin (:func:`same_origin`: ``host:port`` equal to
      ``Host``, loopback names in any combination) or one of ``cors_origins``: 403
      otherwise (a page elsewhere cannot queue jobs);
    * the JSON endpoints (``json_paths``) take ``application/json`` bodies only: 415 for
      ``text/plain`` and the form types a page can send without a preflight.
    """

    UNSAFE = ("POST", "PUT", "PATCH", "DELETE")

    def __init__(self, app, allowed_hosts, cors_origins, json_paths: tuple[str, ...],
                 token: Optional[str] = None, open_paths: tuple[str, ...] = ()):
        self.app = app
        self.token = token
        self.open_paths = open_paths
        self.allowed_hosts = (None if allowed_hosts is None
                              else {host_name(h) for h in allowed_hosts})
        self.cors_origins = {o.rstrip("/").lower() for o in cors_origins}
        self.json_paths = json_paths

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", ())}
        host = headers.get("host", "")
        if not host_allowed(host, self.allowed_hosts):
            return await BodyLimit._reply(
                send, 421, f"Host {host!r} is not a name of this server (allowed: "
                           f"{sorted(self.allowed_hosts)}; add one with --allow-host)")
        method = scope["method"]
        origin = headers.get("origin")
        if method in self.UNSAFE and origin is not None:
            if not same_origin(origin, host, self.cors_origins):
                return await BodyLimit._reply(
                    send, 403, f"cross-site request refused: Origin {origin!r} is not this "
                               f"server's origin nor an allowed one (--cors ORIGIN)")
        path = scope["path"]
        if self.token is not None and path.startswith("/api") and path not in self.open_paths:
            # the bearer token before anything reads the body (an unauthenticated 56 MB
            # upload was read in full before its 401); the routes check it again
            import secrets

            given = headers.get("authorization", "")
            scheme, _, credentials = given.partition(" ")
            if scheme.lower() != "bearer" or not secrets.compare_digest(
                    credentials.strip().encode(), self.token.encode()):
                body = json.dumps({"detail": "missing or wrong bearer token (send "
                                             "'Authorization: Bearer <token>')"}).encode()
                await send({"type": "http.response.start", "status": 401,
                            "headers": [(b"content-type", b"application/json"),
                                        (b"content-length", str(len(body)).encode()),
                                        (b"www-authenticate", b"Bearer"),
                                        (b"connection", b"close")]})
                await send({"type": "http.response.body", "body": body})
                return
        if method == "POST" and path in self.json_paths:  # (no other method has a body)
            ctype = headers.get("content-type", "").split(";", 1)[0].strip().lower()
            if ctype != "application/json" and not (ctype.startswith("application/")
                                                    and ctype.endswith("+json")):
                return await BodyLimit._reply(
                    send, 415, f"Content-Type {ctype or '(none)'!r}: this endpoint takes "
                               f"application/json")
        return await self.app(scope, receive, send)


MAX_JSON_DEPTH = 64  # a scene nests 6 deep; far deeper is an attack on the parser


def json_body(raw: bytes):
    """A request body parsed as JSON; ValueError (with the reason) for bad JSON or JSON
    nested deeper than ``MAX_JSON_DEPTH`` (which would exhaust Python's recursion in the
    checks after the parser: a RecursionError, a 500)."""
    try:
        data = json.loads(raw)
    except RecursionError:
        raise ValueError(f"nested deeper than {MAX_JSON_DEPTH} levels") from None
    stack = [(data, 1)]  # an iterative walk: no recursion of its own
    while stack:
        value, depth = stack.pop()
        if isinstance(value, (dict, list)):
            if depth > MAX_JSON_DEPTH:
                raise ValueError(f"nested deeper than {MAX_JSON_DEPTH} levels")
            items = value.values() if isinstance(value, dict) else value
            stack.extend((v, depth + 1) for v in items if isinstance(v, (dict, list)))
    return data
