"""The studio holds its design as a validated ``engine.Scene`` (issue 23 item 5): one parse
per edit, which the cost line and the saved JSON reuse."""
from __future__ import annotations

import socket

import pytest


@pytest.fixture
def studio_app():
    import viser

    from studio.web.app import Studio, demo_scene

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    app = Studio(server, None, demo_scene())
    yield app
    app.close()
    server.stop()


def test_one_parse_per_edit_and_the_cost_line_reuses_it(studio_app, monkeypatch):
    # Bugs caught: the cost line (or the saved JSON) parsing the dict again, a design held
    # apart from the dict the fields edit (the cost of the design before the edit).
    import engine

    app = studio_app
    parses = []
    real = engine.parse_scene
    monkeypatch.setattr(engine, "parse_scene", lambda d: parses.append(1) or real(d))
    assert app.edit("rows", 3)
    app._update_run_cost()
    assert len(parses) == 1, "an edit parses the design once"
    assert isinstance(app.design, engine.Scene) and app.design.brushes[0].rows == 3
    assert app.scene["brushes"][0]["rows"] == 3
    n_nodes = 3 * app.design.brushes[0].columns * app.design.brushes[0].n_nodes
    assert app.run_cost.cost.n_nodes == n_nodes and f"**{n_nodes:,}** nodes" in \
        app.md_cost.content
    assert real(app.design_json()) == app.design
    assert len(parses) == 1, "the cost line and the saved JSON reuse the edit's parse"
    # a refused edit keeps the design and its cost line
    held = app.design
    assert not app.edit("n_nodes", 1)
    app._update_run_cost()
    assert app.design is held
