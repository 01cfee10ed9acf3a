"""The studio's Studies tab: start a study as a job and look at what it wrote.

The form offers the studies people start from the studio (:data:`STUDY_NAMES`: wedge, spin,
refinement, convergence), each generated from the study's options model (:func:`form_spec`:
the command line's fields, defaults, units and help; a scene field starts on the current
design), plus an "other options" JSON field (any option of the study, docs/studies.md). Start submits the study through
the same :class:`studio.service.jobs.JobManager` as the HTTP API (``submit_study``: the study runs in
a worker process, its files under ``DATA/runs/<id>/study/``). When it has finished, the tab
shows its PNG plots as images, a convergence study's table (markdown) and log-log error
against wall time (plotly, from ``studio.studies.convergence.load_convergence``), and lists its files
for download.

The pure helpers (:func:`form_options`, :func:`convergence_markdown`,
:func:`convergence_figure`, :func:`png_array`) are what the tests check without a browser.
"""
from __future__ import annotations

import json
import math
from fnmatch import fnmatch
from pathlib import Path
from typing import Any, Callable, Optional

from studio.web.panels.common import (NO_JOBS, _fmt_s, _one_line, follow_job, job_of,
                            set_job_choices)
from studio.plots.study_charts import study_charts, study_eta

#: the studies the tab offers; each form is generated from the study's options model
#: (:func:`form_spec`): its fields, defaults, units and help are the command line's
STUDY_NAMES = ("wedge", "spin", "refinement", "convergence", "optimise")
#: the first choice of every scene dropdown that takes any scene: the session's design as it
#: is now (stored, then named to the study as ``design:<id>``, see
#: ``studio.studies.registry``); the form starts on it when the studio has a design
CURRENT_DESIGN = "(current design)"
#: a dropdown's "leave it out" choice: the study's own default applies
DEFAULT_CHOICE = "(default)"
MAX_IMAGES = 6  # PNG plots shown for one study
#: study -> its PNG plots an interactive chart (studio.plots.study_charts) replaces in the tab
CHARTED_PNGS = {"wedge": ("force_depth.png",), "spin": ("omega_*.png",),
                "refinement": ("refinement.png",), "optimise": ("*_vs_*.png", "pareto.png")}
#: the study whose form picks its variables from the design (issue 24, item 4)
SEARCH = "optimise"
#: the option the variable rows fill (the text field is left out of the form)
VARIABLES = "variables"
SEARCH_POLL_S = 1.0   # s between reads of a running search's journal
POPOUT_WINDOW = (900, 680)  # px: the study charts' window, floating over the view
#: viser draws a plot ``aspect`` times as TALL as the panel is wide (height = width x
#: aspect): the study charts had PLOT_ASPECT's 0.62, 330 x 205 px less their margins and
#: legend, a plot area of ~165 x 60 px (issue 29, item 7)
STUDY_CHART_ASPECT = 1.1    # in the side panel: ~330 x 360 px, a plot area ~265 x 200
POPOUT_ASPECT = 0.6         # in the pop-out window: ~880 x 530 px
NO_TRIALS = "(no trial yet)"


class FormError(ValueError):
    """A form value that cannot be an option (shown beside the Start button)."""


def _label(field: dict) -> str:
    """``depth_mm`` with unit mm -> ``depth [mm]``; others their name with spaces."""
    name, unit = field["name"], field.get("unit")
    if unit:
        suffix = "_" + unit.replace("/", "_per_")
        # (case aside: stress_limit_mpa with unit MPa is "stress limit [MPa]")
        base = name[:-len(suffix)] if name.lower().endswith(suffix.lower()) else name
        return f"{base.replace('_', ' ')} [{unit}]"
    return name.replace("_", " ")


def form_spec(study: str) -> list[dict]:
    """The form of ``study``: its options model's fields less the execution options
    (:func:`studio.studies.options.form_fields`), each with its ``label`` and ``widget``
    (scene, number, text, bool, choice). Optional numbers are text fields: empty means the
    study's default (the scene's own resolution, the profile's depth)."""
    from studio.studies.options import form_fields
    from studio.studies.registry import get

    try:
        fields = form_fields(get(study).options)
    except Exception as exc:  # StudyOptionError: unknown study
        raise FormError(str(exc)) from None
    out = []
    for f in fields:
        f = dict(f, label=_label(f))
        if f["scene"]:
            f["widget"] = "scene"
        elif f["kind"] == "bool":
            f["widget"] = "bool"
        elif f["kind"] == "choice":
            f["widget"] = "choice"
        elif f["kind"] in ("int", "float") and not f["optional"] and f["default"] is not None:
            f["widget"] = "number"
        else:
            f["widget"] = "text"
        out.append(f)
    return out


def fine_step(*values: float) -> float:
    """A number box's step (and so its decimals, in viser): a thousandth of the largest
    value's decade, so that values typed to three significant digits arrive as typed."""
    top = max((abs(v) for v in values if v and math.isfinite(v)), default=1.0)
    return 10.0 ** (math.floor(math.log10(top)) - 3)


def _trial_number(label: str) -> Optional[int]:
    from studio.web.design_search import trial_of

    return trial_of(label or "")


def form_spec_default(study: str, name: str) -> list[str]:
    """The default of option ``name`` of ``study`` as a list of text."""
    d = next(f["default"] for f in form_spec(study) if f["name"] == name)
    return [str(v) for v in (d if isinstance(d, list) else [d])]


def _initial(field: dict):
    """A widget's first value: the model's default in the widget's terms."""
    d = field["default"]
    if field["widget"] in ("scene", "choice"):
        return DEFAULT_CHOICE if d in (None, []) else str(d)
    if field["widget"] == "bool":
        return bool(d)
    if field["widget"] == "number":
        return d
    if isinstance(d, list):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in d)
    return "" if d is None else str(d)


def form_options(study: str, values: dict, extra: str = "") -> dict:
    """The options dict of ``study`` from the form's ``values`` (option name -> widget
    value) and the "other options" JSON text ``extra`` (an object; its keys override the
    form's). Empty text fields, ``(default)`` choices and false flags are left out (the
    study's default applies); the values are checked by the study's model when the job is
    submitted (``JobManager.submit_study``), with the messages of the command line."""
    spec = {f["name"]: f for f in form_spec(study)}
    out: dict = {}
    for name, v in values.items():
        f = spec.get(name)
        if f is None:
            raise FormError(f"{name}: not an option of study {study!r}")
        if f["widget"] == "bool":
            # (a flag on by default, optimise's refine, is sent when it is unticked)
            if bool(v) != bool(f["default"]):
                out[name] = bool(v)
        elif f["widget"] == "number":
            if v is None:
                continue
            if isinstance(v, float) and not math.isfinite(v):
                raise FormError(f"{f['label']}: must be finite")
            if v != f["default"]:
                out[name] = v
        elif f["widget"] in ("scene", "choice"):
            if v not in (None, "", DEFAULT_CHOICE, _initial(f)):
                out[name] = [v] if f["kind"] == "list" else v
        else:
            text = str(v).strip() if v is not None else ""
            if text and text != _initial(f):
                out[name] = text
    extra = (extra or "").strip()
    if extra:
        try:
            more = json.loads(extra)
        except ValueError as exc:
            raise FormError(f"other options: not JSON ({exc})") from None
        if not isinstance(more, dict):
            raise FormError('other options: must be a JSON object, e.g. {"max_hold": 0.5}')
        out.update(more)
    return out


def convergence_markdown(table) -> str:
    """A convergence study's table (``studio.studies.convergence.ConvergenceTable``) as markdown:
    one row per level, then the reference, the observed order and the cheapest levels."""
    def num(x, fmt):
        return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) \
            else format(x, fmt)

    head = f"**{table.quantity} [{table.unit}]** of `{table.scene_name}`"
    # narrow columns for the side panel: dt in µs, the error in per cent, short numbers
    rows = [f"| level | nodes | dt [µs] | {table.quantity} | error [%] | wall [s] | |",
            "|---:|---:|---:|---:|---:|---:|---|"]
    for r in table.rows:
        err = r.get("error")
        rows.append(f"| {r['level']} | {'' if r.get('n_nodes') is None else r['n_nodes']} | "
                    f"{'auto' if r.get('dt') is None else format(r['dt'] * 1e6, '.3g')} | "
                    f"{num(r.get('quantity'), '.5g')} | "
                    f"{num(None if err is None else 100 * err, '+.2g')} | "
                    f"{num(r.get('wall_s'), '.1f')} | "
                    f"{'ok' if r.get('status') == 'completed' else r.get('status', '')} |")
    ref = "none" if table.reference is None else f"{table.reference:.8g} {table.unit}"
    notes = [f"reference: {ref} ({table.reference_kind}: {table.reference_note})"]
    orders = ", ".join(num(o, ".3g") for o in table.observed_orders)
    if orders:
        notes.append(f"observed order (h = {table.resolution}): {orders}; fit "
                     f"{num(table.fitted_order, '.3g')}")
    for tol, row in (table.cheapest or {}).items():
        notes.append(f"cheapest within {100 * float(tol):g} %: " + (
            "none" if row is None else f"level {row['level']} in {row['wall_s']:.2f} s"))
    return "\n\n".join([head, "\n".join(rows)] + ["- " + n for n in notes])


def convergence_figure(table):
    """Log-log |error| against wall time, one marker per level (plotly figure); levels with
    no error (the reference level itself, failed levels) are left out."""
    import plotly.graph_objects as go

    xs, ys, labels = [], [], []
    for r in table.rows:
        e, w = r.get("error"), r.get("wall_s")
        if e is None or w is None or not (math.isfinite(e) and math.isfinite(w)) \
                or e == 0 or w <= 0:
            continue
        xs.append(w)
        ys.append(abs(e))
        labels.append(f"level {r['level']}" + (f", n={r['n_nodes']}" if r.get("n_nodes")
                                              else ""))
    fig = go.Figure()
    fig.add_scatter(x=xs, y=ys, mode="lines+markers+text", text=labels,
                    textposition="top center", name=table.quantity)
    fig.update_layout(title=dict(text=f"{table.quantity}: error against wall time",
                                 font=dict(size=13)),
                      # (room either side: the first and last levels' labels stay whole)
                      xaxis=dict(type="log", title="wall time [s]", range=[
                          math.log10(min(xs)) - 0.25, math.log10(max(xs)) + 0.25]
                          if xs else None),
                      yaxis=dict(type="log", title="|relative error|"),
                      margin=dict(l=50, r=10, t=30, b=40), height=300, showlegend=False)
    return fig


def png_array(path: Path, max_side: int = 900):
    """A PNG file as an RGB uint8 array (downscaled so its longer side is at most
    ``max_side`` pixels)."""
    import numpy as np
    from PIL import Image

    with Image.open(path) as im:
        im = im.convert("RGB")
        scale = max(im.size) / max_side
        if scale > 1:
            im = im.resize((int(im.size[0] / scale), int(im.size[1] / scale)))
        return np.asarray(im, dtype=np.uint8)


class StudiesTab:
    """The Studies tab's widgets and behaviour (built inside ``tab``; ``poll`` is called by
    the studio's polling thread)."""

    def __init__(self, gui, tab, jobs, preset_names: list[str], md_escape,
                 current_design: Optional[Callable[[], tuple[str, str]]] = None,
                 design_scene: Optional[Callable[[], dict]] = None,
                 load_design: Optional[Callable[[dict, str], Optional[str]]] = None):
        self.gui = gui
        self.jobs = jobs
        self.esc = md_escape
        # () -> (scene reference, design name) of the session's design as it is now
        self.current_design = current_design
        # () -> the session's design as a scene dict (the search's variables come from it)
        self.design_scene = design_scene
        # (scene dict, label) -> None or the refusal: put a scene into the design view
        self.load_design = load_design
        self.var_rows: dict[str, dict] = {}   # variable path -> its row's handles and field
        self._field_titles: tuple = ()
        self.search_job: Optional[str] = None  # the search the Design search folder shows
        self.search_progress = None
        self.search_plots: list = []
        self.search_figs: list = []
        self._search_read = 0.0
        self._search_sig = None
        self.search_loaded: Optional[str] = None
        self.figures: list = []                # (title, plotly figure) the tab shows
        self.popout = None                     # the charts' floating window
        self.popout_plots: list = []
        self.charts: list = []
        self.active: Optional[str] = None     # the study started here and followed
        self.active_study: Optional[str] = None
        self.shown: Optional[str] = None      # the study whose results are shown
        self.shown_status: Optional[str] = None
        self.images: list = []
        self.plot = None
        self.last_error: Optional[str] = None
        self._list_md = ""
        self.fields: dict[str, dict[str, Any]] = {}
        presets = list(preset_names) or ["wedge_60"]
        with tab:
            self.dd_study = gui.add_dropdown("study", STUDY_NAMES, initial_value="wedge")
            self.dd_study.on_update(lambda e: self._show_form())
            for study in STUDY_NAMES:
                self.fields[study] = {f["name"]: self._widget(f, presets)
                                      for f in form_spec(study)}
            self.fields[SEARCH][VARIABLES].visible = False
            # the search starts on the design being edited (its variables are picked from
            # it), not on the study's own default rig design
            preset = self.fields[SEARCH].get("preset")
            if preset is not None and CURRENT_DESIGN in preset.options:
                preset.value = CURRENT_DESIGN
            self._build_variables_gui(gui)
            self.tx_extra = gui.add_text("other options (JSON)", "")
            self.bt_start = gui.add_button("Start study", color="green")
            self.bt_start.on_click(lambda e: self.start())
            self.bt_cancel = gui.add_button("Cancel study", color="red", disabled=True)
            self.bt_cancel.on_click(lambda e: self.cancel())
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.md_status = gui.add_markdown("No study started yet.")
            with gui.add_folder("Studies", expand_by_default=False):
                self.md_list = gui.add_markdown("No studies yet.")
                self.dd_list = gui.add_dropdown("study job", (NO_JOBS,))
                self.bt_show = gui.add_button("Show selected study")
                self.bt_show.on_click(lambda e: self._show_selected())
            with gui.add_folder("Study results", expand_by_default=True):
                self.md_result = gui.add_markdown("Finished studies show here.")
                self.dd_file = gui.add_dropdown("file", ("(none)",), disabled=True)
                self.bt_download = gui.add_button("Download file", disabled=True)
                self.bt_download.on_click(self._on_download)
                self.md_table = gui.add_markdown("", visible=False)
                self.bt_popout = gui.add_button(
                    "Pop out charts", disabled=True,
                    hint="the study's charts large, in a window over the view")
                self.bt_popout.on_click(lambda e: self.pop_out())
                self.results_folder = gui.add_folder("Plots", expand_by_default=True)
            self._build_search_gui(gui)
        self._show_form()

    # ----------------------------------------------------------------- form
    def _widget(self, f: dict, presets: list[str]):
        """The widget of form field ``f`` (:func:`form_spec`). A scene field that takes any
        scene starts on the current design (its own resolution kept: the nodes field is
        empty, the scene's); the studies' own presets (rod, spin) on ``(default)``."""
        gui, label, hint = self.gui, f["label"], f["help"] or None
        initial = _initial(f)
        if f["widget"] == "scene":
            first = [CURRENT_DESIGN] if (self.current_design is not None and f["design"]) \
                else []
            if first and initial == DEFAULT_CHOICE:
                initial = CURRENT_DESIGN
            opts = tuple(dict.fromkeys(first + [DEFAULT_CHOICE] + presets))
            if initial not in opts:
                opts = opts + (initial,)
            return gui.add_dropdown(label, opts, initial_value=initial, hint=hint)
        if f["widget"] == "choice":
            opts = tuple(([DEFAULT_CHOICE] if f["optional"] else [])
                         + [str(c) for c in f["choices"]])
            return gui.add_dropdown(label, opts, initial_value=initial, hint=hint)
        if f["widget"] == "bool":
            return gui.add_checkbox(label, initial, hint=hint)
        if f["widget"] == "number":
            bounds = {k: f[b] for k, b in (("min", "ge"), ("max", "le")) if b in f}
            if f["kind"] == "int":
                return gui.add_number(label, int(initial), step=1, hint=hint, **bounds)
            # (viser derives the box's decimals from its step, and its step from the first
            # value: 0.4 s took one decimal, so a typed 0.02 became 0.0)
            return gui.add_number(label, float(initial), hint=hint,
                                  step=fine_step(float(initial)), **bounds)
        return gui.add_text(label, initial, hint=hint)

    def _show_form(self) -> None:
        study = self.dd_study.value
        for s, handles in self.fields.items():
            for name, h in handles.items():
                h.visible = s == study and not (s == SEARCH and name == VARIABLES)
        self.vars_folder.visible = study == SEARCH
        if study == SEARCH:
            self._refresh_field_choices()

    # ----------------------------------------------------------------- design variables
    def _build_variables_gui(self, gui) -> None:
        """The search's variables, picked from the design's fields (issue 24, item 4)."""
        self.vars_folder = gui.add_folder("Design variables", expand_by_default=True,
                                          visible=False)
        with self.vars_folder:
            self.md_vars = gui.add_markdown("")
            self.dd_var_field = gui.add_dropdown(
                "design field", ("(none)",),
                hint="a numeric field of the design's brush; Add variable searches it "
                     "between the bounds of its row")
            self.bt_add_var = gui.add_button("Add variable")
            self.bt_add_var.on_click(lambda e: self.add_variable(self.dd_var_field.value))
        self._vars_note()

    def _fields(self) -> list:
        from studio.web.design_search import search_fields

        if self.design_scene is None:
            return []
        try:
            return search_fields(self.design_scene())
        except Exception:  # (a design the mapping cannot read: nothing to pick)
            return []

    def _refresh_field_choices(self) -> None:
        titles = tuple(f.title for f in self._fields()) or ("(none)",)
        if titles != self._field_titles:
            self._field_titles = titles
            keep = self.dd_var_field.value
            self.dd_var_field.options = titles
            self.dd_var_field.value = keep if keep in titles else titles[0]

    def _vars_note(self) -> None:
        if self.var_rows:
            self.md_vars.content = (f"{len(self.var_rows)} variable"
                                    f"{'s' if len(self.var_rows) != 1 else ''} of the design "
                                    "searched between their bounds (the Design tab's units).")
        else:
            default = ", ".join(form_spec_default(SEARCH, VARIABLES))
            self.md_vars.content = ("Pick the design's fields to search: choose one, *Add "
                                    f"variable*. None picked: the study's default `{default}`.")

    def add_variable(self, title: str) -> Optional[str]:
        """Add a variable row for the design field titled ``title`` (bounds from half to
        twice its value now); returns its path (None: no such field, or already there)."""
        from studio.web.design_search import default_bounds

        f = next((x for x in self._fields() if x.title == title), None)
        if f is None or f.path in self.var_rows:
            return None
        low, high, log = default_bounds(f)
        gui = self.gui
        with self.vars_folder:
            folder = gui.add_folder(f"{f.title}: {f.value:g} now")
        with folder:
            unit = f" [{f.unit}]" if f.unit else ""
            kw = {"step": 1 if f.integer else fine_step(low, high, f.value)}
            nb_low = gui.add_number(f"{f.label} from{unit}", low, **kw)
            nb_high = gui.add_number(f"{f.label} to{unit}", high, **kw)
            cb_log = gui.add_checkbox(f"{f.label} on a log scale", log,
                                      disabled=f.integer)
            bt = gui.add_button(f"Remove {f.label}", color="gray")
        bt.on_click(lambda e, p=f.path: self.remove_variable(p))
        self.var_rows[f.path] = {"field": f, "folder": folder, "low": nb_low,
                                 "high": nb_high, "log": cb_log}
        self._vars_note()
        return f.path

    def remove_variable(self, path: str) -> None:
        row = self.var_rows.pop(path, None)
        if row is not None:
            row["folder"].remove()
        self._vars_note()

    def variables(self) -> list[str]:
        """The variable rows as the study's ``--variables`` (SI); FormError on bad bounds."""
        from studio.web.design_search import variable_text

        out = []
        for row in self.var_rows.values():
            try:
                out.append(variable_text(row["field"], float(row["low"].value),
                                         float(row["high"].value), bool(row["log"].value)))
            except (TypeError, ValueError) as exc:
                raise FormError(str(exc)) from None
        return out

    def options(self) -> tuple[dict, Optional[str]]:
        """The form's options, and the name of the design they study when a scene field
        is on the current design (stored now: the study sees it as it is at Start)."""
        study = self.dd_study.value
        values = {name: h.value for name, h in self.fields[study].items()}
        design = None
        for name, value in values.items():
            if value == CURRENT_DESIGN:
                if self.current_design is None:
                    raise FormError("no design to study in this tab")
                ref, design = self.current_design()
                if ref is None:
                    raise FormError("studying the current design needs the studio's data "
                                    "folder")
                values[name] = ref
        if study == SEARCH:
            values.pop(VARIABLES, None)
            if design is not None and self.design_scene is not None:
                scene = self.design_scene()
                n = len(scene.get("brushes") or [])
                if n != 1:
                    raise FormError(f"the design search varies one brush; this design has "
                                    f"{n} (remove the others, or pick a preset)")
                bodies = [b.get("name") for b in scene.get("bodies") or []]
                if "cube" not in bodies and len(bodies) != 1:
                    raise FormError("the design search's targets take the place of the "
                                    "design's body: it needs one body (or one named "
                                    f"'cube'); this design has {len(bodies)}")
        options = form_options(study, values, self.tx_extra.value)
        if study == SEARCH and self.var_rows and VARIABLES not in options:
            options[VARIABLES] = self.variables()
        return options, design

    def start(self) -> Optional[str]:
        """Submit the form's study; returns the job id (None if refused)."""
        from studio.service.jobs import StudyOptionError

        study = self.dd_study.value
        try:
            options, design = self.options()
            name = f"{study} study of design {design!r}" if design else None
            job_id = self.jobs.submit_study(study, options, name=name)
        except (FormError, StudyOptionError) as exc:
            self.last_error = str(exc)
            # red on the panel, as the Run tab's refusals (issue 29, item 8)
            self.md_status.content = (f"<span style='color:#d00'><b>Refused:</b> "
                                      f"{self.esc(str(exc))}</span>")
            return None
        except Exception as exc:  # keep the studio alive; say why
            self.last_error = f"{type(exc).__name__}: {exc}"
            self.md_status.content = (f"<span style='color:#d00'>Could not start: "
                                      f"{self.esc(self.last_error)}</span>")
            return None
        self.last_error = None
        self.active, self.active_study = job_id, study
        self.progress.value = 0.0
        self.bt_cancel.disabled = False
        self.md_status.content = f"Queued {study} study `{job_id}`."
        return job_id

    def cancel(self) -> None:
        if self.active is not None:
            self.jobs.cancel(self.active, wait=0.0)

    def _show_selected(self) -> None:
        job = job_of(self.dd_list.value)
        if job is not None:
            self.show(job)

    # ----------------------------------------------------------------- design search
    def _build_search_gui(self, gui) -> None:
        """A search's progress (trials done, best so far), its objective / Pareto charts
        and the trials whose design loads into the design view."""
        self.search_folder = gui.add_folder("Design search", expand_by_default=True,
                                            visible=False)
        with self.search_folder:
            self.md_search = gui.add_markdown("")
            self.search_plot_folder = gui.add_folder("Search charts", expand_by_default=True)
            self.dd_trial = gui.add_dropdown("trial", (NO_TRIALS,), disabled=True,
                                             hint="the trials that finished, best first")
            self.bt_load_trial = gui.add_button(
                "Load trial's design", disabled=True,
                hint="the design the study started from with this trial's values, into the "
                     "design view (undo there goes back)")
            self.bt_load_trial.on_click(lambda e: self.load_trial(
                _trial_number(self.dd_trial.value)))
            self.bt_load_best = gui.add_button(
                "Load best.json (winner on its worst target)", disabled=True)
            self.bt_load_best.on_click(lambda e: self.load_best())
            self.md_loaded = gui.add_markdown("")

    def _search_update(self, job_id: str, force: bool = False) -> None:
        """Read the search's journal and redraw its progress line, charts and trial list
        (at most every :data:`SEARCH_POLL_S` unless ``force``; charts only when a trial
        finished)."""
        import time as _time

        from studio.web.design_search import progress_text, read_progress, search_figures, trial_label

        now = _time.monotonic()
        if not force and job_id == self.search_job and now - self._search_read < SEARCH_POLL_S:
            return
        self._search_read = now
        if job_id != self.search_job:
            self.search_job, self._search_sig = job_id, None
            self.md_loaded.content = ""
        info = self.jobs.get(job_id)
        self.search_folder.visible = True
        try:
            prog = read_progress(self.jobs.study_dir(job_id))
        except Exception as exc:  # (a journal being written: next time)
            self.md_search.content = f"Search `{job_id}`: cannot read its trials ({exc})"
            return
        self.search_progress = prog
        trials = (info.options or {}).get("trials")
        self.md_search.content = f"Search `{job_id}` ({info.status}): " + \
            progress_text(prog, trials)
        sig = None if prog is None else tuple((t.number, t.state) for t in prog.trials)
        if sig == self._search_sig and not force:
            return
        self._search_sig = sig
        figs = search_figures(prog) if prog is not None and prog.complete else []
        with self.search_plot_folder:
            for k, (title, fig) in enumerate(figs):
                if k < len(self.search_plots):
                    self.search_plots[k].figure = fig
                else:
                    self.search_plots.append(self.gui.add_plotly(fig, aspect=STUDY_CHART_ASPECT))
        for h in self.search_plots[len(figs):]:
            h.remove()
        self.search_plots = self.search_plots[:len(figs)]
        self.search_figs = figs
        done = [] if prog is None else sorted(
            prog.complete, key=lambda t: (not t.feasible, t.values[0]))
        labels = tuple(trial_label(t, prog.objectives) for t in done) or (NO_TRIALS,)
        self.dd_trial.options = labels
        self.dd_trial.value = labels[0]  # (the best so far, as a trial finishes)
        self.dd_trial.disabled = self.bt_load_trial.disabled = not done
        self.bt_load_best.disabled = "best.json" not in (info.files or [])
        self.bt_popout.disabled = not self._all_figures()
        if self.popout is not None and self.popout.visible:
            self.pop_out()

    def load_trial(self, number: Optional[int]) -> Optional[str]:
        """Put the design of trial ``number`` of the shown search into the design view
        (the study's starting design with the trial's values); returns the refusal."""
        from studio.web.design_search import trial_scene

        prog, job = self.search_progress, self.search_job
        trial = None if prog is None else next(
            (t for t in prog.trials if t.number == number), None)
        if trial is None or job is None:
            return self._loaded("no such trial")
        info = self.jobs.get(job)
        try:
            base = info.name.split("'")[1] if "'" in info.name else "design"
            scene = trial_scene(info.options or {}, trial.params, f"{base}_trial{number}")
        except Exception as exc:
            return self._loaded(f"cannot make trial {number}'s design: {exc}")
        return self._loaded(self._load(scene, f"trial {number} of search {job}"),
                            f"trial {number}")

    def load_best(self) -> Optional[str]:
        """Put the search's ``best.json`` (the winner against its worst target) into the
        design view."""
        from studio.web.design_search import best_scene

        job = self.search_job
        scene = None if job is None else best_scene(self.jobs.study_dir(job))
        if scene is None:
            return self._loaded("this search wrote no best.json (no feasible winner yet)")
        return self._loaded(self._load(scene, f"best.json of search {job}"), "best.json")

    def _load(self, scene: dict, label: str) -> Optional[str]:
        if self.load_design is None:
            return "no design view in this tab"
        return self.load_design(scene, label)

    def _loaded(self, refusal: Optional[str], what: str = "") -> Optional[str]:
        if refusal:
            self.md_loaded.content = f"<span style='color:#d00'>⚠ {self.esc(refusal)}</span>"
        else:
            self.search_loaded = what
            self.md_loaded.content = (f"Loaded {what}'s design into the design view "
                                      "(Design tab; *Undo edit* goes back).")
        return refusal

    # ----------------------------------------------------------------- pop-out
    def _all_figures(self) -> list:
        return list(self.figures) + (self.search_figs if self.search_folder.visible
                                         else [])

    def pop_out(self) -> None:
        """The charts the tab shows, large, in a window floating over the view (issue 29,
        item 7: the side panel leaves a plot area of ~165 x 60 px)."""
        import copy as _copy

        from studio.plots.study_charts import large_layout

        gui = self.gui
        figs = self._all_figures()
        for h in self.popout_plots:
            h.remove()
        self.popout_plots = []
        if not figs or not hasattr(gui, "add_panel"):
            return
        if self.popout is None:
            self.popout = gui.add_panel(visible=True)
            self.popout_tab = self.popout.add_tab("Study charts")
            self.popout.float(x=30, y=30, width=POPOUT_WINDOW[0], height=POPOUT_WINDOW[1])
        self.popout.visible = True
        self.popout.expand()
        with self.popout_tab:
            close = gui.add_button("Close charts window")
            close.on_click(lambda e: self.close_popout())
            self.popout_plots.append(close)
            for title, fig in figs:
                big = large_layout(_copy.deepcopy(fig))
                self.popout_plots.append(gui.add_plotly(big, aspect=POPOUT_ASPECT))

    def close_popout(self) -> None:
        if self.popout is not None:
            self.popout.visible = False

    # ----------------------------------------------------------------- polling
    def poll(self) -> None:
        studies = self.jobs.list(limit=50, kind="study")
        rows = ["| study | status | progress | left | message |", "|---|---|---|---|---|"]
        for j in studies:
            msg = _one_line(j.error or j.message)
            eta = study_eta(j)
            rows.append(f"| `{j.id}` {self.esc(j.name)} | {j.status} | "
                        f"{100 * (j.progress or 0):.0f} % | "
                        f"{'' if eta is None else _fmt_s(eta)} | {self.esc(msg)} |")
        md = "\n".join(rows) if studies else "No studies yet."
        if md != self._list_md:
            self._list_md = md
            self.md_list.content = md
            set_job_choices(self.dd_list, studies, job_of(self.dd_list.value))
        job = self.active
        if self.dd_study.value == SEARCH and job is None:
            import time as _time

            now = _time.monotonic()
            if now - getattr(self, "_fields_read", 0.0) > SEARCH_POLL_S:
                self._fields_read = now
                self._refresh_field_choices()  # (a brush or body added since)
        if job is None:
            return
        if self.active_study == SEARCH:
            self._search_update(job)
        info = follow_job(self.jobs, job, self.progress, self.md_status, "Study",
                          self._running_text)
        if info is not None:  # it ended
            self.active = None
            self.bt_cancel.disabled = True
            self.md_status.content = (f"Study `{job}` **{info.status}**" + (
                f": {self.esc(info.error.splitlines()[0])}" if info.error else "."))
            self.show(job)

    def _running_text(self, info) -> str:
        eta = study_eta(info)
        return (f"{100 * float(info.progress or 0):.0f} %" +
                ("" if eta is None else f", about {_fmt_s(eta)} left") +
                f" · {self.esc(info.message or '')} ({len(info.files)} files so far)")

    # ----------------------------------------------------------------- results
    def show(self, job_id: str) -> None:
        """Show a study's plots, table and files."""
        info = self.jobs.get(job_id)
        folder = self.jobs.study_dir(job_id)
        files = list(info.files)
        self.shown, self.shown_status = job_id, None
        head = f"**{self.esc(info.name)}** (`{job_id}`, {info.status}"
        if info.summary.get("wall_s") is not None:
            head += f", {info.summary['wall_s']:.1f} s"
        head += f"): {len(files)} files"
        if info.error:
            head += f"\n\n{self.esc(info.error.splitlines()[0])}"
        self.md_result.content = head
        self.dd_file.options = tuple(files) or ("(none)",)
        self.dd_file.disabled = self.bt_download.disabled = not files
        for h in self.images + self.charts:
            h.remove()
        self.images, self.charts = [], []
        if self.plot is not None:
            self.plot.remove()
            self.plot = None
        self.md_table.visible = False
        self.figures = []
        if info.study == SEARCH:
            self._search_update(job_id, force=True)
        else:
            self.search_folder.visible = False
            self.search_job = None
        if info.study == "convergence" and "convergence.json" in files:
            try:
                from studio.studies.convergence import load_convergence

                table = load_convergence(folder)
                self.md_table.content = convergence_markdown(table)
                self.md_table.visible = True
                with self.results_folder:
                    fig = convergence_figure(table)
                    self.plot = self.gui.add_plotly(fig, aspect=STUDY_CHART_ASPECT)
                    self.figures.append(("convergence", fig))
            except (OSError, ValueError, TypeError, KeyError) as exc:
                self.md_table.content = f"cannot read the convergence table: {exc}"
                self.md_table.visible = True
        with self.results_folder:
            for name, fig in study_charts(info.study, folder, files):
                if isinstance(fig, str):
                    self.charts.append(self.gui.add_markdown(self.esc(fig)))
                else:
                    self.charts.append(self.gui.add_plotly(fig, aspect=STUDY_CHART_ASPECT))
                    self.figures.append((name, fig))
        # the PNGs the charts replace are left to the file list; the others are shown
        charted = CHARTED_PNGS.get(info.study or "", ()) if (
            self.charts or info.study == SEARCH and self.search_plots) else ()
        pngs = [f for f in files if f.lower().endswith(".png")
                and not any(fnmatch(Path(f).name, p) for p in charted)][:MAX_IMAGES]
        with self.results_folder:
            for name in pngs:
                try:
                    self.images.append(self.gui.add_image(png_array(folder / name),
                                                          label=name, format="png"))
                except (OSError, ValueError) as exc:
                    self.images.append(self.gui.add_markdown(f"{name}: cannot show ({exc})"))
        self.bt_popout.disabled = not self._all_figures()
        if self.popout is not None and self.popout.visible:
            self.pop_out()
        # (a search draws in its own folder: no empty Plots folder above it)
        self.results_folder.visible = bool(self.charts or self.images or self.plot)
        self.shown_status = info.status  # (last: what a state reader sees is all drawn)

    def _on_download(self, event) -> None:
        if event.client is None or self.shown is None:
            return
        name = self.dd_file.value
        try:
            path = self.jobs.study_file(self.shown, name)
        except KeyError:
            return
        event.client.send_file_download(Path(name).name, path.read_bytes(),
                                        save_immediately=True)

    def state(self) -> dict:
        """What the tab shows (for /studio/state and the tests)."""
        return {"study": self.dd_study.value, "active": self.active, "shown": self.shown,
                "shown_status": self.shown_status, "images": len(self.images),
                "charts": len(self.charts),
                "plot": self.plot is not None, "table": bool(self.md_table.visible),
                "files": list(self.dd_file.options) if self.shown else [],
                "error": self.last_error,
                # the shown study's form as the server holds it (what Start would submit)
                "form": {name: h.value for name, h in
                         self.fields.get(self.dd_study.value, {}).items()},
                "other_options": self.tx_extra.value,
                "variables": {p: [r["low"].value, r["high"].value, r["log"].value]
                              for p, r in self.var_rows.items()},
                "field_choices": list(self.dd_var_field.options),
                "search": self._search_state(),
                "popout": {"open": bool(self.popout is not None and self.popout.visible),
                           "charts": max(len(self.popout_plots) - 1, 0)
                           if self.popout is not None and self.popout.visible else 0,
                           "titles": [t for t, _ in self._all_figures()]}}

    def _search_state(self) -> Optional[dict]:
        prog = self.search_progress
        if self.search_job is None:
            return None
        best = None if prog is None else prog.best()
        return {"job": self.search_job, "done": 0 if prog is None else len(prog.done),
                "best": None if best is None else {"trial": best.number,
                                                   "values": best.values,
                                                   "params": best.params},
                "charts": [[d.name for d in f.data] for _, f in
                           self.search_figs],
                "trials": list(self.dd_trial.options), "loaded": self.search_loaded}
