"""Every study by name: its typed ``Options``, its ``run``, and the checking of options that
come as a dict (from the HTTP API or the studio's Studies tab).

    from studio.studies.registry import make_options, get

    options = make_options("wedge", {"preset": "wedge_60", "depth_mm": 2, "nodes": 3})
    result = get("wedge").run(options, "out", progress=..., cancel=event)

A study's command-line parser is the one declaration of its options (flags, types, choices,
help): a dict of options is checked by that parser (:func:`study_argv`), so the job service
accepts exactly what the command accepts, and then becomes the study's ``Options``
(:func:`make_options`). Options the job layer sets itself (output folder, scheduler,
workers, progress bars) are refused from clients, and scenes are preset names (or designs
the studio stored: ``design:<id>``) only.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
from dataclasses import dataclass
from typing import Callable, Optional

from engine.jsonable import jsonable_null as _json
from . import (convergence, detumble, optimise, refinement, rod_study, sensitivity,
               spin_study, wedge_study)


@dataclass(frozen=True)
class Study:
    """A study: its name, its options type, its ``run`` and how its parser is added
    (``add_parser(subparsers)``; ``command``: the words before it on the command line)."""

    name: str
    options: type
    run: Callable
    add_parser: Callable
    command: str = "study"

    def options_from_dict(self, data: dict):
        """The study's ``Options`` from :meth:`options_to_dict`'s dict."""
        if hasattr(self.options, "model_validate"):  # a pydantic options model
            return self.options.model_validate(
                {k: v for k, v in data.items() if k in self.options.model_fields})
        names = {f.name for f in dataclasses.fields(self.options)}
        return self.options(**{k: v for k, v in data.items() if k in names})


def _montecarlo_parser(sub) -> None:
    sensitivity.add_parser(sub)  # adds both sensitivity and montecarlo


#: study name -> Study (``convergence`` is a top-level command, the others ``study NAME``)
REGISTRY: dict[str, Study] = {
    "wedge": Study("wedge", wedge_study.Options, wedge_study.run, wedge_study.add_parser),
    "spin": Study("spin", spin_study.Options, spin_study.run, spin_study.add_parser),
    "refinement": Study("refinement", refinement.Options, refinement.run,
                        refinement.add_parser),
    "sensitivity": Study("sensitivity", sensitivity.SensitivityOptions,
                         sensitivity.run_sensitivity, sensitivity.add_parser),
    "montecarlo": Study("montecarlo", sensitivity.MonteCarloOptions,
                        sensitivity.run_montecarlo, _montecarlo_parser),
    "rod": Study("rod", rod_study.Options, rod_study.run, rod_study.add_parser),
    "detumble": Study("detumble", detumble.Options, detumble.run, detumble.add_parser),
    "optimise": Study("optimise", optimise.Options, optimise.run, optimise.add_parser),
    "convergence": Study("convergence", convergence.Options, convergence.run,
                         convergence.register, command=""),
}
STUDIES = tuple(REGISTRY)
#: options the job layer sets itself: a client may not choose where files go or which
#: cluster runs them
SERVER_OPTIONS = {"output": "the output folder is the job's own (DATA/runs/<id>/study/)",
                  "o": "the output folder is the job's own (DATA/runs/<id>/study/)",
                  "scheduler": "the Dask scheduler is chosen when the server starts "
                               "(brush-studio serve --scheduler)",
                  "workers": "a study job runs on one local Dask worker (or the server's "
                             "--scheduler)",
                  "no_progress": "progress is reported through the job",
                  "quiet": "progress is reported through the job",
                  "help": "not an option of a job"}
#: options naming scenes: preset NAMES only, resolved by studio.presets.preset_path
SCENE_OPTIONS = ("preset", "scene")


def get(study: str) -> Study:
    """The study named ``study``; :class:`StudyOptionError` for an unknown name."""
    try:
        return REGISTRY[study]
    except (KeyError, TypeError):
        raise StudyOptionError([("study", study, f"unknown study; one of {list(STUDIES)}")]
                               ) from None


class StudyOptionError(ValueError):
    """A study job refused: unknown study, unknown or bad option, a server-only option or a
    file path where a preset name belongs. ``problems``: ``(option, value, message)``."""

    def __init__(self, problems):
        self.problems = [tuple(p) for p in problems]
        super().__init__("; ".join(f"{o} = {v!r}: {m}" if v is not None else f"{o}: {m}"
                                   for o, v, m in self.problems))

    def as_dicts(self) -> list[dict]:
        return [{"option": o, "value": _json(v), "message": m} for o, v, m in self.problems]


def _study_parser_class():
    class _Parser(argparse.ArgumentParser):
        """argparse that raises instead of printing and exiting."""

        def error(self, message):
            raise StudyOptionError([("options", None, message)])

        def exit(self, status=0, message=None):
            raise StudyOptionError([("options", None, (message or "").strip()
                                     or f"argparse exit {status}")])

    return _Parser


def study_parser(study: str):
    """The argparse parser of ``study``'s command (the CLI's own options, errors raised as
    :class:`StudyOptionError`)."""
    entry = get(study)
    root = _study_parser_class()(prog="brush-studio study", add_help=False)
    sub = root.add_subparsers(dest="study")
    entry.add_parser(sub)
    parser = sub.choices[study]
    parser.prog = " ".join(w for w in ("brush-studio", entry.command, study) if w)
    return parser


def study_options(study: str) -> list[dict]:
    """The options a client may give ``study``: name (the options dict's key), kind (flag,
    value, list), help, default, required."""
    out = []
    for a in study_parser(study)._actions:
        if a.dest in SERVER_OPTIONS or a.dest in ("func",) or isinstance(a, argparse._HelpAction):
            continue
        if isinstance(a, argparse._StoreTrueAction):
            kind = "flag"
        elif isinstance(a, argparse._AppendAction):
            kind = "list"
        else:
            kind = "value"
        default = a.default if a.default is not argparse.SUPPRESS else None
        out.append({"name": a.dest, "kind": kind, "help": a.help or "",
                    "default": _json(default), "required": bool(a.required),
                    "choices": _json(list(a.choices)) if a.choices else None,
                    "preset": a.dest in SCENE_OPTIONS})
    return out


#: a scene option may name a design stored by the studio (``Studio.share_design``) as
#: ``design:<id>``: the file ``<data>/designs/<id>.json`` of the server's own data folder
DESIGN_PREFIX = "design:"


def _resolve_design(option: str, value: str, designs_dir) -> str:
    """``design:<id>`` -> the stored design's file; refused without a designs folder, for
    an id that is not alphanumeric (no paths) or a design that was never stored."""
    from pathlib import Path

    design_id = value[len(DESIGN_PREFIX):]
    if designs_dir is None:
        raise StudyOptionError([(option, value, "stored designs are not available here")])
    path = Path(designs_dir) / f"{design_id}.json"
    if not design_id.isalnum() or not path.is_file():
        raise StudyOptionError([(option, value, "no stored design with that id (the studio "
                                                "stores one with 'Share this design')")])
    return str(path)


def _resolve_preset(option: str, value, designs_dir=None) -> str:
    """A preset NAME -> its file (studio.presets.preset_path), ``design:<id>`` -> a stored
    design's file in ``designs_dir``; anything else refused."""
    if not isinstance(value, str) or not value.strip():
        raise StudyOptionError([(option, value, "must be a preset name (GET /api/presets)")])
    if value.startswith(DESIGN_PREFIX):
        return _resolve_design(option, value, designs_dir)
    try:
        from ..presets import list_presets, preset_path
    except ImportError as exc:  # pragma: no cover (the presets are part of the project)
        raise StudyOptionError([(option, value, f"presets unavailable: {exc}")]) from None
    try:
        return str(preset_path(value))
    except KeyError:
        names = [p["name"] for p in list_presets()]
        raise StudyOptionError([(option, value, f"not a preset name (file paths are not "
                                                f"accepted); presets: {names}")]) from None


def study_argv(study: str, options: Optional[dict], designs_dir=None) -> list[str]:
    """The command-line arguments of ``study`` for ``options`` (keys: option names with
    ``_`` or ``-``, e.g. ``{"preset": "wedge_60", "depth_mm": 3, "nodes": 4}`` ->
    ``["--preset=.../wedge_60.json", "--depth-mm=3", "--nodes=4"]``), checked with the
    study's own parser. Flags take true/false, list options a list (or one value), other
    options a value (a list is joined with commas: ``"angles": [30, 60]`` -> ``30,60``).
    Output, scheduler and worker options are refused (the job layer sets them); scenes are
    preset names (or ``design:<id>``, a design stored in ``designs_dir``) only. Raises
    :class:`StudyOptionError` naming every bad option."""
    parser = study_parser(study)
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise StudyOptionError([("options", type(options).__name__,
                                 "must be an object of option: value")])
    actions = {a.dest: a for a in parser._actions if a.dest not in ("help", "func")}
    allowed = sorted(d for d in actions if d not in SERVER_OPTIONS)
    by_flag = {f: a for a in actions.values() for f in a.option_strings
               if a.dest not in SERVER_OPTIONS}
    problems: list = []
    argv: list[str] = []
    positional: list[str] = []
    for key, value in options.items():
        k = str(key).lstrip("-").replace("-", "_")
        if k in SERVER_OPTIONS:
            problems.append((str(key), value, f"not accepted: {SERVER_OPTIONS[k]}"))
            continue
        # by its destination, or by its flag (``nodes`` is --nodes everywhere, though rod and
        # spin keep the destination n_nodes of their older spelling)
        a = actions.get(k) or by_flag.get("--" + k.replace("_", "-"))
        if a is None:
            problems.append((str(key), value, f"unknown option of study {study!r}; "
                                              f"options: {allowed}"))
            continue
        flag = next((f for f in a.option_strings if f.startswith("--")),
                    None) if a.option_strings else None
        try:
            if isinstance(a, argparse._StoreTrueAction):
                if not isinstance(value, bool):
                    raise StudyOptionError([(str(key), value, "must be true or false")])
                if value:
                    argv.append(flag)
                continue
            if value is None:
                continue
            values = list(value) if isinstance(value, (list, tuple)) else [value]
            for v in values:
                if isinstance(v, (dict, list, tuple)) or isinstance(v, bool):
                    raise StudyOptionError([(str(key), value, "must be a number or text "
                                                              "(or a list of them)")])
                if isinstance(v, float) and not math.isfinite(v):
                    raise StudyOptionError([(str(key), value, "must be finite")])
                if "\x00" in str(v) or "\n" in str(v):
                    raise StudyOptionError([(str(key), value, "bad characters")])
            if k in SCENE_OPTIONS:
                values = [_resolve_preset(str(key), v, designs_dir) for v in values]
            if not a.option_strings:  # a positional (convergence's scene)
                if len(values) != 1:
                    raise StudyOptionError([(str(key), value, "takes one value")])
                positional.append(str(values[0]))
            elif isinstance(a, argparse._AppendAction):
                argv += [f"{flag}={v}" for v in values]
            else:
                argv.append(f"{flag}=" + ",".join(str(v) for v in values))
        except StudyOptionError as exc:
            problems += exc.problems
    if problems:
        raise StudyOptionError(problems)
    argv = positional + argv
    try:
        parser.parse_args(argv + ["--output", "/nonexistent/validation-only"])
    except StudyOptionError as exc:
        raise StudyOptionError([("options", None, f"{exc.problems[0][2]} (study {study!r}; "
                                                  f"options: {allowed})")]) from None
    return argv


def make_options(study: str, options: Optional[dict], *, scheduler: Optional[str] = None,
                 designs_dir=None):
    """``study``'s typed ``Options`` for a client's ``options`` dict (checked as
    :func:`study_argv` checks it), with the execution the job layer chooses: ``scheduler``,
    or one worker in the job's own process; no terminal progress bars. Returns
    ``(options, argv)``: the argv is what the same study is on the command line."""
    entry = get(study)
    argv = study_argv(study, options, designs_dir)
    args = study_parser(study).parse_args(argv + ["--output", "/nonexistent/job-folder"])
    opts = entry.options.from_args(args)
    execution = {"scheduler": scheduler, "workers": None if scheduler else 1,
                 "no_progress": True, "quiet": True}
    if hasattr(opts, "model_copy"):  # a pydantic options model
        return opts.model_copy(update={k: v for k, v in execution.items()
                                       if k in type(opts).model_fields}), argv
    opts = dataclasses.replace(opts, **{k: v for k, v in execution.items()
                                        if k in {f.name for f in dataclasses.fields(opts)}})
    return opts, argv


def options_to_dict(options) -> dict:
    """A study's ``Options`` as JSON-able data (:meth:`Study.options_from_dict` reads it)."""
    if hasattr(options, "model_dump"):  # a pydantic options model
        return _json(options.model_dump())
    return _json(dataclasses.asdict(options))
