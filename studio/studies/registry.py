"""Every study by name: its options model, its ``run``, and the check of options that come
as a dict (from the HTTP API or the studio's Studies tab).

    from studio.studies.registry import make_options, get

    options = make_options("wedge", {"preset": "wedge_60", "depth_mm": 2, "nodes": 3})
    result = get("wedge").run(options, "out", progress=..., cancel=event)

A study's ``Options`` model (:mod:`studio.studies.options`) is the one declaration of its
options: the command line, the studio's form, the HTTP schema and this check all come from
it, so the job service accepts exactly what the command accepts. Options the job layer sets
itself (output folder, scheduler, workers, progress bars) are refused from clients, and
scenes are preset names (or designs the studio stored: ``design:<id>``) only.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

from engine.jsonable import jsonable_null as _json
from . import (convergence, detumble, docking, fur, optimise, reduce, refinement,
               sensitivity)
from .rod import study as rod_study
from .spin import study as spin_study
from .wedge import study as wedge_study
from . import capture, trap
from .options import StudyOptionError, StudyOptions, field_extra, form_fields, parse_options

__all__ = ["Study", "REGISTRY", "STUDIES", "SERVER_OPTIONS", "SCENE_OPTIONS", "get",
           "register", "StudyOptionError", "make_options", "options_from_dict",
           "options_to_dict", "study_options", "study_schema", "DESIGN_PREFIX"]


@dataclass(frozen=True)
class Study:
    """A study: its name, its options model, its ``run`` and how its parser is added
    (``add_parser(subparsers)``; ``command``: the words before it on the command line)."""

    name: str
    options: type
    run: Callable
    add_parser: Callable
    command: str = "study"

    def options_from_dict(self, data: dict) -> StudyOptions:
        """The study's ``Options`` from :func:`options_to_dict`'s dict (checked again)."""
        return parse_options(self.options, data)

    def schema(self) -> dict:
        """The JSON schema of the study's options (``Options.model_json_schema()``)."""
        return self.options.model_json_schema()


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
    "reduce": Study("reduce", reduce.Options, reduce.run, reduce.add_parser),
    "fur": Study("fur", fur.Options, fur.run, fur.add_parser),
    "docking": Study("docking", docking.Options, docking.run, docking.add_parser),
    "capture": Study("capture", capture.Options, capture.run, capture.add_parser),
    "trap": Study("trap", trap.Options, trap.run, trap.add_parser),
    "optimise": Study("optimise", optimise.Options, optimise.run, optimise.add_parser),
    "convergence": Study("convergence", convergence.Options, convergence.run,
                         convergence.register, command=""),
}
STUDIES = tuple(REGISTRY)


def register(study: Study) -> Study:
    """Add ``study`` to the registry (a new study: one options model and one ``run``;
    ``add_parser`` adds its command). Returns it."""
    if not (isinstance(study.options, type) and issubclass(study.options, StudyOptions)):
        raise TypeError(f"study {study.name!r}: its options must be a StudyOptions model")
    global STUDIES
    REGISTRY[study.name] = study
    STUDIES = tuple(REGISTRY)
    return study


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
        raise StudyOptionError([("study", study, f"unknown study; one of {list(REGISTRY)}")]
                               ) from None


def study_options(study: str) -> list[dict]:
    """The options a client may give ``study`` (the studio's form and ``GET
    /api/study-types``): the model's fields less the execution options, each with name,
    kind (flag, value, list), help, default, required, choices, unit, bounds and whether it
    names a preset."""
    out = []
    for f in form_fields(get(study).options):
        kind = {"bool": "flag", "list": "list"}.get(f["kind"], "value")
        out.append({"name": f["name"], "kind": kind, "type": f["kind"], "item": f["item"],
                    "help": f["help"], "default": _json(f["default"]),
                    "required": f["required"], "choices": _json(f["choices"]),
                    "unit": f["unit"], "preset": f["scene"],
                    **{b: f[b] for b in ("ge", "gt", "le", "lt") if b in f}})
    return out


def study_schema(study: str) -> dict:
    """The JSON schema of ``study``'s options (its model's, execution options included:
    ``POST /api/studies`` refuses those, the server sets them)."""
    return get(study).schema()


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


def _resolve_scenes(model, data: dict, designs_dir) -> dict:
    """``data`` with each scene option's preset name (or ``design:<id>``) replaced by its
    file; file paths refused."""
    out = dict(data)
    for key, value in data.items():
        name = str(key).lstrip("-").replace("-", "_")
        info = model.model_fields.get(name)
        if info is None or not (field_extra(info).get("scene") or name in SCENE_OPTIONS):
            continue
        if value is None:
            continue
        if isinstance(value, list):
            out[key] = [_resolve_preset(str(key), v, designs_dir) for v in value]
        else:
            out[key] = _resolve_preset(str(key), value, designs_dir)
    return out


def make_options(study: str, options: Optional[dict], *, scheduler: Optional[str] = None,
                 designs_dir=None) -> StudyOptions:
    """``study``'s ``Options`` for a client's ``options`` dict (option names with ``_`` or
    ``-``), checked by the study's model, with the execution the job layer chooses:
    ``scheduler``, or one worker in the job's own process; no terminal progress bars.
    Output, scheduler and worker options are refused (the job layer sets them); scenes
    are preset names (or ``design:<id>``, a design stored in ``designs_dir``) only, resolved
    to their files. Raises :class:`StudyOptionError` naming every bad option, its value and
    the bound it breaks."""
    entry = get(study)
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise StudyOptionError([("options", type(options).__name__,
                                 "must be an object of option: value")])
    problems = []
    for key, value in options.items():
        k = str(key).lstrip("-").replace("-", "_")
        if k in SERVER_OPTIONS:
            problems.append((str(key), value, f"not accepted: {SERVER_OPTIONS[k]}"))
    if problems:
        raise StudyOptionError(problems)
    data = _resolve_scenes(entry.options, options, designs_dir)
    data.update(scheduler=scheduler, workers=None if scheduler else 1, no_progress=True)
    return parse_options(entry.options, data)


def options_from_dict(study: str, data: dict) -> StudyOptions:
    """``study``'s ``Options`` from a stored dict (:func:`options_to_dict`)."""
    return get(study).options_from_dict(data)


def options_to_dict(options: StudyOptions) -> dict:
    """A study's ``Options`` as JSON-able data (:meth:`Study.options_from_dict` reads it)."""
    return _json(options.model_dump(mode="json"))
