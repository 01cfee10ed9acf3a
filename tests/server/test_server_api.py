"""The HTTP API against a real ``brush-studio serve --headless`` subprocess: a run end to
end, bad input answered with a clear 4xx (and the server unharmed), meshes by id."""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import trimesh

import engine


def _box_stl() -> bytes:
    return trimesh.creation.box(extents=(0.01, 0.01, 0.002)).export(file_type="stl")


def test_submit_poll_download_and_read(server, tiny_scene, tmp_path):
    r = server.client.post("/api/runs", json=tiny_scene(), params={"name": "first"})
    assert r.status_code == 201, r.text
    run = r.json()
    assert run["name"] == "first" and run["status"] in ("queued", "running")
    assert r.headers["location"] == f"/api/runs/{run['id']}"
    info = server.wait_run(run["id"])
    assert info["status"] == "completed", info
    assert info["progress"] == 1.0 and info["error"] is None
    assert info["dt"] > 0 and "bristle" in info["dt_limited_by"]
    assert set(info["stages"]) >= {"bonds", "recording"} and info["wall_s"] > 0
    assert info["sim_time"] == pytest.approx(0.004, rel=1e-3)

    r = server.client.get(f"/api/runs/{run['id']}/result")
    assert r.status_code == 200 and r.headers["content-type"] == "application/x-hdf5"
    path = tmp_path / "run.h5"
    path.write_bytes(r.content)
    with engine.open_result(path) as res:
        assert res.status == "completed" and res.n_frames >= 9  # 0..4 ms every 0.5 ms
        force = res.series("brushes/brush/root_force")
        t = res.time
    assert t[-1] == pytest.approx(0.004, rel=1e-2)  # recorded to the end (within one dt)

    # the series endpoint serves the same numbers as the file
    r = server.client.get(f"/api/runs/{run['id']}/series",
                          params={"channel": "brushes/brush/root_force"})
    assert r.status_code == 200
    data = r.json()
    assert data["series"]["brushes/brush/root_force"]["shape"] == [3]
    np.testing.assert_array_equal(np.array(data["time"]), t)
    np.testing.assert_array_equal(
        np.array(data["series"]["brushes/brush/root_force"]["values"]), force)
    channels = server.client.get(f"/api/runs/{run['id']}/series").json()["channels"]
    assert "energy/total" in channels

    listed = [i["id"] for i in server.client.get("/api/runs").json()]
    assert run["id"] in listed
    assert server.client.get("/api/runs/" + run["id"] + "/scene").json()["name"] == "tiny"


def _without(scene, *path):
    scene = copy.deepcopy(scene)
    node = scene
    for key in path[:-1]:
        node = node[key]
    del node[path[-1]]
    return scene


def _with(scene, value, *path):
    scene = copy.deepcopy(scene)
    node = scene
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return scene


@pytest.mark.parametrize("case", ["missing_field", "negative_radius", "nan", "infinity",
                                  "schema_version", "not_json", "not_an_object",
                                  "server_path", "unknown_mesh"])
def test_bad_scene_is_422_with_the_field(server, tiny_scene, case):
    scene = tiny_scene()
    expect_field = {
        "missing_field": "brushes.0.bristle_length",
        "negative_radius": "brushes.0.root_radius",
        "nan": "brushes.0.tip_radius",
        "infinity": "run.duration",
        "schema_version": "schema_version",
        "not_json": "(body)",
        "not_an_object": "(body)",
        "server_path": "bodies.0.shape.file",
        "unknown_mesh": "bodies.0.shape.file",
    }[case]
    if case == "missing_field":
        body = json.dumps(_without(scene, "brushes", 0, "bristle_length"))
    elif case == "negative_radius":
        body = json.dumps(_with(scene, -0.001, "brushes", 0, "root_radius"))
    elif case == "nan":  # Python's json writes NaN, as many clients do
        body = json.dumps(_with(scene, float("nan"), "brushes", 0, "tip_radius"))
    elif case == "infinity":
        body = json.dumps(_with(scene, float("inf"), "run", "duration"))
    elif case == "schema_version":
        body = json.dumps(_with(scene, 99, "schema_version"))
    elif case == "not_json":
        body = json.dumps(scene)[:-10]
    elif case == "not_an_object":
        body = json.dumps([scene])
    elif case == "server_path":  # clients never name server files
        body = json.dumps(_with(scene, {"type": "mesh", "file": "/etc/passwd"},
                                "bodies", 0, "shape"))
    else:
        body = json.dumps(_with(scene, {"type": "mesh", "file": "mesh:../../jobs.sqlite"},
                                "bodies", 0, "shape"))
    before = len(server.client.get("/api/runs").json())
    r = server.client.post("/api/runs", content=body,
                           headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert expect_field in [d["field"] for d in detail], detail
    assert all(d["msg"] for d in detail)
    assert expect_field in r.json()["message"]
    assert len(server.client.get("/api/runs").json()) == before  # nothing was queued
    assert server.client.get("/api/health").json()["status"] == "ok"


def test_oversized_body_is_413(server):
    body = b'{"name": "' + b"x" * (9 * 1024 * 1024) + b'"}'  # default limit: 8 MiB
    r = server.client.post("/api/runs", content=body,
                           headers={"content-type": "application/json"})
    assert r.status_code == 413 and "too large" in r.json()["detail"]
    assert server.client.get("/api/health").status_code == 200


def test_unknown_ids_are_404(server):
    for url in ("/api/runs/0123456789ab", "/api/runs/0123456789ab/result",
                "/api/runs/0123456789ab/series", "/api/runs/..%2F..%2Fetc",
                "/api/presets/..%2F..%2Fetc%2Fpasswd", "/api/presets/no_such_preset"):
        assert server.client.get(url).status_code == 404, url
    assert server.client.delete("/api/runs/0123456789ab").status_code == 404


def test_meshes_upload_limits_and_a_run_naming_one(server, tiny_scene):
    r = server.client.post("/api/meshes", files={"file": ("junk.stl", b"solid x\nnot a mesh\n")})
    assert r.status_code == 422 and "junk.stl" in r.json()["detail"]
    r = server.client.post("/api/meshes", files={"file": ("box.dwg", _box_stl())})
    assert r.status_code == 422 and ".stl" in r.json()["detail"]
    ico = trimesh.creation.icosphere(subdivisions=3).export(file_type="stl")  # 1280 triangles
    r = server.client.post("/api/meshes", files={"file": ("ball.stl", ico)})
    assert r.status_code == 413 and "1280 triangles" in r.json()["detail"]

    r = server.client.post("/api/meshes", files={"file": ("box.stl", _box_stl())})
    assert r.status_code == 201, r.text
    mesh = r.json()
    assert mesh["triangles"] == 12 and mesh["watertight"] and mesh["ref"] == f"mesh:{mesh['id']}"
    again = server.client.post("/api/meshes", files={"file": ("same.stl", _box_stl())}).json()
    assert again["id"] == mesh["id"]  # content-addressed
    assert mesh["id"] in [m["id"] for m in server.client.get("/api/meshes").json()]

    scene = _with(tiny_scene(), {"type": "mesh", "file": mesh["ref"]}, "bodies", 0, "shape")
    r = server.client.post("/api/runs", json=scene)
    assert r.status_code == 201, r.text
    info = server.wait_run(r.json()["id"])
    assert info["status"] == "completed", info
    # the box mesh presses the bristles like the box primitive: a downward push on them
    fz = server.client.get(f"/api/runs/{info['id']}/series",
                           params={"channel": "bodies/box/contact_force"}).json()
    assert fz["series"]["bodies/box/contact_force"]["values"][-1][2] > 0


def test_presets_listed_and_loadable(server):
    r = server.client.get("/api/presets")
    assert r.status_code == 200
    presets = r.json()
    assert presets and all({"name", "title", "description"} <= set(p) for p in presets)
    name = presets[0]["name"]
    scene = server.client.get(f"/api/presets/{name}").json()
    assert engine.parse_scene(scene).name  # a valid scene


def test_openapi_documents_the_endpoints(server):
    paths = server.client.get("/openapi.json").json()["paths"]
    for p in ("/api/runs", "/api/runs/{job_id}", "/api/runs/{job_id}/result",
              "/api/runs/{job_id}/series", "/api/presets", "/api/presets/{name}",
              "/api/meshes", "/api/health"):
        assert p in paths, p
    assert server.client.get("/docs").status_code == 200
