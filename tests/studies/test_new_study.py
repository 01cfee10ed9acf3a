"""A new study is one options model and one ``run`` (issue 23): registered, it has a command
line, a checked dict API, a form and a JSON schema, all from the model, and ``run`` returns
its data."""
from __future__ import annotations

import argparse

import pytest
from pydantic import Field

from studio.studies import api, registry
from studio.studies.options import StudyOptionError, StudyOptions, form_fields
from studio.studies.study_command import set_command


class Options(StudyOptions):
    depth_mm: float = Field(2.0, gt=0, le=50, description="full depth",
                            json_schema_extra={"unit": "mm"})
    levels: list[int] = Field([3, 5], min_length=1, description="nodes per bristle")
    loud: bool = Field(False, description="say more")


def _body(options: Options, out_dir):
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = [f"{n},{options.depth_mm * 1e-3 * n:g}" for n in options.levels]
    (out_dir / "table.csv").write_text("n,value\n" + "\n".join(rows) + "\n")
    if options.depth_mm > 40:
        raise api.StudyInputError(f"depth {options.depth_mm} mm: deeper than this scene")
    return 0, {"depth_m": options.depth_mm * 1e-3, "levels": list(options.levels)}


run = api.study_run("tiny", _body)


def add_parser(sub) -> None:
    set_command(sub.add_parser("tiny", help="a tiny test study"), run, Options)


@pytest.fixture
def tiny():
    study = registry.register(registry.Study("tiny", Options, run, add_parser))
    yield study
    registry.REGISTRY.pop("tiny")
    registry.STUDIES = tuple(registry.REGISTRY)


def _cli(argv: list[str]) -> int:
    root = argparse.ArgumentParser(prog="brush-studio")
    add_parser(root.add_subparsers(dest="study"))
    args = root.parse_args(argv)
    return args.func(args)


def test_a_new_study_runs_from_the_command_line_and_the_registry(tiny, tmp_path, capsys):
    # the command line, from the model: --depth-mm, --levels 4,6, --loud
    assert _cli(["tiny", "--depth-mm", "3", "--levels", "4,6", "--loud",
                 "-o", str(tmp_path / "cli")]) == 0
    assert (tmp_path / "cli" / "table.csv").read_text().splitlines()[1:] == [
        "4,0.012", "6,0.018"]
    # the same options as a dict (HTTP, the studio's form), checked by the same model
    opts = registry.make_options("tiny", {"depth_mm": 3, "levels": [4, 6], "loud": True})
    result = registry.get("tiny").run(opts, tmp_path / "api")
    assert result.ok and result.summary == {"depth_m": 0.003, "levels": [4, 6]}
    assert result.tables == {"table": tmp_path / "api" / "table.csv"}
    assert (tmp_path / "api" / "table.csv").read_text() == \
        (tmp_path / "cli" / "table.csv").read_text()
    # its form and schema come from the model
    assert [f["name"] for f in form_fields(Options)] == ["depth_mm", "levels", "loud"]
    assert registry.study_schema("tiny")["properties"]["depth_mm"]["unit"] == "mm"
    assert {o["name"] for o in registry.study_options("tiny")} == {"depth_mm", "levels",
                                                                   "loud"}


def test_a_new_studys_bad_input_is_refused_with_its_message(tiny, tmp_path, capsys):
    # the model's bound, on the command line and in a dict
    assert _cli(["tiny", "--depth-mm", "60", "-o", str(tmp_path / "a")]) == 2
    assert "--depth-mm = '60': Input should be less than or equal to 50" in \
        capsys.readouterr().err
    with pytest.raises(StudyOptionError, match="depth_mm = 60: Input should be less than"):
        registry.make_options("tiny", {"depth_mm": 60})
    # the study's own check: a typed error, printed whole by the command line
    assert _cli(["tiny", "--depth-mm", "45", "-o", str(tmp_path / "b")]) == 2
    assert "error: depth 45.0 mm: deeper than this scene" in capsys.readouterr().err
    with pytest.raises(api.StudyInputError, match="deeper than this scene"):
        registry.get("tiny").run(registry.make_options("tiny", {"depth_mm": 45}),
                                 tmp_path / "c")
