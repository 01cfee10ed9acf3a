"""The design search of the Studies tab (issue 24, item 4), without viser: which fields of the
current design can be search variables, their default bounds, the ``--variables`` text of
``brush-studio study optimise``, the search's progress read from its Optuna journal while it
runs, the objective / Pareto charts, and a trial's design as a scene.

The UI shows and takes bounds in the Design tab's units (mm, MPa, deg, through
``studio.web.fields``); the study takes SI, converted here.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from studio.web import fields as uf

#: the bending stiffness E d^4 of the bristle root: a variable of the study's own
#: (``studio.studies.optimise.variables.STIFFNESS``), in Pa m^4
STIFFNESS = "bending_stiffness"
#: the Design tab's fields a search may vary (brush geometry and material of brush 1);
#: the nodes per bristle are the study's ``nodes`` option, the seed no design choice
FIELD_KEYS = ("rows", "columns", "pitch_x", "pitch_y", "bristle_length", "root_radius",
              "tip_radius", "youngs_modulus", "poisson_ratio", "density", "bond_damping",
              "friction_bristles", "restitution_bristles", "friction_body",
              "restitution_body")
#: upper limits of fields with one (UI units): a bound past them would be refused
FIELD_MAX = {"poisson_ratio": 0.49, "restitution_bristles": 1.0, "restitution_body": 1.0,
             "friction_bristles": 80.0, "friction_body": 80.0, "bond_damping": 1.0}
#: fields best searched on a log scale (they span decades)
LOG_KEYS = ("youngs_modulus", STIFFNESS)


@dataclass(frozen=True)
class SearchField:
    """A field of the design a search can vary: ``path`` as the study takes it (SI),
    ``value`` the design's value in the UI ``unit``."""

    key: str
    label: str
    path: str
    unit: str
    value: float
    integer: bool = False

    @property
    def title(self) -> str:
        """``root radius [mm]`` (the dropdown's and the variable row's name)."""
        return f"{self.label} [{self.unit}]" if self.unit else self.label


def _target_index(scene: dict) -> int:
    """The body the search's targets replace (a body named ``cube``, else the first)."""
    for i, b in enumerate(scene.get("bodies") or []):
        if b.get("name") == "cube":
            return i
    return 0


def search_fields(scene: dict) -> list[SearchField]:
    """The numeric fields of the design's first brush (and its material and contact pairs)
    a search can vary, with their current values, then the root's bending stiffness."""
    sel = uf.Selection(brush=0, body=_target_index(scene))
    out = []
    for key in FIELD_KEYS:
        f = uf.FIELDS_BY_KEY[key]
        try:
            path = uf.resolve(f, scene, sel)
            value = uf.get_path(scene, path)
        except (uf.NotApplicable, KeyError, IndexError, TypeError):
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        text = uf.dotted(path)
        material = scene["brushes"][0].get("material")
        if text.startswith(f"materials.{material}."):  # follow the brush to its material
            text = "brushes.0.material." + text.split(".", 2)[2]
        integer = f.kind == "int"
        out.append(SearchField(key, f.label, text, "" if integer else f.unit,
                               float(value) if integer else uf.to_ui(value, f.unit),
                               integer))
    try:
        from studio.studies.optimise.variables import bending_stiffness

        out.append(SearchField(STIFFNESS, "bending stiffness E d⁴", STIFFNESS, "Pa m⁴",
                               float(f"{bending_stiffness(scene):.6g}")))
    except (KeyError, IndexError, TypeError, ValueError):
        pass
    return out


def default_bounds(f: SearchField) -> tuple[float, float, bool]:
    """Bounds around the design's value (UI units): half to twice it (a count: half to
    twice, at least one apart), on a log scale for the fields that span decades; a zero
    value searches 0 to the field's limit (or 1)."""
    v = f.value
    if f.integer:
        low = max(1, int(v) // 2)
        return float(low), float(max(2 * int(v), low + 1)), False
    top = FIELD_MAX.get(f.key)
    if v <= 0:
        return 0.0, float(top or 1.0), False
    low, high = v / 2, 2 * v
    if top is not None:
        high = min(high, top)
    return float(f"{low:.4g}"), float(f"{high:.4g}"), f.key in LOG_KEYS


def variable_text(f: SearchField, low: float, high: float, log: bool = False) -> str:
    """``PATH=LOW:HIGH[:log]`` (SI) of the study's ``--variables``, from UI bounds;
    ValueError when they cannot be a range."""
    if not (math.isfinite(low) and math.isfinite(high)) or not low < high:
        raise ValueError(f"{f.title}: the low bound must be below the high bound "
                         f"({low:g} .. {high:g})")
    if log and low <= 0:
        raise ValueError(f"{f.title}: a log scale needs a low bound above 0")
    if f.integer:
        if low != int(low) or high != int(high):
            raise ValueError(f"{f.title}: a count takes whole-number bounds")
        return f"{f.path}={int(low)}:{int(high)}"
    if f.key == STIFFNESS:
        lo, hi = low, high
    else:
        lo, hi = uf.to_si(low, f.unit), uf.to_si(high, f.unit)
    return f"{f.path}={lo:.6g}:{hi:.6g}" + (":log" if log else "")


# --------------------------------------------------------------------------- progress
@dataclass
class Trial:
    number: int
    state: str                       # COMPLETE, FAIL, RUNNING
    values: Optional[list]           # objectives (minimised)
    params: dict                     # variable path -> value (SI)
    feasible: bool = True


@dataclass
class SearchProgress:
    """What a search's Optuna journal holds so far."""

    objectives: list[str] = field(default_factory=list)   # "abs_spin_left:worst", ...
    trials: list[Trial] = field(default_factory=list)

    @property
    def done(self) -> list[Trial]:
        return [t for t in self.trials if t.state in ("COMPLETE", "FAIL")]

    @property
    def complete(self) -> list[Trial]:
        return [t for t in self.trials if t.state == "COMPLETE" and t.values]

    def best(self) -> Optional[Trial]:
        """The best complete trial by the first objective, feasible ones first."""
        done = self.complete
        if not done:
            return None
        return min(done, key=lambda t: (not t.feasible, t.values[0]))

    def best_so_far(self) -> list[tuple[int, float]]:
        """(trial number, best feasible first objective up to it), one per complete trial."""
        out, best = [], math.inf
        for t in sorted(self.complete, key=lambda t: t.number):
            if t.feasible and t.values[0] < best:
                best = t.values[0]
            if math.isfinite(best):
                out.append((t.number, best))
        return out

    def pareto(self) -> list[Trial]:
        """The feasible complete trials no other feasible one beats in every objective."""
        pts = [t for t in self.complete if t.feasible and len(t.values) >= 2]
        return sorted([t for t in pts if not any(
            all(a <= b for a, b in zip(o.values, t.values)) and o.values != t.values
            for o in pts)], key=lambda t: t.values[0])


def read_progress(folder: Path) -> Optional[SearchProgress]:
    """The search in ``folder`` (its ``optuna.journal``) as it is now; None when there is
    none yet. Read only: the study's own process writes it."""
    journal = Path(folder) / "optuna.journal"
    if not journal.is_file():
        return None
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    from studio.studies.optimise.search import STUDY_NAME

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        storage = JournalStorage(JournalFileBackend(str(journal)))
        study = optuna.load_study(study_name=STUDY_NAME, storage=storage)
    except (KeyError, ValueError, RuntimeError):  # (not created yet)
        return None
    prog = SearchProgress(objectives=list(study.user_attrs.get("objectives") or []))
    for t in study.get_trials(deepcopy=False):
        if t.user_attrs.get("interrupted"):
            continue
        cons = t.user_attrs.get("constraints") or []
        prog.trials.append(Trial(t.number, t.state.name,
                                 list(t.values) if t.values else None, dict(t.params),
                                 all(c <= 0 for c in cons)))
    if not prog.objectives and prog.complete:
        prog.objectives = [f"objective {k + 1}" for k in range(len(prog.complete[0].values))]
    return prog


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _short(path: str) -> str:
    """``brushes.0.root_radius`` -> ``root_radius``; ``brushes.0.pitch.1`` -> ``pitch.1``."""
    parts = path.split(".")
    return ".".join(parts[-2:]) if parts[-1].isdigit() else parts[-1]


def design_text(params: dict) -> str:
    """``root_radius = 0.0005, rows = 3`` (the variables' last path part, SI)."""
    return ", ".join(f"{_short(p)} = {_fmt(v)}" for p, v in params.items())


def progress_text(prog: Optional[SearchProgress], trials: Optional[int]) -> str:
    """``trials done 3 of 20 · best so far: trial 2, abs_spin_left:worst = 0.123
    (root_radius = 0.0005)`` (markdown)."""
    if prog is None:
        return "Search: no trial finished yet."
    n = len(prog.done)
    text = f"**trials done {n}" + (f" of {trials}" if trials else "") + "**"
    failed = sum(t.state == "FAIL" for t in prog.trials)
    if failed:
        text += f" ({failed} with failed runs)"
    best = prog.best()
    if best is None:
        return text + " · no complete trial yet"
    name = prog.objectives[0] if prog.objectives else "objective"
    text += (f" · best so far: trial {best.number}, {name} = {_fmt(best.values[0])}"
             f" ({design_text(best.params)})")
    if not best.feasible:
        text += " — infeasible: no trial meets the constraints yet"
    return text


def trial_label(t: Trial, objectives: list[str]) -> str:
    """The trial dropdown's entry: ``trial 3: abs_spin_left:worst = 0.123``."""
    if t.values:
        vals = ", ".join(f"{_fmt(v)}" for v in t.values)
        name = objectives[0] if len(t.values) == 1 and objectives else "objectives"
        return f"trial {t.number}: {name} = {vals}" + ("" if t.feasible else " (infeasible)")
    return f"trial {t.number}: {t.state.lower()}"


def trial_of(label: str) -> Optional[int]:
    """The trial number of a :func:`trial_label`."""
    if not label.startswith("trial "):
        return None
    try:
        return int(label[6:].split(":", 1)[0])
    except ValueError:
        return None


# --------------------------------------------------------------------------- charts
def search_figures(prog: SearchProgress, *, height: int = 420, large: bool = False) -> list:
    """``[(title, figure)]``: the first objective against the trial number (feasible dots,
    infeasible crosses, the best so far as a step line) and, with two objectives or more,
    the first two against each other with the Pareto front. ``large``: laid out for a big
    window (legend at the right)."""
    import plotly.graph_objects as go

    name = prog.objectives[0] if prog.objectives else "objective"
    done = prog.complete
    fig = go.Figure()
    for ok, style, label in ((True, dict(symbol="circle", color="#1f77b4"), "feasible"),
                             (False, dict(symbol="x", color="#d62728"), "infeasible")):
        pts = [t for t in done if t.feasible == ok]
        if pts:
            fig.add_scatter(x=[t.number for t in pts], y=[t.values[0] for t in pts],
                            mode="markers", name=f"trial ({label})", marker=style,
                            text=[design_text(t.params) for t in pts],
                            hovertemplate="trial %{x}: %{y:.4g}<br>%{text}<extra></extra>")
    bsf = prog.best_so_far()
    if bsf:
        fig.add_scatter(x=[p[0] for p in bsf], y=[p[1] for p in bsf], mode="lines",
                        line=dict(shape="hv", color="#2ca02c"), name="best so far")
    _layout(fig, f"{name} per trial (minimised)", "trial", name, height, large)
    n = max((t.number for t in done), default=0) + 1
    fig.update_xaxes(tick0=0, dtick=max(1, math.ceil(n / 8)))  # whole trial numbers
    out = [("objective per trial", fig)]
    if len(prog.objectives) >= 2 and done:
        n0, n1 = prog.objectives[:2]
        fig2 = go.Figure()
        fig2.add_scatter(x=[t.values[0] for t in done], y=[t.values[1] for t in done],
                         mode="markers", name="trials", marker=dict(color="#999999"),
                         text=[f"trial {t.number}" for t in done])
        front = prog.pareto()
        if front:
            fig2.add_scatter(x=[t.values[0] for t in front], y=[t.values[1] for t in front],
                             mode="lines+markers", name="Pareto front (feasible)",
                             line=dict(color="#ff7f0e"),
                             text=[f"trial {t.number}" for t in front])
        _layout(fig2, "Pareto front", n0, n1, height, large)
        out.append(("Pareto front", fig2))
    return out


def _layout(fig, title: str, x: str, y: str, height: int, large: bool) -> None:
    from studio.plots.study_charts import large_layout, _layout as panel_layout

    panel_layout(fig, title, x, y)
    fig.update_layout(height=height)
    if large:
        large_layout(fig)


# --------------------------------------------------------------------------- trial design
def trial_scene(options: dict, params: dict, name: str) -> dict:
    """The study's starting design (its ``preset`` option: the current design stored at
    Start, a preset or a scene file) with a trial's values: the design the trial tried,
    as a scene dict (the targets of the search's scenarios are not in it)."""
    from studio.studies.optimise.scenarios import base_scene
    from studio.studies.optimise.variables import apply_design

    preset = options.get("preset") or "spin_cube_40"
    if isinstance(preset, list):
        preset = preset[0]
    scene = base_scene(str(preset))
    apply_design(scene, dict(params), stiffness_via=options.get("stiffness_via")
                 or "youngs_modulus")
    scene["name"] = name
    return scene


def best_scene(folder: Path) -> Optional[dict]:
    """``best.json`` of a finished search (the winner against its worst scenario)."""
    path = Path(folder) / "best.json"
    if not path.is_file():
        return None
    return json.loads(path.read_text())
