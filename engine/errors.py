"""The one exception family of Brush Studio's engine.

``BrushStudioError`` is the base. ``SceneError`` names the field, the bad value and what is
allowed; ``InstabilityError`` names the quantity that failed, where (bristle/node/body), the
simulated time and what to change.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from engine.jsonable import jsonable


class BrushStudioError(Exception):
    """Base class of every error the engine raises on purpose."""


@dataclass
class FieldProblem:
    field: str  # dotted path, e.g. "brushes.0.root_radius"
    value: Any
    allowed: str

    def __str__(self) -> str:
        return f"{self.field} = {self.value!r}: {self.allowed}"


class SceneError(BrushStudioError, ValueError):
    """A scene that cannot be built. ``problems`` lists every bad field."""

    def __init__(self, problems: list[FieldProblem] | FieldProblem):
        if isinstance(problems, FieldProblem):
            problems = [problems]
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"invalid scene ({len(self.problems)} problem(s)):\n{lines}")

    @classmethod
    def single(cls, field: str, value: Any, allowed: str) -> "SceneError":
        return cls([FieldProblem(field, value, allowed)])

    def as_dicts(self) -> list[dict]:
        return [{"field": p.field, "value": jsonable(p.value), "allowed": p.allowed}
                for p in self.problems]


class InstabilityError(BrushStudioError, RuntimeError):
    """The run became (or was about to become) numerically unstable and was stopped.

    The frames recorded before the failure are kept in the result file.
    """

    def __init__(self, quantity: str, where: str, time: float, advice: str, detail: str = ""):
        self.quantity = quantity
        self.where = where
        self.time = time
        self.advice = advice
        self.detail = detail
        extra = f" ({detail})" if detail else ""
        super().__init__(
            f"instability: {quantity} at {where}, t = {time:.6g} s{extra}. {advice}")

    def as_dict(self) -> dict:
        return {"quantity": self.quantity, "where": self.where, "time": self.time,
                "advice": self.advice, "detail": self.detail, "message": str(self)}


class RunCancelled(BrushStudioError):
    """Raised internally when a cancel flag is set; ``run`` turns it into status 'cancelled'."""
