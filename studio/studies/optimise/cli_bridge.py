"""The argparse arguments of a pydantic options model: ``--depth-mm`` from ``depth_mm``,
bools as flags, lists as comma- or space-separated values, ``Literal`` as choices; the help
is the field's description with its unit and default.

A stand-in for ``studio.studies.options.add_model_arguments`` (written in another branch):
the merge replaces this module's one function with that one.
"""
from __future__ import annotations

import argparse
import typing
from typing import Literal, get_args, get_origin

from pydantic import BaseModel


def _split(text: str) -> list[str]:
    return [t for t in text.replace(",", " ").split() if t]


class _Flatten(argparse.Action):
    """A list option given as one or several words, each holding items."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, [item for chunk in values for item in chunk])


def _base_type(annotation):
    """(type, is_list, choices) of a field's annotation (Optional unwrapped)."""
    origin = get_origin(annotation)
    if origin is typing.Union or str(origin) == "types.UnionType":
        args = [a for a in get_args(annotation) if a is not type(None)]
        return _base_type(args[0])
    if origin is list:
        inner = get_args(annotation)[0]
        return inner, True, None
    if origin is Literal:
        return str, False, list(get_args(annotation))
    return annotation, False, None


def add_model_arguments(parser: argparse.ArgumentParser, model: type[BaseModel],
                        skip: tuple = ()) -> None:
    """One ``--option`` per field of ``model`` (except ``skip``), with the field's default."""
    for name, field in model.model_fields.items():
        if name in skip:
            continue
        flag = "--" + name.replace("_", "-")
        typ, is_list, choices = _base_type(field.annotation)
        default = field.get_default(call_default_factory=True)
        extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
        unit = extra.get("unit")
        text = ((field.description or "") + (f" [{unit}]" if unit else "")).replace("%", "%%")
        if typ is bool:  # off by default: a flag; on by default: --x / --no-x
            action = argparse.BooleanOptionalAction if default else "store_true"
            parser.add_argument(flag, dest=name, action=action, default=default, help=text)
            continue
        if is_list:
            def convert(value, typ=typ, flag=flag):
                try:
                    return [typ(v) for v in _split(value)]
                except ValueError:
                    raise argparse.ArgumentTypeError(
                        f"{flag}: expected {typ.__name__} values separated by commas or "
                        f"spaces, got {value!r}") from None
            shown = ",".join(str(v) for v in default) if default else "none"
            # a variable or objective holds no comma or space: "a,b", "a b" and a b all work
            parser.add_argument(flag, dest=name, type=convert, default=default, nargs="+",
                                action=_Flatten, metavar=name.upper(),
                                help=f"{text} (default {shown})")
            continue
        parser.add_argument(flag, dest=name, type=typ if typ in (int, float, str) else str,
                            default=default, choices=choices,
                            metavar=None if choices else name.upper(),
                            help=f"{text} (default {default})")
