"""``brush-studio convergence`` (studio/studies/convergence/): observed order and Richardson
extrapolation on synthetic sequences of known order, the references against the independent
ones of tests/engine/analytic.py, the quantity extractors, and a tiny real ladder through the
command (Dask layer) writing CSV, HDF5, JSON and PNG."""
from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import engine
from studio.studies import convergence as cv
from studio.cli.main import main

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "engine"))
import analytic  # noqa: E402  (tests/engine/analytic.py: closed forms, no engine model inside)

ALONG_X = [math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0]
SILICONE = {"youngs_modulus": 2.7e6, "poisson_ratio": 0.48, "density": 1700.0}


def cone_scene(tip_force: float = 3e-6) -> dict:
    """The conical silicone bristle (33 mm, radius 1.0 -> 0.5 mm) as a horizontal cantilever
    with a small tip load (deflection 0.1 % of L) ramped in 50 ms and settled by local
    damping: its tip deflection is the tapered-beam value at every resolution."""
    return {
        "name": "cone-static",
        "materials": {"silicone": SILICONE},
        "brushes": [{"name": "brush", "material": "silicone", "bristle_length": 0.033,
                     "root_radius": 0.001, "tip_radius": 0.0005, "n_nodes": 5,
                     "base": {"orientation": ALONG_X}}],
        "loads": [{"brush": "brush", "node": -1, "force": [0.0, 0.0, -tip_force],
                   "profile": {"times": [0.0, 0.05], "values": [0.0, 1.0]}}],
        "environment": {"local_damping": 0.7},
        "run": {"duration": 0.5, "record_interval": 0.05, "channels": ["nodes"]},
    }


# ------------------------------------------------------------------------------ order, Richardson
@pytest.mark.parametrize("ladder", [[3, 5, 9, 17, 33], [4, 6, 9, 13]])
@pytest.mark.parametrize("order", [1.0, 2.0, 4.0])
def test_richardson_recovers_a_pure_power_law(ladder, order):
    h = [1.0 / (n - 1) for n in ladder]
    exact = 0.7
    q = [exact + 0.3 * x ** order for x in h]
    estimate, p = cv.richardson(h, q)
    # 1e-8: a single power law is solved exactly by the three-level formula (brentq to 1e-12)
    assert p == pytest.approx(order, abs=1e-8)
    assert estimate == pytest.approx(exact, abs=1e-8)
    errors = [(v - exact) / exact for v in q]
    assert cv.observed_orders(h, errors) == pytest.approx([order] * (len(h) - 1), abs=1e-9)
    assert cv.fitted_order(h, errors) == pytest.approx(order, abs=1e-9)


def test_richardson_with_a_higher_order_remainder():
    h = [1.0 / (n - 1) for n in (5, 9, 17, 33)]
    q = [2.0 - 0.5 * x ** 2 + 0.4 * x ** 3 for x in h]
    estimate, p = cv.richardson(h, q)
    # the h^3 term shifts the observed order of the three finest levels (h = 1/8 .. 1/32) by
    # about 0.4 h / 0.5 ~ 0.1 and leaves an O(h^3) remainder in the estimate, ~3e-5
    assert p == pytest.approx(2.0, abs=0.15)
    assert estimate == pytest.approx(2.0, abs=1e-4)
    assert abs(estimate - 2.0) < abs(q[-1] - 2.0)  # better than the finest level itself


def test_richardson_refuses_non_monotone_sequences():
    h = [0.5, 0.25, 0.125]
    assert all(math.isnan(v) for v in cv.richardson(h, [1.0, 1.2, 1.1]))  # oscillates
    assert all(math.isnan(v) for v in cv.richardson(h, [1.0, 1.1, 1.3]))  # diverges
    assert all(math.isnan(v) for v in cv.richardson(h[:2], [1.0, 1.1]))  # too few


def _levels(ns):
    return [cv.Level(i, n, None, None, f"L{i}", {}) for i, n in enumerate(ns)]


def test_analyse_reference_choice_and_cheapest_levels():
    q = cv.parse_quantity("wedge_force@10mm")
    ns = [3, 5, 9, 17]
    h = [1.0 / (n - 1) for n in ns]
    values = [1.0 + 0.2 * x ** 2 for x in h]
    walls = [0.1, 0.4, 1.6, 6.4]
    args = (q, _levels(ns), values, walls, ["completed"] * 4, [""] * 4, [1e-5] * 4)
    table = cv.analyse(*args, analytic=None)
    assert table.reference_kind == "richardson"
    assert table.reference == pytest.approx(1.0, abs=1e-10)
    assert table.richardson_order == pytest.approx(2.0, abs=1e-8)
    errors = [r["error"] for r in table.rows]
    assert errors == pytest.approx([0.2 * x ** 2 for x in h], rel=1e-8)
    # 1 %: 0.2 / 16^2 = 7.8e-4 at 17 nodes, 0.2 / 8^2 = 3.1e-3 at 9 nodes -> 9 is cheapest;
    # 5 %: 0.2 / 16 = 1.25e-2 at 5 nodes
    assert table.cheapest["0.01"]["n_nodes"] == 9
    assert table.cheapest["0.05"]["n_nodes"] == 5
    finest = cv.analyse(*args, analytic=None, reference="finest")
    assert finest.reference == values[-1] and finest.rows[-1]["error"] == 0
    # the finest level cannot be its own "cheapest within 1 %"
    assert finest.cheapest["0.01"]["n_nodes"] == 9
    given = cv.analyse(*args, analytic=cv.Reference(1.1, "analytic", "made up"))
    assert given.reference_kind == "analytic" and given.reference == 1.1
    with pytest.raises(cv.ConvergenceError, match="analytic"):
        cv.analyse(*args, analytic=None, reference="analytic")
    # a failed level is carried as a row without value; the others are analysed
    failed = cv.analyse(q, _levels(ns), [None] + values[1:], walls, ["failed"] + ["completed"] * 3,
                        ["instability"] + [""] * 3, [1e-5] * 4, analytic=None)
    assert failed.rows[0]["error"] is None and failed.rows[0]["status"] == "failed"
    assert failed.reference == pytest.approx(1.0, abs=1e-10)


# ------------------------------------------------------------------------------ parsing
def test_parse_quantities_and_ladders():
    q = cv.parse_quantity("wedge_force@20mm:wedge")
    assert (q.kind, q.depth, q.body) == ("wedge_force", pytest.approx(0.02), "wedge")
    assert cv.parse_quantity("wedge_force@0.01").depth == pytest.approx(0.01)
    q = cv.parse_quantity("spectral_peak:3")
    assert (q.kind, q.peak, q.index) == ("spectral_peak", 3, 0)
    assert cv.parse_quantity("spectral_peak").peak == 1
    assert cv.parse_quantity("body_omega_after_first_contact:cube").body == "cube"
    assert cv.parse_quantity("peak_plate_force").body is None
    assert cv.parse_quantity("tip_deflection:4").index == 4
    for bad in ("tip_force", "wedge_force", "wedge_force@-1mm", "spectral_peak:0",
                "tip_deflection:x"):
        with pytest.raises(cv.ConvergenceError):
            cv.parse_quantity(bad)
    assert cv.parse_ladder("n_nodes=3,5,9") == [3, 5, 9]
    for bad in ("nodes=3,5", "n_nodes=5,3", "n_nodes=1,3", "n_nodes="):
        with pytest.raises(cv.ConvergenceError):
            cv.parse_ladder(bad)
    assert cv.parse_factors("1,0.5,0.25") == [1.0, 0.5, 0.25]
    for bad in ("1,2", "0.5,1", "0", "x"):
        with pytest.raises(cv.ConvergenceError):
            cv.parse_factors(bad)


def test_levels_set_n_nodes_and_a_fraction_of_the_automatic_dt():
    scene = cone_scene()
    levels = cv.make_levels(scene, [3, 9], [0.5])
    assert [lv.n_nodes for lv in levels] == [3, 9]
    for lv in levels:
        auto = engine.build(engine.parse_scene(dict(cone_scene(), brushes=[
            dict(scene["brushes"][0], n_nodes=lv.n_nodes)]))).dt
        # the level's run.dt is exactly half its automatic dt (1e-12: one rounding)
        assert lv.scene["run"]["dt"] == pytest.approx(0.5 * auto, rel=1e-12)
        assert lv.scene["brushes"][0]["n_nodes"] == lv.n_nodes
    assert levels[0].run_id != levels[1].run_id
    with pytest.raises(cv.ConvergenceError, match="equal numbers"):
        cv.make_levels(scene, [3, 5, 9], [1.0, 0.5])


# ------------------------------------------------------------------------------ references
def test_elastica_reference_matches_the_independent_solutions():
    E, r, L = 200e9, 0.71e-3, 0.4
    second_moment = analytic.circle_second_moment(r)
    for alpha in (0.5, 2.0):
        x, y = cv.tapered_elastica_tip(L, E, r, r, alpha * E * second_moment / L ** 2)
        # 1e-8: both are BVP/quadrature solutions to ~1e-10 of the same elastica
        assert (x, y) == pytest.approx(analytic.elastica_tip(alpha)[:2], abs=1e-8)
    # tapered cone, small load: the Castigliano integral (linear theory; the load gives a
    # deflection of 1e-4 L, so the geometric non-linearity is ~1e-8 relative)
    cone_I = analytic.conical_second_moment(1e-3, 0.5e-3, 0.033)
    force = 1e-4 * 0.033 / analytic.tapered_cantilever_tip_deflection(1.0, 0.033, 2.7e6, cone_I)
    _, y = cv.tapered_elastica_tip(0.033, 2.7e6, 1e-3, 0.5e-3, force)
    ref = analytic.tapered_cantilever_tip_deflection(force, 0.033, 2.7e6, cone_I)
    assert y * 0.033 == pytest.approx(ref, rel=1e-6)
    # own weight only, small: w L^4 / (8 E I) (a 1 mm steel wire 0.1 m long sags 2e-4 L)
    rho_g = 7640 * 9.81
    _, y = cv.tapered_elastica_tip(0.1, E, 0.5e-3, 0.5e-3, 0.0, rho_g)
    w = rho_g * math.pi * 0.5e-3 ** 2
    assert y * 0.1 == pytest.approx(w * 0.1 ** 4 / (8 * E * analytic.circle_second_moment(0.5e-3)),
                                    rel=1e-5)


def test_analytic_references_only_for_rod_cases():
    scene = engine.parse_scene(cone_scene())
    ref = cv.analytic_reference(scene, cv.parse_quantity("tip_deflection"))
    assert ref is not None and ref.kind == "analytic"
    cone_I = analytic.conical_second_moment(1e-3, 0.5e-3, 0.033)
    # 1e-5: the elastica at a 1e-3 L deflection differs from linear theory by ~1e-6
    assert ref.value == pytest.approx(
        analytic.tapered_cantilever_tip_deflection(3e-6, 0.033, 2.7e6, cone_I), rel=1e-5)
    # a conical bristle has no closed-form frequencies here; a uniform rod has
    assert cv.analytic_reference(scene, cv.parse_quantity("spectral_peak:2")) is None
    rod = cone_scene()
    rod["brushes"][0]["tip_radius"] = 0.001
    f2 = cv.analytic_reference(engine.parse_scene(rod), cv.parse_quantity("spectral_peak:2"))
    expected = analytic.cantilever_frequencies(0.033, 2.7e6, analytic.circle_second_moment(1e-3),
                                               1700.0, analytic.circle_area(1e-3), 2)[1]
    assert f2.value == pytest.approx(expected, rel=1e-10)
    # a load along the bristle is not a bending case: no reference
    axial = cone_scene()
    axial["loads"][0]["force"] = [-3e-6, 0.0, 0.0]
    assert cv.analytic_reference(engine.parse_scene(axial),
                                 cv.parse_quantity("tip_deflection")) is None


# ------------------------------------------------------------------------------ extractors
def test_spectral_peaks_of_a_known_signal():
    t = np.arange(0, 4.0, 1e-3)
    signal = 1.0 * np.sin(2 * np.pi * 6.35 * t) + 0.05 * np.sin(2 * np.pi * 39.8 * t + 0.3) \
        + 0.01 * np.sin(2 * np.pi * 111.5 * t + 1.0)
    peaks = cv.spectral_peaks(t, signal, 3)
    # 0.02 Hz: the interpolated peak of a Blackman-Harris-windowed, 8x padded 4 s record is good to a
    # small fraction of the 0.25 Hz bin; the side lobes of the strong 6.35 Hz line (100x the
    # weakest) must not be taken for peaks
    assert peaks == pytest.approx([6.35, 39.8, 111.5], abs=0.02)


def test_first_contact_end():
    t = np.arange(0, 0.2, 0.002)
    touching = np.zeros(len(t), bool)
    touching[5:15] = True      # contact from 10 ms ...
    touching[17:25] = True     # ... a 4 ms gap (between bristle rows): the same contact
    touching[40:43] = True     # a second contact after a 30 ms gap
    assert cv.first_contact_end(t, touching, gap=0.02) == 25
    assert cv.first_contact_end(t, touching, gap=0.003) == 15
    assert cv.first_contact_end(t, np.zeros(len(t), bool)) is None
    assert cv.first_contact_end(t, np.ones(len(t), bool)) is None
    # a graze: the first episode changes the speed by 1 % (< 2 %), the second by 50 %
    speed = np.full(len(t), 10.0)
    speed[15:] = 9.9
    speed[43:] = 5.0
    assert cv.first_contact_end(t, touching, gap=0.02, speed=speed) == 43
    assert cv.contact_episodes(t, touching, gap=0.02) == [(5, 25), (40, 43)]
    # ... and a contact still going on at the end of the run has not ended
    assert cv.contact_episodes(t, touching, gap=0.02)[-1][1] is not None
    assert cv.contact_episodes(t[:42], touching[:42], gap=0.02)[-1] == (40, None)


def test_wedge_force_is_the_settled_push_back(tmp_path, tiny_scene):
    """A 2 x 2 brush pressed in two 0.4 mm parabolic steps with a 4 ms rest after each: the
    force on the box at each rest equals the roots' vertical reaction (an independent
    channel: equilibrium, no gravity)."""
    scene = tiny_scene()
    scene["environment"] = {"gravity": [0.0, 0.0, 0.0], "local_damping": 0.5}
    scene["bodies"][0]["motion"]["profile"] = {
        "kind": "stepped_parabolic", "step": 0.0004, "max_acceleration": 600.0,
        "n_steps": 2, "dwell": 0.004}
    scene["run"] = {"duration": 0.0125, "record_interval": 0.0002,
                    "channels": ["bodies", "root_force"]}
    result = engine.run(engine.build(engine.parse_scene(scene)), output=tmp_path / "r.h5")
    forces = [cv.measure(result.path, f"wedge_force@{d}mm") for d in (0.4, 0.8)]
    with engine.open_result(result.path) as res:
        depth = res.series("bodies/box/position")[0, 2] - res.series("bodies/box/position")[:, 2]
        root = res.series("brushes/brush/root_force")[:, 2]
    for d, f in zip((0.4e-3, 0.8e-3), forces):
        at = np.flatnonzero(np.abs(depth - d) < 1e-9)
        # 1e-3: at rest after 4 ms of damping both sides agree to ~1e-5 (measured); the
        # window average differs from the last frame only by the residual ringing
        assert f == pytest.approx(root[at[-1]], rel=1e-3)
    assert forces[1] > 2 * forces[0] > 0  # deeper presses harder (0.6 vs 0.2 mm of overlap)
    with pytest.raises(cv.ConvergenceError, match="never rests at depth"):
        cv.measure(result.path, "wedge_force@0.5mm")


@pytest.mark.parametrize("plate_z", [-0.0019, 0.05])
def test_peak_plate_force_counts_the_roots_standing_on_the_plate(tmp_path, tiny_scene, plate_z):
    """The tiny brush's roots (z = 0) stand on a fixed plate whose top face is 0.9 mm below
    them (within the 1 mm rooting distance; no bristle touches it): everything the box
    pushes into the brush reaches the plate through the roots. A plate 5 cm away carries
    nothing."""
    scene = tiny_scene(record_interval=0.0002)
    scene["bodies"].append({"name": "plate", "material": "pla",
                            "shape": {"type": "box", "size": [0.01, 0.01, 0.002]},
                            "pose": {"position": [0.0, 0.0, plate_z]}})
    scene["run"]["channels"] = ["bodies", "root_force"]
    result = engine.run(engine.build(engine.parse_scene(scene)), output=tmp_path / "r.h5")
    peak = cv.measure(result.path, "peak_plate_force")
    with engine.open_result(result.path) as res:
        on_plate = np.abs(res.series("bodies/plate/contact_force")).max()
        roots = np.linalg.norm(res.series("brushes/brush/root_force"), axis=1).max()
    assert on_plate == 0.0  # nothing touches the plate itself
    assert roots > 0.5  # N: the box does press the brush (0.8 mm into four bristles)
    if plate_z < 0:
        assert peak == pytest.approx(roots, rel=1e-12)
    else:
        assert peak == 0.0


# ------------------------------------------------------------------------------ command
def test_convergence_command_tiny_ladder(tmp_path, write_scene, capsys):
    path = write_scene(cone_scene())
    out = tmp_path / "conv"
    code = main(["convergence", str(path), "--quantity", "tip_deflection",
                 "--ladder", "n_nodes=3,5,9", "-o", str(out), "--workers", "1", "-q"])
    assert code == 0, capsys.readouterr().err
    with (out / "convergence.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["level", "n_nodes", "dt", "quantity", "error", "wall_s"]
    assert [int(r["n_nodes"]) for r in rows] == [3, 5, 9]
    errors = [float(r["error"]) for r in rows]
    cone_I = analytic.conical_second_moment(1e-3, 0.5e-3, 0.033)
    ref = analytic.tapered_cantilever_tip_deflection(3e-6, 0.033, 2.7e6, cone_I)
    for r, e in zip(rows, errors):
        # the error column is the quantity's relative error against the reference (the
        # elastica equals the linear value to ~1e-6 at this load)
        assert e == pytest.approx(float(r["quantity"]) / ref - 1.0, abs=1e-5)
        assert float(r["wall_s"]) > 0 and float(r["dt"]) > 0
    # the frustum bond element is exact for a tip load at any resolution: every level is
    # the tapered beam's value up to the relaxation remainder (measured -2.6e-4, +4e-5,
    # ...); the element before (one mean 1/I per segment) gave +27 %, +6.0 %, +1.45 %
    assert all(abs(e) < 1e-3 for e in errors), errors
    table = cv.load_convergence(out)
    assert table.reference_kind == "analytic"
    assert table.reference == pytest.approx(ref, rel=1e-5)
    # every level is within both tolerances: the cheapest is the one of least wall time
    walls = {int(r["n_nodes"]): float(r["wall_s"]) for r in rows}
    fastest = min(walls, key=walls.get)
    assert table.cheapest["0.05"]["n_nodes"] == fastest
    assert table.cheapest["0.01"]["n_nodes"] == fastest
    with h5py.File(out / "convergence.h5", "r") as f:
        g = f["convergence"]
        np.testing.assert_allclose(g["error"][:], errors, rtol=1e-12)
        assert list(g["n_nodes"][:]) == [3, 5, 9]
        assert g.attrs["quantity"] == "tip_deflection"
        assert g.attrs["reference_kind"] == "analytic"
    png = (out / "convergence.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    assert len(list((out / "runs").glob("*.h5"))) == 3
    printed = capsys.readouterr().out
    assert f"cheapest level within 5 %: level {[3, 5, 9].index(fastest)}" in printed


def test_convergence_command_bad_input(tmp_path, write_scene, capsys):
    path = write_scene(cone_scene())
    out = str(tmp_path / "o")
    assert main(["convergence", str(path), "--quantity", "tip_force",
                 "--ladder", "n_nodes=3,5", "-o", out]) == 2
    assert "unknown quantity" in capsys.readouterr().err
    assert main(["convergence", str(path), "--quantity", "tip_deflection",
                 "--ladder", "n_nodes=5,3", "-o", out]) == 2
    assert "increase" in capsys.readouterr().err
    assert main(["convergence", str(path), "--quantity", "tip_deflection", "-o", out]) == 2
    bad = cone_scene()
    bad["brushes"][0]["root_radius"] = -1.0
    assert main(["convergence", str(write_scene(bad, "bad.json")), "--quantity",
                 "tip_deflection", "--ladder", "n_nodes=3,5", "-o", out]) == 2
    assert "brushes.0.root_radius" in capsys.readouterr().err
    assert not (tmp_path / "o" / "convergence.csv").exists()


def test_load_convergence_refuses_other_folders(tmp_path):
    with pytest.raises(FileNotFoundError):
        cv.load_convergence(tmp_path)
    (tmp_path / "convergence.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(ValueError):
        cv.load_convergence(tmp_path)


# ------------------------------------------------------------------------------ refusals
def test_tip_deflection_of_an_undamped_free_vibration_is_refused_before_running(tmp_path,
                                                                                capsys):
    """The bug this catches: a ladder of last frames of a free vibration (the seed's weight
    release) reported as a convergence table with errors of -58 % and an order of 0.3."""
    from studio.presets import preset_path

    out = tmp_path / "conv"
    code = main(["convergence", str(preset_path("rod_weight_release")), "--quantity",
                 "tip_deflection", "--ladder", "n_nodes=3,5,9", "-o", str(out), "-q"])
    err = capsys.readouterr().err
    assert code == 2
    assert "tip_deflection needs a static scene" in err and "no damping" in err
    assert "rod_weight_static" in err   # it says what to use instead
    assert not out.exists()             # nothing ran


def test_damped_scene_and_other_quantities_are_measurable():
    from studio.presets import load_preset

    cv.check_measurable(load_preset("rod_weight_static"), cv.parse_quantity("tip_deflection"))
    cv.check_measurable(load_preset("rod_weight_release"), cv.parse_quantity("spectral_peak"))
    scene = cone_scene()
    scene["loads"][0]["profile"]["frequency"] = 5.0
    with pytest.raises(cv.ConvergenceError, match="oscillating at 5 Hz"):
        cv.check_measurable(engine.parse_scene(scene), cv.parse_quantity("tip_deflection"))


def test_other_quantities_that_do_not_fit_the_scene_are_refused():
    from studio.presets import load_preset

    impulse = load_preset("rod_tip_impulse")
    cv.check_measurable(impulse, cv.parse_quantity("spectral_peak:2"))
    with pytest.raises(cv.ConvergenceError, match="needs a body driven by a stepped"):
        cv.check_measurable(impulse, cv.parse_quantity("wedge_force@10mm"))
    with pytest.raises(cv.ConvergenceError, match="needs a hinge or free body"):
        cv.check_measurable(impulse, cv.parse_quantity("body_omega_after_first_contact"))
    wedge = load_preset("wedge_60")   # 33 steps of 1 mm
    cv.check_measurable(wedge, cv.parse_quantity("wedge_force@20mm"))
    with pytest.raises(cv.ConvergenceError, match="down to 0.033 m only"):
        cv.check_measurable(wedge, cv.parse_quantity("wedge_force@40mm"))
    driven = cone_scene()
    driven["loads"][0]["profile"]["frequency"] = 5.0   # driven to the end: no free vibration
    with pytest.raises(cv.ConvergenceError, match="free vibration after the loads end"):
        cv.check_measurable(engine.parse_scene(driven), cv.parse_quantity("spectral_peak"))
