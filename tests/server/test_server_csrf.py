"""Cross-site request forgery and DNS rebinding (issue 13, item 4): a page on another
origin cannot queue jobs on the default (loopback, no token) set-up, nor read the API
through a rebound name; JSON endpoints take application/json only."""
from __future__ import annotations

import json
import socket

from fastapi.testclient import TestClient

from studio.service.hosts import allowed_hosts
from studio.service.server import create_app


def raw_post(url: str, path: str, body: bytes, headers: dict) -> tuple[int, dict]:
    """One HTTP/1.1 request written by hand on a socket, as a browser would send it."""
    host, port = url.split("://", 1)[1].split(":")
    head = {"Content-Length": str(len(body)), "Connection": "close", **headers}
    head.setdefault("Host", f"{host}:{port}")
    request = (f"POST {path} HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in head.items())
               + "\r\n").encode() + body
    with socket.create_connection((host, int(port)), timeout=30) as s:
        s.sendall(request)
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    status = int(data.split(b" ", 2)[1])
    payload = data.split(b"\r\n\r\n", 1)[1]
    try:
        return status, json.loads(payload)
    except ValueError:
        return status, {}


def test_a_foreign_origin_cannot_queue_a_job(server, tiny_scene):
    before = len(server.client.get("/api/runs").json())
    body = json.dumps(tiny_scene()).encode()
    # the request: a cross-origin text/plain POST (no preflight in a browser)
    status, answer = raw_post(server.url, "/api/runs", body,
                              {"Origin": "http://evil.example", "Content-Type": "text/plain"})
    assert status == 403 and "evil.example" in answer["detail"]
    # the same with a JSON content type (a preflight would stop it; refused all the same)
    status, _ = raw_post(server.url, "/api/runs", body,
                         {"Origin": "http://evil.example", "Content-Type": "application/json"})
    assert status == 403
    # a form post from a page (no Origin check to pass: no Origin given): JSON only
    status, answer = raw_post(server.url, "/api/runs", body, {"Content-Type": "text/plain"})
    assert status == 415 and "application/json" in answer["detail"]
    status, _ = raw_post(server.url, "/api/studies", b'{"study": "rod"}',
                         {"Content-Type": "application/x-www-form-urlencoded"})
    assert status == 415
    assert len(server.client.get("/api/runs").json()) == before  # nothing was queued


def test_a_rebound_host_name_cannot_read_the_api(server):
    r = server.client.get("/api/runs", headers={"Host": f"evil.example:{server.port}"})
    assert r.status_code == 421 and "evil.example" in r.json()["detail"]
    for name in ("127.0.0.1", "localhost"):
        assert server.client.get("/api/runs", headers={
            "Host": f"{name}:{server.port}"}).status_code == 200


def test_same_origin_and_allowed_origins_pass(server, tiny_scene):
    body = json.dumps(tiny_scene(duration=0.002)).encode()
    status, answer = raw_post(server.url, "/api/runs", body, {
        "Origin": server.url, "Content-Type": "application/json; charset=utf-8"})
    assert status == 201, answer


def test_cors_origins_may_post(tmp_path, tiny_scene):
    from studio.service.jobs import JobManager

    jm = JobManager(tmp_path / "data", workers=1)
    try:
        client = TestClient(create_app(jm, cors_origins=["https://lab.example"]))
        r = client.post("/api/runs", json=tiny_scene(duration=0.002),
                        headers={"Origin": "https://lab.example"})
        assert r.status_code == 201
        r = client.delete(f"/api/runs/{r.json()['id']}", headers={"Origin": "https://x.example"})
        assert r.status_code == 403
    finally:
        jm.close()


def test_allowed_hosts_of_a_bind():
    assert allowed_hosts("127.0.0.1") == {"127.0.0.1", "localhost", "::1"}
    assert allowed_hosts("0.0.0.0") is None  # unknown names: Host unchecked (token advised)
    assert "lab.example" in allowed_hosts("0.0.0.0", ["lab.example"])
    assert allowed_hosts("192.168.1.5") == {"192.168.1.5"}
