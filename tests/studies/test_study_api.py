"""Each study's typed API: its ``Options`` name exactly the options of its command line (so
``Options.from_args`` loses none and the job service can build them), a dict of options
becomes typed options through the registry, and a cancel or a progress callback reaches a
study through ``run`` without signals."""
from __future__ import annotations

import dataclasses
import threading

import pytest

from studio.studies import api, registry
from studio.studies.registry import STUDIES, StudyOptionError, make_options, study_parser


@pytest.mark.parametrize("study", STUDIES)
def test_options_fields_are_the_command_line_options(study):
    parser = study_parser(study)
    dests = {a.dest for a in parser._actions if a.dest not in ("help", "output")}
    kind = registry.get(study).options
    fields = (set(kind.model_fields) if hasattr(kind, "model_fields")  # a pydantic model
              else {f.name for f in dataclasses.fields(kind)})
    # a flag the command has but the Options lack would be dropped on the way to run()
    assert dests <= fields, dests - fields
    # an Options field that no flag sets is a constant of the study (refinement's angles)
    assert fields - dests <= {"angles", "no_progress", "quiet"}, fields - dests


def test_a_dict_of_options_becomes_typed_options():
    opts, argv = make_options("wedge", {"preset": "wedge_60", "depth_mm": 3, "nodes": "4"})
    assert isinstance(opts, registry.get("wedge").options)
    assert opts.depth_mm == 3.0 and opts.nodes == 4 and opts.preset[0].endswith(
        "wedge_60.json")
    # the job runs in its own process, without a terminal bar
    assert opts.workers == 1 and opts.scheduler is None and opts.no_progress
    assert argv[0].startswith("--preset=")
    with pytest.raises(StudyOptionError, match="invalid int value"):
        make_options("wedge", {"nodes": "many"})
    back = registry.get("wedge").options_from_dict(registry.options_to_dict(opts))
    assert back == opts


def test_a_set_cancel_stops_a_study_before_its_first_run(tmp_path):
    from studio.studies import wedge_study as wedge

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


def test_bad_options_are_bad_input_not_an_exception(tmp_path):
    from studio.studies import rod_study

    result = rod_study.run(rod_study.Options(cases="nope"), tmp_path)
    assert result.exit_code == 2 and result.status == "bad_input"


def test_a_session_check_raises_only_when_cancelled():
    ev = threading.Event()
    with api.session(cancel=ev):
        api.check_cancel()
        ev.set()
        with pytest.raises(KeyboardInterrupt):  # StudyCancelled: the Ctrl-C path
            api.check_cancel()
    api.check_cancel()  # outside a study: nothing to cancel
