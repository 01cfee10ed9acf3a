"""Fixtures of the studio UI tests: the demo scene as the studio's working dict."""
from __future__ import annotations

import pytest


@pytest.fixture
def demo(demo_scene_dict):
    """The demo scene, validated and dumped the way the studio keeps it."""
    import engine
    from studio.web import scene as us

    return us.scene_dict(engine.parse_scene(demo_scene_dict))
