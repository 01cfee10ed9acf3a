"""The studio's API port and its WebSocket with the headless service's Host and Origin
rules (issue 28, items 2, 3 and 9): a rebound name (``Host: evil.example:PORT``) is 421, a
page of another origin cannot POST (403) nor open the studio's WebSocket (403, not 101), the
design-changing request is a POST, and loopback names are accepted in any combination."""
from __future__ import annotations

import json
import socket

import pytest
from fastapi.testclient import TestClient

from studio.service.server.common import same_origin
from studio.service.server.studio_routes import make_api_app


class _Studio:
    """What the studio routes need of a studio: one shared design, loads counted."""
    per_client = False

    def __init__(self):
        self.loaded = []

    def load_preset(self, name):
        self.loaded.append(name)

    def state(self, client=None):
        return {"loaded": self.loaded}


@pytest.fixture
def studio_api(tmp_path):
    from studio.service.jobs import JobManager

    jm = JobManager(tmp_path / "data", workers=1)
    studio = _Studio()
    app = make_api_app(jm, studio, viser_port=8080, host="127.0.0.1")
    with TestClient(app, base_url="http://127.0.0.1:8081") as client:
        yield client, studio
    jm.close()


def test_a_rebound_page_can_neither_post_nor_read(studio_api, tiny_scene):
    # bug caught: the studio built its API without a Host check and compared Origin with
    # Host, so a rebound page was "same origin": 201 for the POST, 200 for the GET
    client, _ = studio_api
    evil = {"Host": "evil.example:8081", "Origin": "http://evil.example:8081"}
    r = client.post("/api/runs", content=json.dumps(tiny_scene()),
                    headers={**evil, "Content-Type": "application/json"})
    assert r.status_code == 421
    assert client.get("/api/runs", headers={"Host": "evil.example:8081"}).status_code == 421
    assert client.get("/studio/state", headers={"Host": "evil.example:8081"}).status_code == 421
    r = client.post("/api/runs", content=json.dumps(tiny_scene()),
                    headers={"Origin": "http://evil.example",
                             "Content-Type": "application/json"})
    assert r.status_code == 403
    assert client.get("/api/runs").json() == []  # nothing was queued


def test_changing_the_shared_design_is_a_post_guarded_by_origin(studio_api):
    # bug caught: GET /studio?preset=NAME changed the design, so an <img> on any page could
    client, studio = studio_api
    r = client.get("/studio?preset=demo", follow_redirects=False)
    assert r.status_code == 405 and studio.loaded == []
    r = client.post("/studio?preset=demo", headers={"Origin": "http://evil.example"},
                    follow_redirects=False)
    assert r.status_code == 403 and studio.loaded == []
    r = client.post("/studio?preset=demo", headers={"Origin": "http://localhost:8081"},
                    follow_redirects=False)
    assert r.status_code == 303 and studio.loaded == ["demo"]


@pytest.mark.parametrize("origin", ["localhost", "127.0.0.1", "[::1]"])
@pytest.mark.parametrize("host", ["localhost", "127.0.0.1", "[::1]"])
def test_loopback_names_in_any_combination(origin, host):
    # bug caught: Origin http://localhost:PORT against Host 127.0.0.1:PORT was refused
    assert same_origin(f"http://{origin}:8081", f"{host}:8081")
    assert not same_origin(f"http://{origin}:9999", f"{host}:8081")  # another port
    assert not same_origin(f"http://evil.example:8081", f"{host}:8081")


def _upgrade(port: int, host: str, origin) -> int:
    """The status line of a WebSocket upgrade sent by hand, as a browser would."""
    head = {"Host": host, "Upgrade": "websocket", "Connection": "Upgrade",
            "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==", "Sec-WebSocket-Version": "13",
            "Sec-WebSocket-Protocol": "viser-v0"}
    if origin:
        head["Origin"] = origin
    request = "GET / HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in head.items()) + "\r\n"
    with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
        s.sendall(request.encode())
        data = s.recv(4096)
    return int(data.split(b" ", 2)[1])


def test_the_studio_websocket_refuses_other_origins_and_hosts():
    # bug caught: the studio's WebSocket accepted any Origin (101 for http://evil.example)
    from studio.service.hosts import allowed_hosts
    from studio.service.server.ws_guard import guarded_viser_server

    server = guarded_viser_server("127.0.0.1", 0, allowed_hosts("127.0.0.1"), verbose=False)
    try:
        port = server.get_port()
        assert _upgrade(port, f"127.0.0.1:{port}", "http://evil.example") == 403
        assert _upgrade(port, f"evil.example:{port}", f"http://evil.example:{port}") == 421
        assert _upgrade(port, f"127.0.0.1:{port}", f"http://localhost:{port}") == 101
        assert _upgrade(port, f"localhost:{port}", None) == 101  # not a browser: no Origin
    finally:
        server.stop()
