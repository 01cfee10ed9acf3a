"""The scene model's building blocks: strict number types (no true/false or text for a
number), the strict base model (unknown fields refused) and ``Pose``.

The cross-reference problems a model validator raises are records ``field FS value FS message``
joined by ``SEP``; ``engine.model.spec`` turns them back into one ``FieldProblem`` each.
"""
from __future__ import annotations

import json
import math
from typing import Annotated

from pydantic import (AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field,
                      field_validator, model_validator)

SEP, FS = "\x1e", "\x1f"  # record/field separators of cross-reference problems


def _number(value):
    """Numbers only: JSON's true/false and text are not numbers (pydantic's lax mode would
    read ``true`` as 1.0 and ``"2"`` as 2.0)."""
    if isinstance(value, (bool, str, bytes)):
        raise ValueError("must be a number (not true/false or text)")
    return value


_Number = BeforeValidator(_number)
PositiveFloat = Annotated[float, _Number, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, _Number, Field(ge=0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, _Number, Field(allow_inf_nan=False)]
Vector3 = tuple[FiniteFloat, FiniteFloat, FiniteFloat]


def _nonzero(a):
    if math.sqrt(sum(c * c for c in a)) < 1e-12:
        raise ValueError("must be a non-zero vector")
    return a


NonZeroVector3 = Annotated[Vector3, AfterValidator(_nonzero)]  # an axis or a direction


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=True)

    @model_validator(mode="before")
    @classmethod
    def _strict_numbers(cls, data):
        """A number field (int or float) takes numbers only, not true/false or text."""
        if isinstance(data, dict):
            bad = [k for k, v in data.items() if isinstance(v, (bool, str, bytes))
                   and k in cls.model_fields and cls.model_fields[k].annotation in (int, float)]
            if bad:
                raise ValueError(SEP.join(
                    f"{k}{FS}{json.dumps(data[k])}{FS}must be a number (not true/false or "
                    f"text)" for k in bad))
        return data


# --------------------------------------------------------------------------- poses
class Pose(_Model):
    """A rigid placement: ``position`` (m) and ``orientation`` as a unit quaternion
    ``[w, x, y, z]`` rotating local coordinates into world coordinates."""

    position: Vector3 = (0.0, 0.0, 0.0)
    orientation: tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat] = (1.0, 0.0, 0.0, 0.0)

    @field_validator("orientation")
    @classmethod
    def _unit_quaternion(cls, q):
        norm = math.sqrt(sum(c * c for c in q))
        if abs(norm - 1.0) > 1e-6:
            raise ValueError(f"must be a unit quaternion [w, x, y, z] (its norm is {norm:.6g})")
        return q
