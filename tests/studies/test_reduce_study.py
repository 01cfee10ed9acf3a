"""``brush-studio study reduce`` on a tiny brush writes a valid law file and its held-out
validation (issue 25). Slow: 13 short DEM runs."""
import json

import numpy as np
import pytest

from engine.model.reduced_law import PARAMS, load_law, torsion_radius
from studio.cli.main import main


def test_torsion_radius_of_a_square_is_the_closed_form():
    # mean distance from the centre of a unit square: (sqrt(2) + asinh(1)) / 6 = 0.38260
    # (closed form); the midpoint rule on 200 x 200 cells is within 1e-5
    assert torsion_radius(1.0, 1.0) == pytest.approx((np.sqrt(2) + np.arcsinh(1)) / 6,
                                                     rel=1e-5)


@pytest.mark.slow
def test_reduce_on_a_tiny_brush_writes_a_valid_law(tmp_path):
    # 1 x 2 bristles, 2 depths x 2 rates of sliding press, 2 x 2 slides, a held-out sliding
    # press, 4 held-out impacts: the law file must load (every parameter finite and in its
    # domain, ranges ordered), name the patch of the brush (2 tips 15 mm apart: 20 x 5 mm),
    # and carry one validation row per impact and per sliding check with finite errors. A
    # fit that silently dropped the slides (no tangential parameters) or wrote NaN would
    # fail load_law.
    out = tmp_path / "red"
    code = main(["study", "reduce", "--rows", "1", "--columns", "2", "--depths", "20,30",
                 "--rates", "10,20", "--slide-depths", "15,30", "--speeds", "80,120",
                 "--impact-speeds", "30,60", "--workers", "1", "--no-progress",
                 "-o", str(out)])
    assert code == 0
    law = load_law(out / "law.json")
    assert set(PARAMS) <= set(law["parameters"])
    assert law["patch"]["size"] == pytest.approx([0.020, 0.005])
    val = json.loads((out / "validation.json").read_text())["impacts"]
    assert len(val) == 4 and len(law["validation"]) == 4
    for row in val:
        assert all(np.isfinite(v) for v in row["errors"].values())
        assert row["dem"]["peak_fn"] > 0
    (check,) = json.loads((out / "validation.json").read_text())["sliding"]
    assert len(law["validation_sliding"]) == 1
    assert all(np.isfinite(v) for v in check["errors"].values())
    assert check["window"][0] > 0 and check["dem"]["tangential_impulse"] > 0
