"""studio.service.client against the real server: submit, wait, download, series, errors."""
from __future__ import annotations

import numpy as np
import pytest

import engine
from studio.service.client import ApiError, Client


def test_client_round_trip(server, tiny_scene, write_scene, tmp_path, capsys):
    with Client(server.url, timeout=300) as client:
        assert client.health()["status"] == "ok"
        run_id = client.submit(write_scene(tiny_scene()), name="from a file")
        info = client.wait(run_id, progress=True, poll=0.1, timeout=600)
        assert info["status"] == "completed" and info["name"] == "from a file"
        assert "100%" in capsys.readouterr().err  # the tqdm bar reached the end
        path = client.download(run_id, tmp_path / "out" / "run.h5")
        with engine.open_result(path) as res:
            expected = res.series("bodies/box/position")
            t = res.time
        data = client.series(run_id, "bodies/box/position")
        np.testing.assert_array_equal(data["values"], expected)
        np.testing.assert_array_equal(data["time"], t)
        assert "energy/total" in client.channels(run_id)
        assert run_id in [i["id"] for i in client.list()]
        assert client.cancel(run_id)["status"] == "completed"  # finished: unchanged
        assert client.submit(engine.parse_scene(tiny_scene()))  # a Scene object too

        bad = tiny_scene()
        bad["brushes"][0]["root_radius"] = -1.0
        with pytest.raises(ApiError) as err:
            client.submit(bad)
        assert err.value.status == 422
        assert err.value.problems[0]["field"] == "brushes.0.root_radius"
        with pytest.raises(ApiError) as err:
            client.download("0123456789ab", tmp_path / "nothing.h5")
        assert err.value.status == 404 and not (tmp_path / "nothing.h5").exists()


@pytest.mark.slow  # a server of its own; the token itself is tested in-process (safety)
def test_client_needs_the_token(start_server, tmp_path):
    server = start_server(args=("--token", "abc"), workers=1)
    with pytest.raises(ApiError) as err:
        Client(server.url).list()
    assert err.value.status == 401
    assert Client(server.url, token="abc").list() == []
