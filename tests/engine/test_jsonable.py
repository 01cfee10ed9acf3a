"""engine.jsonable, the one strict-JSON conversion of the engine's and the studio's writers:
whatever goes in, the text is standard JSON (no NaN/Infinity tokens) and reads back as the
documented values."""
from __future__ import annotations

import json
import math
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest

from engine.errors import SceneError
from engine.jsonable import finite_or_none, json_text, jsonable, jsonable_null


def _strict_loads(text: str):
    # json.loads accepts NaN/Infinity unless told otherwise: refuse them, as browsers do
    def refuse(token):
        raise ValueError(f"non-standard JSON token {token}")
    return json.loads(text, parse_constant=refuse)


VALUE = {"nan": math.nan, "inf": math.inf, "ninf": -math.inf, "x": 1.5, 3: "key as int",
         "tuple": (1, 2.5), "array": np.array([[1.0, np.nan], [np.inf, 2.0]]),
         "f32": np.float32(0.25), "i64": np.int64(7), "flag": np.bool_(True),
         "path": Path("runs/a.h5"), "nested": OrderedDict(a=[{"b": -np.inf}])}


def test_text_mode_writes_non_finite_as_strings():
    back = _strict_loads(json_text(VALUE))
    assert (back["nan"], back["inf"], back["ninf"]) == ("nan", "inf", "-inf")
    assert back["array"] == [[1.0, "nan"], ["inf", 2.0]]
    assert back["nested"] == {"a": [{"b": "-inf"}]}
    # numpy scalars as Python numbers of the same value (float32 0.25 is exact), dict keys
    # as text, tuples as lists, paths as text
    assert (back["f32"], back["i64"], back["flag"]) == (0.25, 7, True)
    assert back["3"] == "key as int" and back["tuple"] == [1, 2.5]
    assert back["path"] == str(Path("runs/a.h5")) and back["x"] == 1.5


def test_null_mode_writes_non_finite_as_null():
    back = _strict_loads(json_text(VALUE, "null"))
    assert (back["nan"], back["inf"], back["ninf"]) == (None, None, None)
    assert back["array"] == [[1.0, None], [None, 2.0]]
    assert jsonable_null(VALUE) == jsonable(VALUE, nonfinite="null")


def test_the_text_has_no_non_standard_token_and_keeps_dumps_options():
    text = json_text([math.nan, math.inf], indent=2)
    assert "NaN" not in text and "Infinity" not in text
    assert text.count("\n") == 3  # indent reached json.dumps: one line per item plus brackets


def test_a_scene_errors_values_go_through_it():
    # the scene error's problem list is what the CLI and the HTTP API print: a NaN a user
    # typed must not make that answer invalid JSON
    err = SceneError.single("run.dt", math.nan, "a positive number of seconds")
    back = _strict_loads(json.dumps(err.as_dicts(), allow_nan=False))
    assert back == [{"field": "run.dt", "value": "nan",
                     "allowed": "a positive number of seconds"}]


def test_unknown_objects_become_their_text():
    class Thing:
        def __str__(self):
            return "a thing"
    assert jsonable({"t": Thing()}) == {"t": "a thing"}
    with pytest.raises(TypeError):  # without the conversion, json refuses it
        json.dumps({"t": Thing()})


def test_finite_or_none_reads_numbers_and_refuses_the_rest():
    # CSV cells and JSON fields: a number (text or numpy) reads as itself; text that is no
    # number, a missing cell, and the non-finite values are None (a chart skips the point)
    assert finite_or_none("2.5e-3") == 2.5e-3 and finite_or_none(np.float32(0.5)) == 0.5
    assert finite_or_none(7) == 7.0 and isinstance(finite_or_none(7), float)
    for bad in ("", "n/a", None, [1.0], "nan", "inf", math.nan, -math.inf):
        assert finite_or_none(bad) is None, bad
