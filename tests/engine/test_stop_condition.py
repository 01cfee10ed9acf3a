"""run.stop: a quantity below a value, held for a time."""
from __future__ import annotations

import math

import pytest

import engine


def _spin_down(hold: float):
    # a hinge cube decaying as omega0 exp(-k1 t) (seed eq. 4.6 with k2 = 0), no contacts
    return engine.parse_scene({
        "materials": {"foam": {"youngs_modulus": 3e7, "density": 40.0}},
        "bodies": [{"name": "cube", "material": "foam",
                    "shape": {"type": "box", "size": [0.04, 0.04, 0.04]},
                    "mass_properties": {"density": 40.0},
                    "motion": {"type": "hinge", "axis": [1, 0, 0], "k1": 2.0, "k2": 0.0},
                    "angular_velocity": [10.0, 0, 0]}],
        "run": {"duration": 3.0, "record_interval": 0.01, "dt": 1e-4,
                "stop": {"quantity": "body_angular_speed", "body": "cube", "value": 1.0,
                         "hold": hold}}})


@pytest.mark.parametrize("hold", [0.0, 0.25])
def test_the_run_stops_after_the_quantity_stayed_below_for_the_hold(hold, tmp_path):
    result = engine.run(engine.build(_spin_down(hold)), output=tmp_path / "s.h5")
    assert result.status == "stopped"
    t_below = math.log(10.0) / 2.0  # omega0 exp(-k1 t) = 1 rad/s
    with engine.open_result(result.path) as res:
        t_end = float(res.time[-1])
    # the first record (every 0.01 s) at least `hold` after the first record below the value
    assert t_below + hold - 1e-9 <= t_end <= t_below + hold + 0.02 + 1e-9
