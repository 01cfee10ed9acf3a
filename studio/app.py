"""Brush Studio in the browser: the viser app (``brush-studio studio``).

    brush-studio studio [--host 127.0.0.1] [--port 8080] [--preset NAME_OR_PATH]
                        [--data DIR] [--workers N] [--api-port PORT]

One design session per server, shared by every browser tab that connects (like a document
open in one editor): the panels on the left edit the scene (millimetres and degrees, SI
inside), the 3D view follows every change at once, Start queues the design as a job in the
background worker pool (``studio.jobs.JobManager``: the worker process runs the engine and
writes HDF5; this process only reads result files with ``engine.open_result``), the latest
frames of a running job stream into the view, and a finished run can be scrubbed, played and
plotted. The Studies tab (``studio.ui_studies``) starts a study (wedge, spin, refinement,
convergence...) as a job of the same pool and shows its plots, table and files. Beside
viser, the same JobManager is served as the HTTP API (``studio.server``) on ``--api-port``
(default port + 1), plus two studio routes:

* ``GET /studio?preset=NAME`` opens the studio on a preset: it loads the preset into the
  session and redirects the browser to the viser page (viser 1.1 does not tell the server
  the page URL a client was opened with, so the preset is set before the page loads);
* ``GET /studio/state``: what the studio shows (mode, instanced segments, bodies' poses,
  timeline frame, field errors) as JSON, for scripts and the browser tests.

See docs/studio.md.
"""
from __future__ import annotations

import copy
import json
import math
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any, Optional

import numpy as np

from . import ui_scene as us
from . import ui_view as uv
from .console import print_scene_error
from .exit_codes import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK
from .presets import demo_scene, load_preset_or_file, preset_names  # noqa: F401  (demo_scene: the studio's public name)

STREAM_HZ = 20.0          # at most this many live frames per second into the view
POLL_S = 0.1              # job polling period
STUDIES_POLL_S = 0.5      # the Studies tab's polling period
PLOT_CURSOR_S = 0.25      # plot cursor updates at most this often while playing
MAX_VIEW_SEGMENTS = 2_000_000  # above this the view draws every bristle as one segment
SPEEDS = ("0.1x", "0.25x", "0.5x", "1x", "2x", "4x")
COLOR_MODES = ("bending moment", "deflection", "none")
DEFAULT_DATA_DIR = "brush-studio-data"


def _fmt_s(s) -> str:
    if s is None or not isinstance(s, (int, float)) or not math.isfinite(s):
        return "?"
    if s < 1:
        return f"{s * 1e3:.0f} ms"
    if s < 120:
        return f"{s:.1f} s"
    return f"{int(s // 60)} min {s % 60:02.0f} s"


def _fmt_rate(x) -> str:
    if x is None or not isinstance(x, (int, float)) or not math.isfinite(x):
        return "?"
    for div, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(x) >= div:
            return f"{x / div:.3g}{suffix}"
    return f"{x:.3g}"


class ResultFrames:
    """One result file opened for display: statics cached, frames read one at a time."""

    def __init__(self, path: Path):
        import engine

        self.path = Path(path)
        self.res = engine.open_result(self.path)
        self._statics()

    def _statics(self) -> None:
        r = self.res
        statics = set(r.statics())
        self.has_nodes = "nodes/radius" in statics and "nodes/positions" in r.channels()
        self.radius = r.static("nodes/radius") if self.has_nodes else np.zeros(0)
        self.bonds = (np.asarray(r.static("bonds/nodes"), np.int64) if "bonds/nodes" in statics
                      else np.zeros((0, 2), np.int64))
        try:
            self.body_names = list(r.json_attr("body_names") or [])
        except Exception:
            self.body_names = []
        self.brush_names = list(r.json_attr("brush_names") or []) if "brush_names" in \
            r.attrs else []
        self.bodies = {}
        for name in self.body_names:
            v, t = f"bodies/{name}/vertices", f"bodies/{name}/triangles"
            if v in statics and t in statics:
                self.bodies[name] = (np.asarray(r.static(v)), np.asarray(r.static(t)))
        channels = set(r.channels())
        self.has_bending = "bonds/bending_moment" in channels
        self.has_body_pose = {n: f"bodies/{n}/position" in channels for n in self.body_names}
        self.rest = None
        self.bending_max = None

    def refresh(self) -> None:
        """See the frames written since: close, then open again (``ResultFile.refresh``
        opens the new handle while the old one is still open, and HDF5 then hands back the
        same, stale, file)."""
        import engine

        self.res.close()
        self.res = engine.open_result(self.path)

    @property
    def n_frames(self) -> int:
        return int(self.res.n_frames)

    @property
    def time(self) -> np.ndarray:
        return self.res.time

    def nodes(self, i: int) -> Optional[np.ndarray]:
        if not self.has_nodes or self.n_frames == 0:
            return None
        return np.asarray(self.res.frame("nodes/positions", i))

    def rest_nodes(self) -> Optional[np.ndarray]:
        if self.rest is None:
            self.rest = self.nodes(0)
        return self.rest

    def body_pose(self, name: str, i: int):
        if not self.has_body_pose.get(name) or self.n_frames == 0:
            return None
        return (np.asarray(self.res.frame(f"bodies/{name}/position", i)),
                np.asarray(self.res.frame(f"bodies/{name}/orientation", i)))

    def colors(self, mode: str, i: int, x: np.ndarray) -> Optional[np.ndarray]:
        """Per-segment colours of frame ``i`` (node positions ``x``)."""
        if mode == "bending moment" and self.has_bending:
            m = np.asarray(self.res.frame("bonds/bending_moment", i), float)
            if self.bending_max is None or self.bending_max <= 0:
                n = self.n_frames
                step = max(1, n // 50)
                sample = np.asarray(self.res.series("bonds/bending_moment",
                                                    slice(0, n, step)), float)
                self.bending_max = float(np.nanmax(sample)) if sample.size else 0.0
                self.bending_max = max(self.bending_max, float(np.nanmax(m)) if m.size else 0)
            return uv.colormap(m, self.bending_max)
        if mode == "deflection":
            rest = self.rest_nodes()
            if rest is None:
                return None
            mid = 0.5 * (x[self.bonds[:, 0]] + x[self.bonds[:, 1]])
            mid0 = 0.5 * (rest[self.bonds[:, 0]] + rest[self.bonds[:, 1]])
            dev = np.linalg.norm(mid - mid0, axis=1)
            vmax = float(self.radius.max()) * 4 if self.radius.size else 1e-3
            return uv.colormap(dev, max(vmax, float(dev.max()) if dev.size else 0.0))
        return None

    def close(self) -> None:
        try:
            self.res.close()
        except Exception:
            pass


# =========================================================================== the studio
class Studio:
    """The viser studio. ``server``: a ``viser.ViserServer``; ``jobs``: a
    ``studio.jobs.JobManager`` (or None: designing only)."""

    def __init__(self, server, jobs, scene, data_dir: Optional[Path] = None):
        self.server = server
        self.jobs = jobs
        self.data_dir = Path(data_dir) if data_dir is not None else None
        self.lock = threading.RLock()
        self.scene: dict = us.scene_dict(scene)
        self.sel = us.Selection()
        self.errors: dict[str, list[str]] = {}
        self.mode = "design"          # design | live | playback
        self.active_job: Optional[str] = None    # the job streamed live
        self.my_jobs: list[str] = []
        self.playback: Optional[ResultFrames] = None
        self.playback_job: Optional[str] = None
        self.live: Optional[ResultFrames] = None
        self.frame_index = 0
        self.play_clock = None
        self.last_stream = 0.0
        self.last_cursor = 0.0
        self.n_segments_drawn = 0
        self._runs_md = ""
        self._stop = threading.Event()
        self.view = uv.View(server)
        server.scene.set_up_direction("+z")
        server.scene.add_grid("/grid", width=200.0, height=200.0, cell_size=10.0,
                              section_size=50.0, plane="xy", position=(0.0, 0.0, 0.0))
        self._build_gui()
        self.gizmo = None
        self.redraw_design()
        self.refresh_fields()
        server.on_client_connect(self._on_connect)
        self.poller = threading.Thread(target=self._poll_loop, name="studio-poll", daemon=True)
        self.poller.start()

    # ----------------------------------------------------------------- GUI
    def _build_gui(self) -> None:
        gui = self.server.gui
        try:
            gui.configure_theme(control_width="large", show_share_button=False)
        except TypeError:
            gui.configure_theme(control_width="large")
        self.md_title = gui.add_markdown("**Brush Studio**")
        self.md_summary = gui.add_markdown("")
        tabs = gui.add_tab_group()
        self.tab_design = tabs.add_tab("Design")
        self.tab_run = tabs.add_tab("Run")
        self.tab_results = tabs.add_tab("Results")
        self.tab_studies = tabs.add_tab("Studies")
        self.widgets: dict[str, Any] = {}
        self.error_md: dict[str, Any] = {}
        with self.tab_design:
            with gui.add_folder("Presets", expand_by_default=True):
                self.dd_preset = gui.add_dropdown("preset", preset_names(),
                                                  initial_value="demo")
                self.bt_preset = gui.add_button("Load preset")
                self.bt_preset.on_click(self._on_load_preset)
                self.up_json = gui.add_upload_button("Upload JSON preset",
                                                     mime_type="application/json")
                self.up_json.on_upload(self._on_upload_json)
                self.bt_download_json = gui.add_button("Download design as JSON")
                self.bt_download_json.on_click(self._on_download_json)
                self.md_preset = gui.add_markdown("", visible=False)
            self.tx_name = gui.add_text("design name", self.scene.get("name", "scene"))
            self.tx_name.on_update(self._on_name)
            folders = {}
            titles = {"brush": "Brush layout", "material": "Material", "body": "Body",
                      "motion": "Body motion", "environment": "Environment",
                      "run": "Run settings"}
            for folder in us.FOLDERS:
                folders[folder] = gui.add_folder(titles[folder],
                                                 expand_by_default=folder == "brush")
            with folders["material"]:
                self.dd_material = gui.add_dropdown(
                    "material preset", ("(keep)",) + tuple(us.MATERIAL_PRESETS),
                    initial_value="(keep)")
                self.dd_material.on_update(self._on_material_preset)
            with folders["body"]:
                self.dd_body = gui.add_dropdown("edit body", self._body_names() or ("(none)",))
                self.dd_body.on_update(self._on_select_body)
                self.bt_add_body = gui.add_button("Add body")
                self.bt_add_body.on_click(self._on_add_body)
                self.bt_remove_body = gui.add_button("Remove body", color="red")
                self.bt_remove_body.on_click(self._on_remove_body)
                self.up_mesh = gui.add_upload_button("Upload mesh (STL/OBJ/PLY)")
                self.up_mesh.on_upload(self._on_upload_mesh)
                self.md_body = gui.add_markdown("", visible=False)
            for f in us.FIELDS:
                with folders[f.folder]:
                    self.widgets[f.key] = self._add_widget(f)
                    self.error_md[f.key] = gui.add_markdown("", visible=False)
        with self.tab_run:
            self.bt_start = gui.add_button("Start run", color="green")
            self.bt_start.on_click(self._on_start)
            self.bt_cancel = gui.add_button("Cancel run", color="red", disabled=True)
            self.bt_cancel.on_click(self._on_cancel)
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.md_status = gui.add_markdown("No run started yet.")
            self.cb_follow = gui.add_checkbox("show the running job live", True)
            with gui.add_folder("Runs"):
                self.md_runs = gui.add_markdown("No runs yet.")
                self.dd_runs = gui.add_dropdown("run", ("(none)",))
                self.bt_load_run = gui.add_button("Load run for playback")
                self.bt_load_run.on_click(self._on_load_run)
                self.bt_cancel_selected = gui.add_button("Cancel selected run")
                self.bt_cancel_selected.on_click(self._on_cancel_selected)
        with self.tab_results:
            self.md_result = gui.add_markdown("No run loaded. Finished runs load here.")
            self.sl_time = gui.add_slider("frame", min=0, max=1, step=1, initial_value=0,
                                          disabled=True)
            self.sl_time.on_update(self._on_slider)
            self.cb_play = gui.add_checkbox("play", False, disabled=True)
            self.dd_speed = gui.add_dropdown("speed (simulated s per s)", SPEEDS,
                                             initial_value="0.25x")
            self.dd_color = gui.add_dropdown("colour bristles by", COLOR_MODES,
                                             initial_value="bending moment")
            self.dd_color.on_update(lambda e: self._show_frame(self.frame_index))
            self.bt_download_h5 = gui.add_button("Download result HDF5", disabled=True)
            self.bt_download_h5.on_click(self._on_download_h5)
            self.bt_design = gui.add_button("Back to the design view")
            self.bt_design.on_click(lambda e: self.set_mode("design"))
            self.plots: dict[str, Any] = {}
            self.figures: dict[str, Any] = {}
        self.studies = None
        if self.jobs is not None:
            from .ui_studies import StudiesTab

            self.studies = StudiesTab(gui, self.tab_studies, self.jobs, preset_names(),
                                      _md_escape)
        else:
            with self.tab_studies:
                gui.add_markdown("No job pool: studies need the studio's workers.")

    def _add_widget(self, f: us.UiField):
        gui = self.server.gui
        label = f"{f.label} [{f.unit}]" if f.unit else f.label
        hint = f.hint or None
        try:
            value = us.get_ui_value(f, self.scene, self.sel)
        except us.NotApplicable:
            value = None
        if f.kind in ("vector3", "rpy"):
            h = gui.add_vector3(label, tuple(value) if value is not None else (0.0, 0.0, 0.0),
                                step=f.step or 0.1, hint=hint)
        elif f.kind == "dropdown":
            h = gui.add_dropdown(label, f.options, initial_value=value if value in f.options
                                 else f.options[0], hint=hint)
        elif f.kind == "checkbox":
            h = gui.add_checkbox(label, bool(value), hint=hint)
        elif f.kind == "int":
            h = gui.add_number(label, int(value) if value is not None else 0, step=1,
                               hint=hint)
        else:
            h = gui.add_number(label, float(value) if value is not None else 0.0,
                               step=f.step or 0.001, hint=hint)
        h.on_update(lambda event, key=f.key: self._on_field(event, key))
        return h

    def _on_connect(self, client) -> None:
        """Point a new client's camera at the design."""
        try:
            b = uv.design_bristles(self.scene) if uv.n_design_segments(self.scene) < 200_000 \
                else None
            if b is not None and len(b.positions):
                lo, hi = b.positions.min(0), b.positions.max(0)
                c = 0.5 * (lo + hi) * uv.VIEW_SCALE
                size = max(float(np.max(hi - lo)) * uv.VIEW_SCALE, 20.0)
            else:
                c, size = np.zeros(3), 50.0
            client.camera.up_direction = (0.0, 0.0, 1.0)
            # viser moves the look-at point along with the position: set it last
            client.camera.position = tuple(float(x) for x in
                                           c + np.array([1.2, -1.6, 0.9]) * size * 1.2)
            client.camera.look_at = tuple(float(x) for x in c)
        except Exception:
            pass

    # ----------------------------------------------------------------- design editing
    def _body_names(self) -> tuple[str, ...]:
        return tuple(b["name"] for b in self.scene.get("bodies") or [])

    def _on_field(self, event, key: str) -> None:
        if event.client is None:  # set by the server (refresh): not an edit
            return
        self.edit(key, event.target.value, from_client=True)

    def edit(self, key: str, value, from_client: bool = False) -> bool:
        """Apply a UI value to the design. Returns True when accepted; a refused value leaves
        the design as it was and shows the message next to the field."""
        with self.lock:
            f = us.FIELDS_BY_KEY[key]
            try:
                new = us.set_ui_value(f, self.scene, self.sel, value)
            except us.NotApplicable:
                return False
            except ValueError as exc:
                self._show_errors({key: [str(exc)]})
                return False
            v = us.validate(new)
            if not v.ok:
                named = us.fields_for_problems(v.problems, new, self.sel)
                msgs = {k: [p.message for p in ps] for k, ps in named.items()}
                mine = [p.message for p in v.problems]
                msgs[key] = mine
                msgs[key] = [f"{f.label} = {_fmt_value(value)} {f.unit}".rstrip() +
                             " refused"] + mine
                self._show_errors(msgs)
                return False
            self.scene = us.scene_dict(v.scene)
            self._clear_errors()
            self.set_mode("design", redraw=False)
            self.redraw_design()
            # (the field a user is typing in keeps what they typed)
            self.refresh_fields(skip=key if from_client else None)
            return True

    def set_design(self, scene) -> None:
        """Replace the whole design (a preset, an upload) by a validated engine.Scene."""
        with self.lock:
            self.scene = us.scene_dict(scene)
            self.sel = us.Selection()
            self._clear_errors()
            self.set_mode("design", redraw=False)
            self.redraw_design()
            self.refresh_fields()
        for client in self.server.get_clients().values():  # a new design: aim at it
            self._on_connect(client)

    def _show_errors(self, msgs: dict[str, list[str]]) -> None:
        for key in list(self.errors):
            if key not in msgs:
                self.error_md[key].visible = False
        self.errors = msgs
        for key, lines in msgs.items():
            md = self.error_md.get(key)
            if md is None:
                continue
            md.content = "\n\n".join(f"<span style='color:#d00'>⚠ {_md_escape(m)}</span>"
                                     for m in lines)
            md.visible = True
            self.widgets[key].visible = True

    def _clear_errors(self) -> None:
        for key in self.errors:
            self.error_md[key].visible = False
        self.errors = {}

    def refresh_fields(self, skip: Optional[str] = None) -> None:
        """Show each applicable field with the design's value; hide the others."""
        with self.lock, self.server.atomic():
            self.tx_name.value = self.scene.get("name", "scene")
            names = self._body_names()
            self.dd_body.options = names or ("(none)",)
            if names:
                self.sel.body = min(self.sel.body, len(names) - 1)
                self.dd_body.value = names[self.sel.body]
            self.bt_remove_body.disabled = not names
            for f in us.FIELDS:
                h = self.widgets[f.key]
                ok = us.applicable(f, self.scene, self.sel)
                h.visible = ok
                if not ok:
                    self.error_md[f.key].visible = False
                    continue
                if f.key == skip or f.key in self.errors:
                    continue
                try:
                    value = us.get_ui_value(f, self.scene, self.sel)
                except us.NotApplicable:
                    h.visible = False
                    continue
                if f.kind == "int":
                    value = int(value)
                elif f.kind in ("vector3", "rpy"):
                    value = tuple(float(c) for c in value)
                h.value = value
            self._update_summary()

    def _update_summary(self) -> None:
        nb = sum(int(b["rows"]) * int(b["columns"]) for b in self.scene.get("brushes") or [])
        ns = uv.n_design_segments(self.scene)
        self.md_summary.content = (
            f"*{self.scene.get('name', 'scene')}*: {nb:,} bristles, {ns:,} segments, "
            f"{len(self.scene.get('bodies') or [])} bod"
            f"{'y' if len(self.scene.get('bodies') or []) == 1 else 'ies'}; "
            f"{self.scene['run']['duration']:g} s to simulate. View: **{self.mode}**")

    def redraw_design(self) -> None:
        """Draw the design: bristles at rest, bodies at their pose, the gizmo on the
        selected body."""
        with self.lock:
            if self.mode != "design":
                return
            t0 = time.perf_counter()
            if uv.n_design_segments(self.scene) > MAX_VIEW_SEGMENTS:
                coarse = copy.deepcopy(self.scene)
                for b in coarse["brushes"]:
                    b["n_nodes"] = 2
                bristles = uv.design_bristles(coarse)
            else:
                bristles = uv.design_bristles(self.scene)
            self.view.set_bristle_nodes(bristles)
            self.n_segments_drawn = bristles.n_segments
            self.view.set_bodies(uv.design_bodies(self.scene))
            self._place_gizmo()
            self.last_draw_s = time.perf_counter() - t0

    def _place_gizmo(self) -> None:
        bodies = self.scene.get("bodies") or []
        if self.mode != "design" or not bodies:
            if self.gizmo is not None:
                self.gizmo.visible = False
            return
        body = bodies[min(self.sel.body, len(bodies) - 1)]
        pos = np.asarray(body.get("pose", {}).get("position", (0, 0, 0)), float)
        q = body.get("pose", {}).get("orientation", (1, 0, 0, 0))
        if self.gizmo is None:
            self.gizmo = self.server.scene.add_transform_controls(
                "/studio/gizmo", scale=15.0, depth_test=False)
            self.gizmo.on_update(self._on_gizmo)
        self.gizmo.position = tuple(float(c) for c in pos * uv.VIEW_SCALE)
        self.gizmo.wxyz = tuple(float(c) for c in q)
        self.gizmo.visible = True

    def _on_gizmo(self, event) -> None:
        handle = event.target if hasattr(event, "target") else event
        with self.lock:
            bodies = self.scene.get("bodies") or []
            if self.mode != "design" or not bodies:
                return
            pos = [float(c) / uv.VIEW_SCALE for c in handle.position]
            q = np.asarray(handle.wxyz, float)
            q = q / np.linalg.norm(q)
            if q[0] < 0:
                q = -q
            new = copy.deepcopy(self.scene)
            body = new["bodies"][self.sel.body]
            body.setdefault("pose", {})
            body["pose"]["position"] = pos
            body["pose"]["orientation"] = [float(c) for c in q]
            v = us.validate(new)
            if not v.ok:
                self._show_errors({"body_position": [p.message for p in v.problems]})
                return
            self.scene = us.scene_dict(v.scene)
            b = uv.design_bodies({"bodies": [self.scene["bodies"][self.sel.body]]})
            if b:
                self.view.set_body_pose(b[0].name, b[0].position, b[0].wxyz)
            self.refresh_fields()

    def _on_name(self, event) -> None:
        if event.client is None:
            return
        with self.lock:
            new = copy.deepcopy(self.scene)
            new["name"] = str(event.target.value)
            v = us.validate(new)
            if v.ok:
                self.scene = us.scene_dict(v.scene)
                self._update_summary()

    def _on_material_preset(self, event) -> None:
        if event.client is None or event.target.value == "(keep)":
            return
        with self.lock:
            try:
                new = us.set_material_preset(self.scene, self.sel, event.target.value)
            except (ValueError, IndexError, KeyError) as exc:
                self._show_errors({"youngs_modulus": [str(exc)]})
                return
            v = us.validate(new)
            if v.ok:
                self.scene = us.scene_dict(v.scene)
                self._clear_errors()
                self.set_mode("design", redraw=False)
                self.redraw_design()
                self.refresh_fields()
            else:
                self._show_errors({"youngs_modulus": [p.message for p in v.problems]})
            self.dd_material.value = "(keep)"

    def _on_select_body(self, event) -> None:
        if event.client is None:
            return
        with self.lock:
            names = self._body_names()
            if event.target.value in names:
                self.sel.body = names.index(event.target.value)
                self._clear_errors()
                self._place_gizmo()
                self.refresh_fields()

    def _on_add_body(self, event) -> None:
        with self.lock:
            new = us.add_body(self.scene)
            v = us.validate(new)
            if v.ok:
                self.scene = us.scene_dict(v.scene)
                self.sel.body = len(self.scene["bodies"]) - 1
                self.set_mode("design", redraw=False)
                self.redraw_design()
                self.refresh_fields()

    def _on_remove_body(self, event) -> None:
        with self.lock:
            bodies = self.scene.get("bodies") or []
            if not bodies:
                return
            new = copy.deepcopy(self.scene)
            name = new["bodies"].pop(self.sel.body)["name"]
            for br in new.get("brushes") or []:
                if br.get("mount") == name:
                    br["mount"] = None
            stop = new["run"].get("stop")
            if stop and stop.get("body") == name:
                new["run"]["stop"] = None
            v = us.validate(new)
            if not v.ok:
                self._set_note(self.md_body, "; ".join(p.message for p in v.problems))
                return
            self.scene = us.scene_dict(v.scene)
            self.sel.body = 0
            self.set_mode("design", redraw=False)
            self.redraw_design()
            self.refresh_fields()

    def _on_upload_mesh(self, event) -> None:
        up = event.target.value
        with self.lock:
            if not (self.scene.get("bodies") or []):
                self.scene = us.scene_dict(us.validate(us.add_body(self.scene)).scene)
            try:
                if self.jobs is not None:
                    info = self.jobs.add_mesh(up.content, up.name)
                    path = self.jobs.mesh_path(info["id"])
                else:
                    folder = (self.data_dir or Path(".")) / "meshes"
                    folder.mkdir(parents=True, exist_ok=True)
                    path = folder / Path(up.name).name
                    path.write_bytes(up.content)
                mesh = uv.shape_mesh({"type": "mesh", "file": str(path)})
            except Exception as exc:
                self._set_note(self.md_body, f"mesh {up.name!r} refused: {exc}")
                return
            new = copy.deepcopy(self.scene)
            body = new["bodies"][self.sel.body]
            extent = float(np.max(mesh.extents)) if len(mesh.vertices) else 1.0
            # a file in millimetres is the usual case for CAD exports: scale it so the body
            # is at most 0.5 m across
            scale = 1.0 if extent <= 0.5 else 1e-3
            body["shape"] = {"type": "mesh", "file": str(path), "scale": scale}
            mp = body.get("mass_properties")
            if mp and not mesh.is_watertight:
                body["mass_properties"] = None
            v = us.validate(new)
            if not v.ok:
                self._set_note(self.md_body, "; ".join(p.message for p in v.problems))
                return
            self.scene = us.scene_dict(v.scene)
            self._set_note(self.md_body, f"mesh {up.name!r}: {len(mesh.faces):,} triangles, "
                           f"{'closed' if mesh.is_watertight else 'open (no density)'}, "
                           f"scale {scale:g}")
            self.set_mode("design", redraw=False)
            self.redraw_design()
            self.refresh_fields()

    @staticmethod
    def _set_note(md, text: str) -> None:
        md.content = _md_escape(text)
        md.visible = bool(text)

    # ----------------------------------------------------------------- presets
    def _on_load_preset(self, event) -> None:
        self.load_preset(self.dd_preset.value)

    def load_preset(self, name: str) -> None:
        import engine

        try:
            scene = load_preset_or_file(name)
        except engine.SceneError as exc:
            self._set_note(self.md_preset, "; ".join(str(p) for p in exc.problems))
            return
        self.set_design(scene)
        if name in self.dd_preset.options:
            self.dd_preset.value = name
        self._set_note(self.md_preset, f"loaded preset {name!r}")

    def _on_upload_json(self, event) -> None:
        import engine

        up = event.target.value
        try:
            scene = engine.parse_scene(up.content)
        except engine.SceneError as exc:
            self._set_note(self.md_preset, f"{up.name} refused: " +
                           "; ".join(str(p) for p in exc.problems))
            return
        self.set_design(scene)
        self._set_note(self.md_preset, f"loaded {up.name}")

    def design_json(self) -> str:
        import engine

        return engine.parse_scene(self.scene).to_json(indent=2) + "\n"

    def _on_download_json(self, event) -> None:
        if event.client is None:
            return
        name = _safe_name(self.scene.get("name", "scene")) + ".json"
        event.client.send_file_download(name, self.design_json().encode(),
                                        save_immediately=True)

    # ----------------------------------------------------------------- runs
    def start_run(self) -> Optional[str]:
        """Submit the design as a job; returns the job id (None if refused or no pool)."""
        import engine

        if self.jobs is None:
            self.md_status.content = "No job pool: this studio was started without workers."
            return None
        with self.lock:
            scene = copy.deepcopy(self.scene)
        try:
            job_id = self.jobs.submit(scene, name=scene.get("name"))
        except engine.SceneError as exc:
            self.md_status.content = "Refused: " + "; ".join(
                _md_escape(str(p)) for p in exc.problems)
            return None
        except Exception as exc:
            self.md_status.content = f"Could not start: {_md_escape(str(exc))}"
            return None
        with self.lock:
            self.my_jobs.append(job_id)
            self.active_job = job_id
            if self.cb_follow.value:
                self.set_mode("live")
        self.md_status.content = f"Queued job `{job_id}`."
        self.bt_cancel.disabled = False
        return job_id

    def _on_start(self, event) -> None:
        self.start_run()

    def _on_cancel(self, event) -> None:
        if self.jobs is not None and self.active_job is not None:
            self.jobs.cancel(self.active_job, wait=0.0)

    def _on_cancel_selected(self, event) -> None:
        job = self._selected_job()
        if self.jobs is not None and job is not None:
            self.jobs.cancel(job, wait=0.0)

    def _selected_job(self) -> Optional[str]:
        v = self.dd_runs.value
        return v.split(" ", 1)[0] if v and v != "(none)" else None

    def _on_load_run(self, event) -> None:
        job = self._selected_job()
        if job is not None:
            self.load_run(job)

    # ----------------------------------------------------------------- modes and frames
    def set_mode(self, mode: str, redraw: bool = True) -> None:
        with self.lock:
            if mode == self.mode:
                return
            self.mode = mode
            if mode != "live" and self.live is not None:
                self.live.close()
                self.live = None
            if mode != "playback":
                self.cb_play.value = False
            if mode == "design" and redraw:
                self.redraw_design()
            self._place_gizmo()
            self._update_summary()

    def load_run(self, job_id: str) -> bool:
        """Open a job's result file for playback (any state but queued)."""
        import engine

        with self.lock:
            # close every handle on result files first: HDF5 shares one open file between
            # the handles of a process, so a new handle would see the live reader's old view
            for old in (self.live, self.playback):
                if old is not None:
                    old.close()
            self.live = self.playback = self.playback_job = None
            try:
                path = self.jobs.result_path(job_id)
                frames = ResultFrames(path)
            except (KeyError, engine.BrushStudioError, OSError) as exc:
                self.md_result.content = f"Cannot open run `{job_id}`: {_md_escape(str(exc))}"
                return False
            self.playback, self.playback_job = frames, job_id
            self.set_mode("playback")
            n = frames.n_frames
            self.sl_time.max = max(n - 1, 1)
            self.sl_time.disabled = n < 2
            self.cb_play.disabled = n < 2
            self.bt_download_h5.disabled = False
            info = self.jobs.get(job_id)
            t_end = float(frames.time[-1]) if n else 0.0
            self.md_result.content = (
                f"Run `{job_id}` ({_md_escape(info.name)}): **{frames.res.status}**, {n} frames,"
                f" t = 0 … {t_end:.4g} s" +
                (f". {_md_escape(info.error)}" if info.error else ""))
            self._make_plots()
            self.frame_index = -1
            self.sl_time.value = 0
            self._show_frame(0)
        return True

    def _on_slider(self, event) -> None:
        if self.mode == "playback":
            self._show_frame(int(event.target.value))

    def _show_frame(self, i: int, source: Optional[ResultFrames] = None) -> None:
        """Draw frame ``i`` of the playback (or live) result."""
        with self.lock:
            res = source or self.playback
            if res is None or res.n_frames == 0:
                return
            i = int(min(max(i, 0), res.n_frames - 1))
            x = res.nodes(i)
            if x is not None and len(res.bonds):
                colors = res.colors(self.dd_color.value, i, x)
                centres, wxyz, scales = uv.segment_instances(x, res.radius, res.bonds)
                self.view.set_bristles(centres, wxyz, scales, colors)
                self.n_segments_drawn = len(centres)
            meshes = []
            for name, (verts, tris) in res.bodies.items():
                pose = res.body_pose(name, i)
                if pose is not None:
                    meshes.append(uv.BodyMesh(name, verts, tris, pose[0], pose[1]))
            self.view.set_bodies(meshes)
            if source is None:
                self.frame_index = i
                now = time.monotonic()
                if not self.cb_play.value or now - self.last_cursor > PLOT_CURSOR_S:
                    self.last_cursor = now
                    self._move_cursor(float(res.time[i]))

    # ----------------------------------------------------------------- plots
    def _make_plots(self) -> None:
        import plotly.graph_objects as go

        res = self.playback
        t = res.time
        channels = set(res.res.channels())
        figs = {}
        f = go.Figure()
        for brush in res.brush_names:
            c = f"brushes/{brush}/root_force"
            if c in channels:
                F = np.asarray(res.res.series(c))
                f.add_scatter(x=t, y=F[:, 2], name=f"{brush} F_z", mode="lines")
                f.add_scatter(x=t, y=np.linalg.norm(F, axis=1), name=f"{brush} |F|",
                              mode="lines")
        figs["root force [N]"] = f
        f = go.Figure()
        for name in res.body_names:
            c = f"bodies/{name}/angular_velocity"
            if c in channels:
                w = np.asarray(res.res.series(c))
                f.add_scatter(x=t, y=np.linalg.norm(w, axis=1), name=f"{name} |ω|",
                              mode="lines")
        figs["body angular velocity [rad/s]"] = f
        f = go.Figure()
        for e in ("kinetic", "bond", "contact", "gravity", "total"):
            c = f"energy/{e}"
            if c in channels:
                f.add_scatter(x=t, y=np.asarray(res.res.series(c)), name=e, mode="lines")
        figs["energy [J]"] = f
        gui = self.server.gui
        for title, fig in figs.items():
            fig.update_layout(title=dict(text=title, font=dict(size=13)),
                              margin=dict(l=40, r=10, t=30, b=30), height=260,
                              xaxis_title="time [s]", legend=dict(font=dict(size=9)))
            fig.add_vline(x=float(t[0]) if len(t) else 0.0, line_color="red", line_width=1)
            self.figures[title] = fig
            if title in self.plots:
                self.plots[title].figure = fig
            else:
                with self.tab_results:
                    self.plots[title] = gui.add_plotly(fig, aspect=1.6)

    def _move_cursor(self, t: float) -> None:
        for title, fig in self.figures.items():
            fig.layout.shapes = ()
            fig.add_vline(x=t, line_color="red", line_width=1)
            self.plots[title].figure = fig

    def _on_download_h5(self, event) -> None:
        if event.client is None or self.playback_job is None:
            return
        path = self.jobs.result_path(self.playback_job)
        event.client.send_file_download(
            f"{_safe_name(self.jobs.get(self.playback_job).name)}-{self.playback_job}.h5",
            path.read_bytes(), save_immediately=True)

    # ----------------------------------------------------------------- polling
    def _poll_loop(self) -> None:
        last = last_studies = time.monotonic()
        while not self._stop.wait(1.0 / STREAM_HZ):
            now = time.monotonic()
            try:
                if now - last >= POLL_S:
                    last = now
                    self._poll_jobs()
                if self.studies is not None and now - last_studies >= STUDIES_POLL_S:
                    last_studies = now
                    self.studies.poll()
                self._stream_live()
                self._advance_play(now)
            except Exception as exc:  # never let the poller die
                print(f"studio: poll error: {type(exc).__name__}: {exc}")

    def _poll_jobs(self) -> None:
        if self.jobs is None:
            return
        jobs = self.jobs.list(limit=50, kind="run")  # (studies: the Studies tab)
        rows = ["| run | status | progress | message |", "|---|---|---|---|"]
        for j in jobs:
            msg = j.error or ""
            if j.status in ("completed", "stopped") and j.summary:
                msg = f"{j.summary.get('frames', '?')} frames, wall " \
                      f"{_fmt_s(j.summary.get('wall_s'))}"
            rows.append(f"| `{j.id}` {_md_escape(j.name)} | {j.status} | "
                        f"{100 * (j.progress or 0):.0f} % | {_md_escape(msg)[:160]} |")
        md = "\n".join(rows) if jobs else "No runs yet."
        if md != self._runs_md:
            self._runs_md = md
            self.md_runs.content = md
            options = tuple(f"{j.id} {j.name} ({j.status})" for j in jobs) or ("(none)",)
            current = self._selected_job()
            self.dd_runs.options = options
            for o in options:
                if current is not None and o.startswith(current):
                    self.dd_runs.value = o
        job = self.active_job
        if job is None:
            return
        info = self.jobs.get(job)
        self.progress.value = 100.0 * float(info.progress or 0.0)
        if info.status == "queued":
            self.md_status.content = f"Job `{job}` queued (waiting for a worker)."
        elif info.status == "running":
            self.md_status.content = (
                f"Job `{job}` running: t = {info.sim_time or 0:.4g} / {info.until or 0:g} s, "
                f"{_fmt_rate(info.steps_per_s)} steps/s, ETA {_fmt_s(info.eta_s)}")
        else:
            self.active_job = None
            self.bt_cancel.disabled = True
            self.md_status.content = (f"Job `{job}` **{info.status}**" +
                                      (f": {_md_escape(info.error)}" if info.error else "."))
            if info.status == "completed":
                self.progress.value = 100.0
            if self.mode == "live":  # (a user editing the design keeps the design view)
                self.load_run(job)
            else:
                self.md_status.content += " Load it from the Runs list."

    def _stream_live(self) -> None:
        """Draw the latest frame of the running job (at most STREAM_HZ per second)."""
        import engine

        if self.mode != "live" or self.active_job is None:
            return
        with self.lock:
            try:
                if self.live is None:
                    path = self.jobs.result_path(self.active_job)
                    if not path.exists():
                        return
                    self.live = ResultFrames(path)
                else:
                    self.live.refresh()
            except (engine.BrushStudioError, OSError, KeyError):
                self.live = None
                return
            n = self.live.n_frames
            if n > 0:
                self._show_frame(n - 1, source=self.live)
                self.frame_index = n - 1

    def _advance_play(self, now: float) -> None:
        if self.mode != "playback" or self.playback is None or not self.cb_play.value:
            self.play_clock = None
            return
        res = self.playback
        t = res.time
        if len(t) < 2:
            return
        speed = float(self.dd_speed.value.rstrip("x"))
        if self.play_clock is None:
            self.play_clock = (now, float(t[max(self.frame_index, 0)]))
        t0_wall, t0_sim = self.play_clock
        sim = t0_sim + (now - t0_wall) * speed
        if sim > t[-1]:
            self.play_clock = (now, float(t[0]))
            sim = float(t[0])
        i = int(np.clip(np.searchsorted(t, sim, side="right") - 1, 0, len(t) - 1))
        if i != self.frame_index:
            self.sl_time.value = i  # triggers _show_frame through the callback

    # ----------------------------------------------------------------- state
    def state(self) -> dict:
        """What the studio shows (for scripts and tests)."""
        with self.lock:
            bodies = {}
            for name, h in self.view.bodies.items():
                bodies[name] = {"position_mm": [float(c) for c in h.position],
                                "wxyz": [float(c) for c in h.wxyz]}
            return {
                "mode": self.mode,
                "scene_name": self.scene.get("name"),
                "n_segments": int(self.view.n_instances if self.view.n_instances > 0 else 0),
                "n_bristles": sum(int(b["rows"]) * int(b["columns"])
                                  for b in self.scene.get("brushes") or []),
                "bodies": bodies,
                "frame": int(self.frame_index),
                "n_frames": int(self.playback.n_frames) if self.playback else 0,
                "playback_job": self.playback_job,
                "active_job": self.active_job,
                "errors": {k: list(v) for k, v in self.errors.items()},
                "studies": self.studies.state() if self.studies is not None else None,
                "scene": self.scene,
            }

    def close(self) -> None:
        self._stop.set()
        self.poller.join(timeout=2.0)
        for r in (self.playback, self.live):
            if r is not None:
                r.close()


def _fmt_value(value) -> str:
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(_fmt_value(c) for c in value) + ")"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")


def _safe_name(name: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name)).strip("._")
    return keep or "scene"


# =========================================================================== CLI
def run_studio(host: str = "127.0.0.1", port: int = 8080, preset: Optional[str] = None,
               data_dir: Path = Path(DEFAULT_DATA_DIR), workers: Optional[int] = None,
               api_port: Optional[int] = None, ready_file: Optional[Path] = None,
               stop: Optional[threading.Event] = None, token: Optional[str] = None,
               scheduler: Optional[str] = None) -> int:
    """Start the studio and block until Ctrl-C (or ``stop`` is set). ``token`` guards the
    HTTP API (bearer token); the viser page itself has no authentication, so a studio bound
    to a non-loopback address is open to whoever reaches its port."""
    import engine
    import viser

    try:
        scene = load_preset_or_file(preset or "demo")
    except engine.SceneError as exc:
        print_scene_error(exc, f"cannot open preset {preset!r}")
        return EXIT_BAD_INPUT
    from .jobs import JobManager
    from .serve_cli import is_loopback

    if not is_loopback(host):
        print(f"WARNING: binding {host}: the studio page has no authentication, anyone who "
              f"can reach port {port} can design and run jobs"
              + ("" if token else "; the HTTP API has no --token either"), file=sys.stderr)
    try:
        jobs = JobManager(Path(data_dir), workers=workers, scheduler=scheduler)
    except Exception as exc:
        print(f"studio: cannot start the job pool in {data_dir}: {type(exc).__name__}: {exc}",
              file=sys.stderr)
        return EXIT_FAILED
    server = viser.ViserServer(host=host, port=port, verbose=False)
    studio = Studio(server, jobs, scene, data_dir=Path(data_dir))
    api = None
    if api_port is None:
        api_port = port + 1
    if api_port > 0:
        try:
            from .server.studio_routes import make_api_app, serve_in_thread

            app = make_api_app(jobs, studio, viser_port=port, token=token)
            api, _ = serve_in_thread(app, host, api_port)
        except Exception as exc:
            print(f"studio: HTTP API not served ({type(exc).__name__}: {exc})")
    print(f"Brush Studio: http://{host}:{port}/" +
          (f"  (HTTP API http://{host}:{api_port}/, open a preset with "
           f"http://{host}:{api_port}/studio?preset=NAME)" if api is not None else ""),
          flush=True)
    if ready_file is not None:
        ready_file.write_text(json.dumps({"port": port, "api_port": api_port}))
    stop = stop or threading.Event()
    try:
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        print("\nstopping the studio")
    finally:
        studio.close()
        if api is not None:
            api.should_exit = True
        if jobs is not None:
            jobs.close()
        server.stop()
    return EXIT_OK


def _cmd_studio(args) -> int:
    return run_studio(host=args.host, port=args.port, preset=args.preset,
                      data_dir=Path(args.data), workers=args.workers, api_port=args.api_port,
                      token=args.token or os.environ.get("BRUSH_STUDIO_TOKEN") or None,
                      scheduler=args.scheduler)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "studio", help="the 3D design studio in the browser (viser)",
        description="Start Brush Studio in the browser: design a brush and its debris, run "
                    "it in background workers, scrub and plot the results. Also serves the "
                    "HTTP API on --api-port (default: port + 1). Ctrl-C stops it.")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=8080, help="studio port (default 8080)")
    p.add_argument("--preset", metavar="NAME_OR_PATH", default=None,
                   help="preset name (static_presets/) or scene JSON file to open "
                        "(default: the embedded demo scene)")
    p.add_argument("--data", metavar="DIR", default=DEFAULT_DATA_DIR,
                   help=f"folder for jobs and results (default ./{DEFAULT_DATA_DIR})")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes (default: one per core)")
    p.add_argument("--api-port", type=int, default=None,
                   help="HTTP API port (default: port + 1; 0: do not serve it)")
    p.add_argument("--token", default=None,
                   help="bearer token the HTTP API requires (default: $BRUSH_STUDIO_TOKEN; "
                        "none: open)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="Dask scheduler that study jobs run their simulations on (default: "
                        "each study job starts one local Dask worker)")
    p.set_defaults(func=_cmd_studio)
