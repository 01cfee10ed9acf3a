"""The studio page's WebSocket with the HTTP API's Host and Origin rules.

viser serves the studio page and its WebSocket on one port with no Host or Origin check, so
a page on any site could open the WebSocket (``Origin: http://evil.example`` was answered
101) and a rebound name could reach it. :func:`guarded_viser_server` starts viser with a
check in front of every HTTP request and WebSocket upgrade of that port: the Host must be a
name of this server (421 otherwise) and a browser's Origin this server's own origin (403
otherwise), by :func:`~.common.host_allowed` and :func:`~.common.same_origin`, the rules of
the headless service. viser 1.1 has no option for it: the check is added to the
``process_request`` hook it gives ``websockets``' ``serve`` while the server starts.
"""
from __future__ import annotations

import http
import threading
from typing import Optional

from studio.service.server.common import host_allowed, host_name, same_origin

_PATCH_LOCK = threading.Lock()


def refusal(headers, allowed_hosts) -> Optional[tuple[int, str]]:
    """``(status, reason)`` for a request (its headers) that must be refused, else None."""
    host = headers.get("Host", "") or ""
    if not host_allowed(host, allowed_hosts):
        return 421, f"Host {host!r} is not a name of this server"
    origin = headers.get("Origin")
    if origin is not None and not same_origin(origin, host):
        return 403, f"cross-site request refused: Origin {origin!r} is not this server's origin"
    return None


def guarded_viser_server(host: str, port: int, allowed_hosts, **kwargs):
    """``viser.ViserServer(host=host, port=port, **kwargs)`` whose port refuses requests by
    :func:`refusal` (``allowed_hosts``: the names its Host may give, None: any)."""
    import viser
    import websockets.asyncio.server as ws_server
    from websockets.datastructures import Headers
    from websockets.http11 import Response

    allowed = None if allowed_hosts is None else {host_name(h) for h in allowed_hosts}
    original = ws_server.serve

    def serve(handler, *args, process_request=None, **kw):
        def guard(connection, request):
            refused = refusal(request.headers, allowed)
            if refused is not None:
                status, reason = refused
                body = reason.encode()
                return Response(status, http.HTTPStatus(status).phrase,
                                Headers({"Content-Type": "text/plain; charset=utf-8",
                                         "Content-Length": str(len(body)),
                                         "Connection": "close"}), body)
            return process_request(connection, request) if process_request else None

        return original(handler, *args, process_request=guard, **kw)

    with _PATCH_LOCK:  # viser calls serve() in its thread before its constructor returns
        ws_server.serve = serve
        try:
            server = viser.ViserServer(host=host, port=port, **kwargs)
        finally:
            ws_server.serve = original
    return server
