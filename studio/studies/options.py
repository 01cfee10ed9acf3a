"""A study's options, declared once: one pydantic model per study, from which come

* the command line (:func:`add_model_arguments`: ``depth_mm`` -> ``--depth-mm``, bools as
  flags, lists as repeated or comma/space separated values, ``Literal`` as choices);
* the studio's form (:func:`form_fields`: name, label, kind, default, unit, bounds, help);
* the HTTP schema (``Model.model_json_schema()``) and the check of a client's dict
  (:func:`parse_options`).

Every path checks the values with the same model, so the bounds are written once::

    class Options(StudyOptions):
        depth_mm: Optional[float] = Field(None, gt=0, le=1000, description="full depth",
                                          json_schema_extra={"unit": "mm"})

A field's ``json_schema_extra`` may also hold ``"flags"`` (the command-line spellings, e.g.
``["--nodes", "--n-nodes"]``), ``"metavar"``, ``"positional": True`` (a positional argument),
``"short"`` (e.g. ``"-Q"``), ``"scene": True`` (a preset name or file: the job layer
resolves names and refuses paths), ``"design": True`` (a scene option that takes any
design: the studio's form starts it on the current design) and ``"group"`` (its section of
the command's help). Values the user types in mm or degrees stay in those units
in the model; the study converts them to SI.
"""
from __future__ import annotations

import argparse
import math
import re
import types
import typing
from typing import Any, Iterable, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

__all__ = ["StudyOptions", "StudyOptionError", "EXECUTION_OPTIONS", "add_model_arguments",
           "options_from_args", "parse_options", "form_fields", "field_extra",
           "option_flag", "describe_errors"]


class StudyOptions(BaseModel):
    """The execution options every study has; a study's ``Options`` adds its own fields."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    scheduler: Optional[str] = Field(
        None, pattern=r"^\w+://.+$",
        description="address of an existing Dask scheduler (its workers must see the output "
                    "folder); default: a local cluster, one single-threaded worker per core",
        json_schema_extra={"metavar": "tcp://HOST:PORT", "group": "output and execution"})
    workers: Optional[int] = Field(
        None, ge=1,
        description="worker processes of the local cluster (default: one per core); 1 runs "
                    "the runs in this process, one after another, without a cluster",
        json_schema_extra={"metavar": "N", "group": "output and execution"})
    no_progress: bool = Field(False, description="no progress bar",
                              json_schema_extra={"group": "output and execution"})

    @model_validator(mode="before")
    @classmethod
    def _text_lists(cls, data):
        """A list option given as text (``angles="45,60"``, as typed on the command line or
        in an older job's options) is split at commas and spaces."""
        if isinstance(data, dict):
            for name, info in cls.model_fields.items():
                value = data.get(name)
                if isinstance(value, str) and _kind(info.annotation)[0] == "list" \
                        and _kind(_kind(info.annotation)[1])[0] != "str":
                    data = {**data, name: _typed_text(info.annotation, _split_list(value))}
        return data

    @model_validator(mode="after")
    def _one_execution(self):
        if self.scheduler is not None and self.workers is not None:
            raise ValueError("workers applies to the local cluster only; leave it out with "
                             "scheduler")
        return self

    def to_dict(self) -> dict:
        """The options as JSON-able data (:func:`parse_options` reads it back)."""
        return self.model_dump(mode="json")


#: the options every study has, set by whoever runs it (the job layer sets them itself)
EXECUTION_OPTIONS = tuple(StudyOptions.model_fields)


class StudyOptionError(ValueError):
    """Options refused: an unknown study, an unknown or bad option, a server-only option or
    a file path where a preset name belongs. ``problems``: ``(option, value, message)``;
    the message names each (``depth_mm = -1: Input should be greater than 0``)."""

    def __init__(self, problems):
        self.problems = [tuple(p) for p in problems]
        super().__init__("; ".join(f"{o} = {v!r}: {m}" if v is not None else f"{o}: {m}"
                                   for o, v, m in self.problems))

    def as_dicts(self) -> list[dict]:
        from engine.jsonable import jsonable_null

        return [{"option": o, "value": jsonable_null(v), "message": m}
                for o, v, m in self.problems]


# ----------------------------------------------------------------------------- fields
def field_extra(info) -> dict:
    """A field's ``json_schema_extra`` (a dict, or empty)."""
    extra = info.json_schema_extra
    return dict(extra) if isinstance(extra, dict) else {}


def _unwrap(annotation):
    """``(base type, optional)`` of an annotation: ``Optional[float]`` -> ``(float, True)``."""
    origin = typing.get_origin(annotation)
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return args[0], True
    return annotation, False


def _kind(annotation) -> tuple[str, Any]:
    """``(kind, item type or choices)``: bool, int, float, str, choice, list."""
    base, _ = _unwrap(annotation)
    origin = typing.get_origin(base)
    if origin is typing.Annotated:
        return _kind(typing.get_args(base)[0])
    if origin is Literal:
        return "choice", list(typing.get_args(base))
    if origin in (list, tuple):
        args = typing.get_args(base)
        return "list", (args[0] if args else str)
    if base is bool:
        return "bool", None
    if base in (int, float):
        return base.__name__, None
    return "str", None


def _bounds(info) -> dict:
    out = {}
    for m in info.metadata:
        for name in ("ge", "gt", "le", "lt"):
            v = getattr(m, name, None)
            if v is not None:
                out[name] = v
    return out


def option_flag(name: str, info=None) -> str:
    """The command-line flag of field ``name`` (its first ``flags`` entry, else
    ``--name-with-dashes``)."""
    flags = field_extra(info).get("flags") if info is not None else None
    return flags[0] if flags else "--" + name.replace("_", "-")


def _split_list(text: str) -> list[str]:
    """``"20,40 60"`` -> ``["20", "40", "60"]`` (commas or spaces; empty items dropped)."""
    return [v for v in re.split(r"[,\s]+", text.strip()) if v]


def _default_text(value) -> str:
    if isinstance(value, list):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _help(info) -> str:
    text = info.description or ""
    unit = field_extra(info).get("unit")
    if unit and f", {unit}" not in text and f" {unit}" not in text.split("(")[0]:
        text = f"{text} [{unit}]" if text else f"[{unit}]"
    default = info.get_default(call_default_factory=True)
    if default not in (None, False, [], "") and "default" not in text:
        text += f" (default {_default_text(default)})"
    return text.replace("%", "%%")


# ----------------------------------------------------------------------------- command line
def add_model_arguments(parser: argparse.ArgumentParser, model: type[StudyOptions], *,
                        skip: Iterable[str] = (), groups: Optional[dict] = None) -> None:
    """Add one argument per field of ``model`` to ``parser`` (fields in ``skip`` left out).
    Values are kept as the text typed (lists split at commas and spaces) and checked by
    the model in :func:`options_from_args`, so the parser and the HTTP API refuse the same
    values with the same message. Arguments not given are absent from the namespace: the
    model's default applies. ``groups``: argument groups already made, by title."""
    groups = dict(groups or {})
    skip = set(skip)
    for name, info in model.model_fields.items():
        if name in skip:
            continue
        extra = field_extra(info)
        group = extra.get("group")
        target = parser
        if group:
            if group not in groups:
                groups[group] = parser.add_argument_group(group)
            target = groups[group]
        kind, arg = _kind(info.annotation)
        kw: dict[str, Any] = {"dest": name, "help": _help(info), "default": argparse.SUPPRESS}
        if extra.get("metavar"):
            kw["metavar"] = extra["metavar"]
        if extra.get("positional"):
            kw.pop("dest")
            if info.is_required():
                kw.pop("default")
                target.add_argument(name, **kw)
            else:
                target.add_argument(name, nargs="?", **kw)
            continue
        flags = list(extra.get("flags") or ["--" + name.replace("_", "-")])
        if extra.get("short"):
            flags.insert(0, extra["short"])
        if kind == "bool":
            kw.pop("metavar", None)
            # a flag that is on by default is turned off by --no-<name>
            on = info.get_default(call_default_factory=True) is True
            target.add_argument(*flags, action=(argparse.BooleanOptionalAction if on
                                                else "store_true"), **kw)
        elif kind == "list":
            kw["action"] = _ListAction
            kw.setdefault("metavar", "V,...")
            target.add_argument(*flags, **kw)
        else:
            if kind == "choice":
                kw["choices"] = [str(c) for c in arg]
            if info.is_required():
                kw["required"] = True
            target.add_argument(*flags, **kw)


class _ListAction(argparse.Action):
    """A list option: repeated flags and comma/space separated values both add items."""

    def __call__(self, parser, namespace, values, option_string=None):
        items = list(getattr(namespace, self.dest, None) or [])
        items += _split_list(values)
        setattr(namespace, self.dest, items)


def options_from_args(model: type[StudyOptions], args, **fixed) -> StudyOptions:
    """``model`` from a parsed command line (an ``argparse.Namespace``; names that are not
    fields, such as ``output`` and ``func``, ignored); ``fixed``: values set on top. A bad
    value raises :class:`StudyOptionError` with the option's flag, the value and the
    bound."""
    data = {k: _typed_text(model.model_fields[k].annotation, v)
            for k, v in vars(args).items() if k in model.model_fields}
    data.update(fixed)
    return parse_options(model, data, flags=True)


def _typed_text(annotation, value):
    """A command-line text (or list of texts) as the number a numeric ``Literal`` choice
    wants (``"20"`` -> ``20``); pydantic converts every other text itself."""
    kind, arg = _kind(annotation)
    if kind == "list":
        item_kind, item_arg = _kind(arg)
        if item_kind == "choice" and isinstance(value, list):
            return [_literal_text(item_arg, v) for v in value]
    if kind == "choice":
        return _literal_text(arg, value)
    return value


def _literal_text(choices, value):
    if isinstance(value, str):
        for c in choices:
            if not isinstance(c, str) and str(c) == value.strip():
                return c
    return value


def describe_errors(model: type[BaseModel], exc: ValidationError, *, flags: bool = False
                    ) -> list[tuple]:
    """``(option, value, message)`` of each error in ``exc`` (option: the field's name, or
    its command-line flag with ``flags``)."""
    problems = []
    for e in exc.errors():
        loc = e.get("loc") or ()
        name = str(loc[0]) if loc else "options"
        info = model.model_fields.get(name)
        label = option_flag(name, info) if (flags and info is not None) else name
        if len(loc) > 1:
            label += "[" + "][".join(str(x) for x in loc[1:]) + "]"
        msg = e.get("msg", "invalid")
        ctx = e.get("ctx") or {}
        if e.get("type") == "extra_forbidden":
            msg = (f"unknown option; options: "
                   f"{sorted(set(model.model_fields) - set(EXECUTION_OPTIONS))}")
        elif e.get("type") == "value_error":
            msg = str(ctx.get("error", msg))
            if not loc:
                label = "options"
        value = e.get("input") if loc else None
        if e.get("type") in ("missing",):
            value = None
        problems.append((label, value, msg))
    return problems


def parse_options(model: type[StudyOptions], data: Optional[dict], *, flags: bool = False
                  ) -> StudyOptions:
    """``model`` checked from ``data`` (a dict from the HTTP API, the studio's form or the
    job store; option names with ``_`` or ``-``). Raises :class:`StudyOptionError` naming
    each bad option, its value and the bound it breaks."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise StudyOptionError([("options", type(data).__name__,
                                 "must be an object of option: value")])
    clean = {}
    for key, value in data.items():
        k = str(key).lstrip("-").replace("-", "_")
        if k not in model.model_fields:  # a flag's other spelling (--n-nodes: n_nodes)
            k = next((n for n, i in model.model_fields.items()
                      if "--" + k.replace("_", "-") in (field_extra(i).get("flags") or ())),
                     k)
        if isinstance(value, float) and not math.isfinite(value):
            raise StudyOptionError([(str(key), value, "must be finite")])
        info = model.model_fields.get(k)
        if info is not None and _kind(info.annotation)[0] == "bool" \
                and not isinstance(value, bool):  # no "yes" or 1 for a flag
            raise StudyOptionError([(str(key), value, "must be true or false")])
        if info is not None and value is not None and not isinstance(value, (list, tuple)) \
                and _kind(info.annotation)[0] == "list":  # one value for a list option
            item = _kind(info.annotation)[1]
            value = _split_list(value) if (isinstance(value, str) and
                                           _kind(item)[0] != "str") else [value]
        if info is not None:
            value = _typed_text(info.annotation, value)
        clean[k] = value
    try:
        return model.model_validate(clean)
    except ValidationError as exc:
        raise StudyOptionError(describe_errors(model, exc, flags=flags)) from None


# ----------------------------------------------------------------------------- form
def form_fields(model: type[StudyOptions], *, skip: Iterable[str] = EXECUTION_OPTIONS
                ) -> list[dict]:
    """The studio form of ``model``: one dict per field (``skip``: the execution options by
    default) with ``name``, ``label``, ``kind`` (bool, int, float, str, choice, list),
    ``item`` (a list's item kind), ``default``, ``unit``, ``help``, ``choices``, the bounds
    (``ge``/``gt``/``le``/``lt``), ``required``, ``optional`` (``None`` allowed), ``scene`` (a
    preset-name option) and ``design`` (a scene option that takes any design)."""
    out = []
    skip = set(skip)
    for name, info in model.model_fields.items():
        if name in skip:
            continue
        extra = field_extra(info)
        kind, arg = _kind(info.annotation)
        default = None if info.is_required() else info.get_default(call_default_factory=True)
        entry = {"name": name, "label": extra.get("label") or name.replace("_", " "),
                 "kind": kind, "default": default, "unit": extra.get("unit"),
                 "help": info.description or "", "required": info.is_required(),
                 "optional": _unwrap(info.annotation)[1], "scene": bool(extra.get("scene")),
                 "design": bool(extra.get("design")),
                 "choices": arg if kind == "choice" else None,
                 "item": (_kind(arg)[0] if kind == "list" else None)}
        entry.update(_bounds(info))
        entry["group"] = extra.get("group")
        out.append(entry)
    # the study's own options first, then the grouped ones (the protocol) as in --help
    return sorted(out, key=lambda e: e["group"] is not None)
