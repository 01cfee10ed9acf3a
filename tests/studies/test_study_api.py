"""Each study's typed API: its ``Options`` model is exactly the options of its command line
(the parser is generated from it), a dict of options
becomes typed options through the registry, and a cancel or a progress callback reaches a
study through ``run`` without signals."""
from __future__ import annotations

import argparse
import threading

import pytest

from studio.studies import api, registry
from studio.studies.options import EXECUTION_OPTIONS, StudyOptions
from studio.studies.registry import STUDIES, StudyOptionError, make_options


def _parser(study: str) -> argparse.ArgumentParser:
    root = argparse.ArgumentParser(prog="brush-studio")
    sub = root.add_subparsers(dest="study")
    registry.get(study).add_parser(sub)
    return sub.choices[study]


@pytest.mark.parametrize("study", STUDIES)
def test_the_command_line_is_the_options_model(study):
    """Every argument of the study's command is a field of its model and every field an
    argument (the parser is generated from the model: nothing is declared twice)."""
    model = registry.get(study).options
    assert issubclass(model, StudyOptions)
    dests = {a.dest for a in _parser(study)._actions} - {"help", "output", "func"}
    assert dests == set(model.model_fields), dests ^ set(model.model_fields)


def test_a_dict_of_options_becomes_typed_options():
    opts = make_options("wedge", {"preset": "wedge_60", "depth_mm": 3, "nodes": "4"})
    assert isinstance(opts, registry.get("wedge").options)
    assert opts.depth_mm == 3.0 and opts.nodes == 4 and opts.preset[0].endswith(
        "wedge_60.json")
    # the job runs in its own process, without a terminal bar
    assert opts.workers == 1 and opts.scheduler is None and opts.no_progress
    with pytest.raises(StudyOptionError, match="valid integer"):
        make_options("wedge", {"nodes": "many"})
    back = registry.get("wedge").options_from_dict(registry.options_to_dict(opts))
    assert back == opts


@pytest.mark.parametrize("study, cli, http", [
    ("wedge", ["--depth-mm", "3", "--nodes", "4", "--angles", "30,45", "--no-unload",
               "--method", "dynamic"],
     {"depth_mm": 3, "nodes": 4, "angles": [30, 45], "no_unload": True,
      "method": "dynamic"}),
    ("spin", ["--cubes", "20", "--configs", "1", "--configs", "2", "--n-nodes", "5",
              "--random-cube", "40"],
     {"cubes": [20], "configs": "1,2", "nodes": 5, "random_cube": 40}),
    ("trap", ["--speeds", "0.3,1", "--adhesions", "0,5", "--pitches", "3", "--shots", "2"],
     {"speeds": [0.3, 1], "adhesions": "0,5", "pitches": [3], "shots": 2}),
    ("convergence", ["rod_tip_impulse", "-Q", "tip_deflection", "--dt-factor", "1,0.5"],
     {"scene": "rod_tip_impulse", "quantity": "tip_deflection", "dt_factor": [1, 0.5]}),
])
def test_the_command_line_and_a_dict_give_the_same_options(study, cli, http):
    """argv (the command line) and a JSON dict (HTTP, the studio's form) are checked by the
    same model into equal options (scene names: the job layer resolves them to files)."""
    from studio.studies.options import options_from_args

    model = registry.get(study).options
    args = _parser(study).parse_args(cli + ["-o", "out"])
    from_cli = options_from_args(model, args)
    from_http = make_options(study, http)
    fields = set(http) - {"scene", "nodes"} | ({"n_nodes"} if "nodes" in http else set())
    for name in {n for n in fields if n in model.model_fields}:
        assert getattr(from_cli, name) == getattr(from_http, name), name
    if study == "convergence":
        assert from_http.scene.endswith("rod_tip_impulse.json")


@pytest.mark.parametrize("argv, http, flag, name, bad, text", [
    (["--depth-mm", "-3"], {"depth_mm": -3}, "--depth-mm", "depth_mm", "-3", "greater than 0"),
    (["--nodes", "1"], {"nodes": 1}, "--nodes", "nodes", "1", "greater than or equal to 2"),
    (["--angles", "30,200"], {"angles": [30, 200]}, "--angles[1]", "angles[1]", "200",
     "less than 180"),
])
def test_a_bad_value_names_the_option_the_value_and_the_bound(argv, http, flag, name, bad,
                                                              text, capsys, tmp_path):
    """The command line and the HTTP dict refuse the same value with the same message:
    the option, the value and the bound."""
    from studio.cli.main import main

    assert main(["study", "wedge", *argv, "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{flag} = '{bad}'" in err and text in err
    with pytest.raises(StudyOptionError) as exc:
        make_options("wedge", http)
    option, value, message = exc.value.problems[0]
    assert option == name and text in message
    assert f"{name} = {bad}: Input should be {text}" in str(exc.value)


def test_a_set_cancel_stops_a_study_before_its_first_run(tmp_path):
    from studio.studies.wedge import study as wedge

    cancel = threading.Event()
    cancel.set()
    told = []
    result = wedge.run(wedge.Options(preset=["wedge_60"], depth_mm=1.0, nodes=3, workers=1,
                                     no_progress=True),
                       tmp_path, progress=lambda f, m: told.append((f, m)), cancel=cancel)
    # a cancel is exit 130, not a failure, and no run was started (no run file written)
    assert result.exit_code == 130 and result.status == "cancelled"
    assert not list((tmp_path / "runs").glob("*.json"))
    assert told and told[0][1].startswith("wedge runs: 0/1")


def test_bad_input_raises_a_typed_error_with_the_whole_message(tmp_path):
    from studio.studies.rod import study as rod_study
    from studio.studies.wedge import study as wedge_study

    with pytest.raises(StudyOptionError, match="cases"):
        registry.get("rod").options_from_dict({"cases": ["nope"]})
    # input the model cannot judge (the scene contradicts it) is the study's typed error
    with pytest.raises(api.StudyInputError, match="whole number"):
        wedge_study.run(wedge_study.Options(preset=["wedge_60"], depth_mm=1.5e-3,
                                            workers=1), tmp_path)
    assert rod_study.Options().cases[-1] == "response"


def test_a_session_check_raises_only_when_cancelled():
    ev = threading.Event()
    with api.session(cancel=ev):
        api.check_cancel()
        ev.set()
        with pytest.raises(KeyboardInterrupt):  # StudyCancelled: the Ctrl-C path
            api.check_cancel()
    api.check_cancel()  # outside a study: nothing to cancel
