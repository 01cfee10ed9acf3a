"""Studies as jobs: option -> argv mapping and refusals (unit), and over HTTP against a real
``brush-studio serve --headless``: a tiny wedge study completes and its CSV downloads."""
from __future__ import annotations

import csv
import io
import time

import pytest

from studio.service.jobs import STUDIES, StudyOptionError, make_options, study_options, study_schema
from studio.presets import preset_path

TINY_WEDGE = {"preset": "wedge_60", "depth_mm": 2, "nodes": 3}  # ~10 s warm


# ----------------------------------------------------------------------------- unit
def test_options_become_the_study_model():
    o = make_options("wedge", {"preset": "wedge_60", "depth_mm": 3, "nodes": 4,
                               "no_unload": True, "max-hold": 0.5})
    assert o.preset == [str(preset_path("wedge_60"))] and o.depth_mm == 3.0
    assert o.nodes == 4 and o.no_unload and o.max_hold == 0.5
    # a list for a list option, or one value; text lists split at commas
    assert make_options("wedge", {"angles": [30, 60]}).angles == [30.0, 60.0]
    assert make_options("wedge", {"angles": "30,60"}).angles == [30.0, 60.0]
    assert make_options("sensitivity", {"preset": ["wedge_30", "wedge_45"]}).preset == [
        str(preset_path("wedge_30")), str(preset_path("wedge_45"))]
    # convergence: the scene (its positional argument) is a preset name too
    c = make_options("convergence", {"scene": "rod_tip_impulse", "quantity": "tip_deflection",
                                     "ladder": "n_nodes=3,5"})
    assert c.scene == str(preset_path("rod_tip_impulse")) and c.ladder == "n_nodes=3,5"
    # every study lists its options without the server-only ones, and has a JSON schema
    for s in STUDIES:
        names = {o["name"] for o in study_options(s)}
        assert not names & {"output", "scheduler", "workers", "no_progress", "quiet"}, s
        assert names <= set(study_schema(s)["properties"]), s
    depth = next(o for o in study_options("wedge") if o["name"] == "depth_mm")
    assert depth["unit"] == "mm" and depth["gt"] == 0
    assert study_schema("wedge")["properties"]["depth_mm"]["unit"] == "mm"


@pytest.mark.parametrize("study, options, where, text", [
    ("nope", {}, "study", "unknown study"),
    ("wedge", {"output": "/tmp/x"}, "output", "output folder is the job's own"),
    ("wedge", {"-o": "/tmp/x"}, "-o", "output folder is the job's own"),
    ("wedge", {"scheduler": "tcp://1.2.3.4:8786"}, "scheduler", "not accepted"),
    ("wedge", {"workers": 8}, "workers", "not accepted"),
    ("wedge", {"preset": "/etc/passwd"}, "preset", "not a preset name"),
    ("wedge", {"preset": "../static_presets/wedge_60"}, "preset", "not a preset name"),
    ("convergence", {"scene": "/work/x.json", "quantity": "tip_deflection"}, "scene",
     "not a preset name"),
    ("wedge", {"depth": 3}, "depth", "unknown option"),
    ("wedge", {"nodes": "abc"}, "nodes", "valid integer"),
    ("wedge", {"depth_mm": 2000}, "depth_mm", "less than or equal to 1000"),
    ("wedge", {"no_unload": "yes"}, "no_unload", "true or false"),
    ("wedge", {"nodes": {"a": 1}}, "nodes", "valid integer"),
    ("convergence", {"scene": "rod_tip_impulse"}, "quantity", "required"),
])
def test_bad_study_options_are_refused_with_the_option_named(study, options, where, text):
    with pytest.raises(StudyOptionError) as exc:
        make_options(study, options)
    assert exc.value.problems[0][0] == where
    assert text in str(exc.value)


# ----------------------------------------------------------------------------- HTTP
def test_bad_study_requests_get_422_with_clear_messages(server):
    c = server.client
    cases = [({"study": "nope"}, "unknown study"),
             ({"study": "wedge", "options": {"depth": 3}}, "unknown option"),
             ({"study": "wedge", "options": {"nodes": "x"}}, "valid integer"),
             ({"study": "wedge", "options": {"depth_mm": -1}}, "depth_mm = -1: Input should "
                                                               "be greater than 0"),
             ({"study": "wedge", "options": {"output": "/tmp/evil"}}, "not accepted"),
             ({"study": "wedge", "options": {"preset": "/etc/passwd"}}, "not a preset"),
             ({"options": {}}, "'study'"),
             ({"study": "wedge", "output": "/tmp"}, "unknown key")]
    n_before = len(c.get("/api/studies").json())
    for body, text in cases:
        r = c.post("/api/studies", json=body)
        assert r.status_code == 422, (body, r.text)
        assert text in r.json()["message"], (body, r.json())
        assert all("msg" in d and "loc" in d for d in r.json()["detail"])
    assert len(c.get("/api/studies").json()) == n_before  # nothing was queued
    types = c.get("/api/study-types").json()
    assert {"wedge", "spin", "refinement", "convergence"} <= set(types)
    assert "depth_mm" in {o["name"] for o in types["wedge"]}


def test_a_tiny_wedge_study_runs_as_a_job_and_its_files_download(server, tmp_path):
    from studio.service.client import ApiError, Client

    with Client(server.url) as client:
        sid = client.submit_study("wedge", TINY_WEDGE, name="tiny wedge")
        info = client.study(sid)
        assert info["kind"] == "study" and info["study"] == "wedge"
        # the job stores the validated model's dict: one copy, scene names resolved
        assert info["options"]["depth_mm"] == 2 and info["options"]["nodes"] == 3
        assert info["options"]["preset"] == [str(preset_path("wedge_60"))]
        seen_running = False
        deadline = time.monotonic() + 300  # a cold numba cache compiles first
        while time.monotonic() < deadline:
            info = client.study(sid)
            seen_running |= info["status"] == "running"
            if info["status"] in ("completed", "stopped", "failed", "cancelled"):
                break
            time.sleep(0.2)
        assert info["status"] == "completed", info
        assert seen_running and info["progress"] == 1.0
        assert info["summary"]["exit_code"] == 0 and info["summary"]["runs"] == 1
        print(f"tiny wedge study as a job: {info['wall_s']:.1f} s in the worker")
        assert client.wait(sid, progress=False)["status"] == "completed"
        names = client.files(sid)
        assert {"force_depth.csv", "force_depth.png", "study.json", "log.txt",
                "runs/wedge_60.h5"} <= set(names)
        path = client.download_file(sid, "force_depth.csv", tmp_path / "fd.csv")
        rows = list(csv.DictReader(io.StringIO(path.read_text())))
        depths = [float(r["depth_m"]) for r in rows]
        # 2 mm in 1 mm steps, loading then unloading: the depths the protocol visits
        assert max(depths) == pytest.approx(0.002, abs=1e-9)
        assert {r["phase"] for r in rows} == {"load", "unload"}
        assert all(float(r["force_N"]) == float(r["force_N"]) for r in rows)  # no NaN
        png = server.client.get(f"/api/studies/{sid}/files/force_depth.png")
        assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"
        # only names from the list: no traversal, no other job's files
        for bad in ("../scene.json", "..%2F..%2Fjobs.sqlite", "%2Fetc%2Fpasswd",
                    "runs/../../study_job.json", "nope.csv"):
            r = server.client.get(f"/api/studies/{sid}/files/{bad}")
            assert r.status_code == 404, (bad, r.status_code)
        with pytest.raises(ApiError) as exc:
            client.download_file(sid, "../../jobs.sqlite", tmp_path / "x")
        assert exc.value.status == 404 and not (tmp_path / "x").exists()
        # studies are listed under /api/studies, not among the scene runs
        assert sid in [s["id"] for s in client.studies()]
        assert sid not in [r["id"] for r in client.list()]
        assert server.client.get("/api/studies/0123456789ab").status_code == 404


def test_bad_study_input_reaches_the_job_error_whole(server):
    """A value the model accepts but the scene contradicts (1.5 mm is not a whole number of
    the wedge's 1 mm steps) is the study's StudyInputError: the job fails with that message
    in its error, not a log tail."""
    c = server.client
    r = c.post("/api/studies", json={"study": "wedge", "options": {
        "preset": "wedge_60", "depth_mm": 1.5, "nodes": 3}})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    deadline = time.monotonic() + 120
    while (info := c.get(f"/api/studies/{sid}").json())["status"] in ("queued", "running"):
        assert time.monotonic() < deadline
        time.sleep(0.2)
    assert info["status"] == "failed" and info["summary"]["exit_code"] == 2, info
    assert "bad input: depth 0.0015 m is not a whole number (>= 1) of 0.001 m steps" \
        in info["error"], info["error"]


def test_the_option_schema_of_every_study_is_served(server):
    c = server.client
    for study in STUDIES:
        r = c.get(f"/api/study-types/{study}/schema")
        assert r.status_code == 200, (study, r.text)
        assert r.json() == study_schema(study)
    wedge = c.get("/api/study-types/wedge/schema").json()["properties"]["depth_mm"]
    assert wedge["unit"] == "mm" and wedge["anyOf"][0]["exclusiveMinimum"] == 0
    assert c.get("/api/study-types/nope/schema").status_code == 404


def test_a_running_study_is_cancelled(server):
    c = server.client
    # the seed's dynamic protocol to 20 mm at 8 nodes runs for minutes (the quasi-static
    # method would finish before the cancel arrives)
    r = c.post("/api/studies", json={"study": "wedge", "options": {
        "preset": "wedge_60", "depth_mm": 20, "nodes": 8, "method": "dynamic"}})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    deadline = time.monotonic() + 300
    while c.get(f"/api/studies/{sid}").json()["status"] != "running":
        assert time.monotonic() < deadline
        time.sleep(0.1)
    time.sleep(3.0)  # inside the Dask run
    t0 = time.monotonic()
    c.delete(f"/api/studies/{sid}")
    while (info := c.get(f"/api/studies/{sid}").json())["status"] == "running":
        assert time.monotonic() - t0 < 40, "the cancel did not stop the study"
        time.sleep(0.2)
    assert info["status"] == "cancelled", info
