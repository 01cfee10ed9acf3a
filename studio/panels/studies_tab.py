"""The studio's Studies tab: start a study as a job and look at what it wrote.

The form offers the studies people start from the studio (:data:`STUDY_NAMES`: wedge, spin,
refinement, convergence), each generated from the study's options model (:func:`form_spec`:
the command line's fields, defaults, units and help; a scene field starts on the current
design), plus an "other options" JSON field (any option of the study, docs/studies.md). Start submits the study through
the same :class:`studio.jobs.JobManager` as the HTTP API (``submit_study``: the study runs in
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

from .common import (NO_JOBS, PLOT_ASPECT, _fmt_s, _one_line, follow_job, job_of,
                            set_job_choices)
from ..study_charts import study_charts, study_eta

#: the studies the tab offers; each form is generated from the study's options model
#: (:func:`form_spec`): its fields, defaults, units and help are the command line's
STUDY_NAMES = ("wedge", "spin", "refinement", "convergence")
#: the first choice of every scene dropdown that takes any scene: the session's design as it
#: is now (stored, then named to the study as ``design:<id>``, see
#: ``studio.studies.registry``); the form starts on it when the studio has a design
CURRENT_DESIGN = "(current design)"
#: a dropdown's "leave it out" choice: the study's own default applies
DEFAULT_CHOICE = "(default)"
MAX_IMAGES = 6  # PNG plots shown for one study
#: study -> its PNG plots an interactive chart (studio.study_charts) replaces in the tab
CHARTED_PNGS = {"wedge": ("force_depth.png",), "spin": ("omega_*.png",),
                "refinement": ("refinement.png",)}


class FormError(ValueError):
    """A form value that cannot be an option (shown beside the Start button)."""


def _label(field: dict) -> str:
    """``depth_mm`` with unit mm -> ``depth [mm]``; others their name with spaces."""
    name, unit = field["name"], field.get("unit")
    if unit:
        suffix = "_" + unit.replace("/", "_per_")
        base = name[:-len(suffix)] if name.endswith(suffix) else name
        return f"{base.replace('_', ' ')} [{unit}]"
    return name.replace("_", " ")


def form_spec(study: str) -> list[dict]:
    """The form of ``study``: its options model's fields less the execution options
    (:func:`studio.studies.options.form_fields`), each with its ``label`` and ``widget``
    (scene, number, text, bool, choice). Optional numbers are text fields: empty means the
    study's default (the scene's own resolution, the profile's depth)."""
    from ..studies.options import form_fields
    from ..studies.registry import get

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
            if v:
                out[name] = True
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
                 current_design: Optional[Callable[[], tuple[str, str]]] = None):
        self.gui = gui
        self.jobs = jobs
        self.esc = md_escape
        # () -> (scene reference, design name) of the session's design as it is now
        self.current_design = current_design
        self.charts: list = []
        self.active: Optional[str] = None     # the study started here and followed
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
                self.results_folder = gui.add_folder("Plots", expand_by_default=True)
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
            return gui.add_number(label, float(initial), hint=hint, **bounds)
        return gui.add_text(label, initial, hint=hint)

    def _show_form(self) -> None:
        study = self.dd_study.value
        for s, handles in self.fields.items():
            for h in handles.values():
                h.visible = s == study

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
        return form_options(study, values, self.tx_extra.value), design

    def start(self) -> Optional[str]:
        """Submit the form's study; returns the job id (None if refused)."""
        from ..jobs import StudyOptionError

        study = self.dd_study.value
        try:
            options, design = self.options()
            name = f"{study} study of design {design!r}" if design else None
            job_id = self.jobs.submit_study(study, options, name=name)
        except (FormError, StudyOptionError) as exc:
            self.last_error = str(exc)
            self.md_status.content = f"**Refused:** {self.esc(str(exc))}"
            return None
        except Exception as exc:  # keep the studio alive; say why
            self.last_error = f"{type(exc).__name__}: {exc}"
            self.md_status.content = f"Could not start: {self.esc(self.last_error)}"
            return None
        self.last_error = None
        self.active = job_id
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
        if job is None:
            return
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
        if info.study == "convergence" and "convergence.json" in files:
            try:
                from ..studies.convergence import load_convergence

                table = load_convergence(folder)
                self.md_table.content = convergence_markdown(table)
                self.md_table.visible = True
                with self.results_folder:
                    self.plot = self.gui.add_plotly(convergence_figure(table),
                                                    aspect=PLOT_ASPECT)
            except (OSError, ValueError, TypeError, KeyError) as exc:
                self.md_table.content = f"cannot read the convergence table: {exc}"
                self.md_table.visible = True
        with self.results_folder:
            for name, fig in study_charts(info.study, folder, files):
                self.charts.append(self.gui.add_plotly(fig, aspect=PLOT_ASPECT) if not isinstance(
                    fig, str) else self.gui.add_markdown(self.esc(fig)))
        # the PNGs the charts replace are left to the file list; the others are shown
        charted = CHARTED_PNGS.get(info.study or "", ()) if self.charts else ()
        pngs = [f for f in files if f.lower().endswith(".png")
                and not any(fnmatch(Path(f).name, p) for p in charted)][:MAX_IMAGES]
        with self.results_folder:
            for name in pngs:
                try:
                    self.images.append(self.gui.add_image(png_array(folder / name),
                                                          label=name, format="png"))
                except (OSError, ValueError) as exc:
                    self.images.append(self.gui.add_markdown(f"{name}: cannot show ({exc})"))
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
                "error": self.last_error}
