"""The Design panel: presets, the scene's fields (millimetres and degrees at this edge, SI
in the design), bodies and their gizmo, uploads of meshes and JSON designs. A mixin of
:class:`studio.web.app.Studio`: it reads and writes ``self.scene``, ``self.sel`` and
``self.errors`` and draws through ``self.view``."""
from __future__ import annotations

import copy
import time
from typing import Any, Optional

import numpy as np

from engine.model import layout

from studio.web import brushes as ub
from studio.web import guides as ug
from studio.web import scene as us
from studio.web import view as uv
from studio.web import design_warnings as uw
from studio.presets import preset_names
from studio.web.panels.brushes import BrushSelector
from studio.web.panels.design_files import DesignFiles
from studio.web.panels.design_history import DesignHistory
from studio.web.panels.common import MAX_VIEW_SEGMENTS, _fmt_value, _md_escape


#: fields that can carry a scale warning (studio.web.design_warnings)
WARNED_FIELDS = ("bristle_length", "pitch_x", "pitch_y")


class DesignPanel(DesignHistory, BrushSelector, DesignFiles):
    """Design tab of the studio (mixin)."""

    def _build_design_gui(self, gui) -> None:
        self.widgets: dict[str, Any] = {}
        self.error_md: dict[str, Any] = {}
        with self.tab_design:
            self._build_history_gui(gui)
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
                self.bt_download_stl = gui.add_button(
                    "Download brush geometry (STL)",
                    hint="the bristles at rest, millimetres, for CAD")
                self.bt_download_stl.on_click(self._on_download_stl)
                self.bt_share = gui.add_button("Share this design (link)")
                self.bt_share.on_click(self._on_share)
                self.md_preset = gui.add_markdown("", visible=False)
            self.tx_name = gui.add_text("design name", self.scene.get("name", "scene"))
            self.tx_name.on_update(self._on_name)
            self.design_folders = folders = {}  # (the Run panel adds to "run")
            titles = {"brush": "Brush layout", "material": "Material", "body": "Body",
                      "motion": "Body motion", "environment": "Environment",
                      "run": "Run settings"}
            for folder in us.FOLDERS:
                folders[folder] = gui.add_folder(titles[folder],
                                                 expand_by_default=folder == "brush")
            with folders["brush"]:
                self._build_brush_selector(gui)
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
                self.md_overlap = gui.add_markdown("", visible=False)
            self.warn_md: dict[str, Any] = {}
            self.warnings: dict[str, list[str]] = {}
            for f in us.FIELDS:
                with folders[f.folder]:
                    self.widgets[f.key] = self._add_widget(f)
                    self.error_md[f.key] = gui.add_markdown("", visible=False)
                    if f.key in WARNED_FIELDS:
                        self.warn_md[f.key] = gui.add_markdown("", visible=False)

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
            # a float box taking decimals, showing whole numbers: viser casts what a client
            # sends to the type of the box's value and the page rounds to the box's
            # precision (0 for step 1), so a typed 2.5 would reach the design as 2 instead
            # of being refused
            h = gui.add_number(label, float(int(value)) if value is not None else 0.0,
                               step=1, hint=hint)
            h.precision = 6
        else:
            h = gui.add_number(label, float(value) if value is not None else 0.0,
                               step=f.step or 0.001, hint=hint)
        h.on_update(lambda event, key=f.key: self._on_field(event, key))
        return h

    def _on_connect(self, client) -> None:
        """Point a client's camera at the design (a new tab, a new design, Fit view)."""
        try:
            lo, hi = self.design_extent
            position, look_at = ug.camera_for(lo, hi)
            client.camera.up_direction = (0.0, 0.0, 1.0)
            # viser's far plane is 1000 view units (1 m): a design over about 0.4 m across
            # (a detumble scene's 1.3 m stage) was clipped away whole
            size = float(np.max(np.asarray(hi, float) - np.asarray(lo, float)))
            client.camera.far = max(1000.0, 20.0 * size)
            # viser moves the look-at point along with the position: set it last
            client.camera.position = tuple(float(x) for x in position)
            client.camera.look_at = tuple(float(x) for x in look_at)
        except Exception:
            pass

    def _on_fit_view(self, event) -> None:
        for client in ([event.client] if event.client is not None else self._clients()):
            self._on_connect(client)

    def _set_extent(self, bristles, bodies) -> None:
        """The box (mm) the design spans, bristles and bodies, at least 20 mm; the guides
        follow it."""
        pts = [bristles.positions] if bristles is not None and len(bristles.positions) else []
        for b in bodies:
            if len(b.vertices):
                pts.append(b.vertices @ layout.quat_to_matrix(b.wxyz).T + b.position)
        if pts:
            allp = np.concatenate(pts) * uv.VIEW_SCALE
            lo, hi = allp.min(0), allp.max(0)
        else:
            lo, hi = np.full(3, -25.0), np.full(3, 25.0)
        pad = np.maximum(20.0 - (hi - lo), 0.0) / 2
        self.design_extent = (lo - pad, hi + pad)
        self.guides.update(*self.design_extent)

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
                self._show_errors({key: [str(exc) + self._kept(f)]})
                if not from_client:
                    self._reset_box(f)
                return False
            v = us.validate(new)
            if not v.ok:
                named = us.fields_for_problems(v.problems, new, self.sel)
                msgs = {k: [p.message for p in ps] for k, ps in named.items()}
                mine = [p.message for p in v.problems]
                msgs[key] = [f"{f.label} = {_fmt_value(value)} {f.unit}".rstrip() +
                             " refused" + self._kept(f)] + mine
                self._show_errors(msgs)
                # A value typed in the browser stays in its box, with the refusal under it:
                # the box sends each keystroke, so "0.8" arrives as 0, 0., 0.8; putting the
                # design's 1 back into the box on the refused 0 made the next keys type
                # "1.8" (issue 29, item 1). The message says what the design keeps.
                if not from_client:
                    self._reset_box(f)
                return False
            self._edit_key = key   # (undo: successive keystrokes in one box are one edit)
            self.hold_design(v.scene)
            self._clear_errors()
            self.set_mode("design", redraw=False)
            self.redraw_design()
            # (the field a user is typing in keeps what they typed)
            self.refresh_fields(skip=key if from_client else None)
            return True

    def _kept(self, f: us.UiField) -> str:
        """' (the design keeps 17)': what the box goes back to after a refusal."""
        try:
            value = us.get_ui_value(f, self.scene, self.sel)
        except us.NotApplicable:
            return ""
        return f" (the design keeps {_fmt_value(value)} {f.unit}".rstrip() + ")"

    def _reset_box(self, f: us.UiField) -> None:
        """Put the design's value back into a field whose new value was refused, so that
        the box never shows a value the design does not have (the message under the field
        says what was typed)."""
        try:
            value = us.get_ui_value(f, self.scene, self.sel)
        except us.NotApplicable:
            return
        self.widgets[f.key].value = self._box_value(f, value)

    @staticmethod
    def _box_value(f: us.UiField, value):
        """A UI value as its box holds it (whole numbers in float boxes, see _add_widget)."""
        if f.kind == "int":
            return float(int(value))
        if f.kind in ("vector3", "rpy"):
            return tuple(float(c) for c in value)
        return value

    def set_design(self, scene) -> None:
        """Replace the whole design (a preset, an upload) by a validated engine.Scene."""
        with self.lock:
            self.loads += 1
            self.hold_design(scene)
            self.loaded_scene = copy.deepcopy(self.scene)   # (has_edits compares with it)
            self.loaded_label = f"{self.scene.get('name', 'scene')!r} was loaded"
            self._history_changed()
            self.sel = us.Selection()
            for md in (self.md_brush, self.md_body):  # notes on the previous design
                self._set_note(md, "")
            self._clear_errors()
            self.set_mode("design", redraw=False)
            self.redraw_design()
            self.refresh_fields()
        for client in self._clients():  # a new design: aim at it
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
            self._refresh_brush_selector()
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
                h.value = self._box_value(f, value)
            self._update_warnings()
            self._update_summary()

    def _update_warnings(self) -> None:
        """Scale warnings (``studio.web.design_warnings``) under the selected brush's fields, in
        orange: accepted values that are probably a slip of the unit."""
        self.warnings = uw.scale_warnings(self.scene, self.sel.brush)
        for key, md in self.warn_md.items():
            lines = self.warnings.get(key, [])
            text = "\n\n".join(f"<span style='color:#b60'>⚠ {_md_escape(m)}</span>"
                                for m in lines)
            if md.content != text:
                md.content = text
            md.visible = bool(text) and self.widgets[key].visible

    def _update_summary(self) -> None:
        nb = sum(int(b["rows"]) * int(b["columns"]) for b in self.scene.get("brushes") or [])
        ns = uv.n_design_segments(self.scene)
        self.md_summary.content = (
            f"*{self.scene.get('name', 'scene')}*: {nb:,} bristles, {ns:,} segments, "
            f"{len(self.scene.get('bodies') or [])} bod"
            f"{'y' if len(self.scene.get('bodies') or []) == 1 else 'ies'}; "
            f"{self.scene['run']['duration']:g} s to simulate.  \n{self._view_line()}" +
            ("  \n<span style='color:#d00'>⚠ the design starts overlapping: see Body</span>"
             if any(o.kind != "bristle-bristle" for o in getattr(self, "overlaps", ()))
             else "") +
            "".join(f"  \n<span style='color:#b60'>⚠ {_md_escape(m)}</span>"
                    for m in getattr(self, "warnings", {}).get("design", [])))

    def _view_line(self) -> str:
        """What the 3D view shows, in words (and how to switch)."""
        run = getattr(self, "playback_job", None)
        if self.mode == "playback":
            return f"View: **run `{run}`** (the design is not shown: *show → design*)"
        if self.mode == "live":
            return f"View: **running job `{self.active_job}`, live**"
        return "View: **design**" + (f" (run `{run}` is loaded: *show → run*)" if run else "")

    def redraw_design(self) -> None:
        """Draw the design: bristles at rest, bodies at their pose, the gizmo on the
        selected body; check it for initial overlap (``engine.assembly.overlap``, the check
        ``engine.build`` makes) and mark what overlaps in red, with the message under the
        Body folder."""
        with self.lock:
            t0 = time.perf_counter()
            coarse = uv.n_design_segments(self.scene) > MAX_VIEW_SEGMENTS
            if coarse:
                scene = copy.deepcopy(self.scene)
                for b in scene["brushes"]:
                    b["n_nodes"] = 2
            else:
                scene = self.scene
            bristles = uv.design_bristles(scene)
            bodies = uv.design_bodies(self.scene)
            self._update_overlaps(None if coarse else bristles, bodies)
            self._set_extent(bristles, bodies)
            if self.mode != "design":
                return
            first = uv.design_bristle_first(scene)
            colors = uv.overlap_segment_colors(bristles, self.overlaps, first)
            colors = ub.selected_brush_colors(scene, bristles.bonds, first, self.sel.brush,
                                              colors, uv.BRISTLE_COLOR)
            self.view.set_bristle_nodes(bristles, colors)
            self.n_segments_drawn = bristles.n_segments
            self.view.set_bodies(bodies, highlight={o.body for o in self.overlaps if o.body})
            self._place_gizmo()
            self.last_draw_s = time.perf_counter() - t0

    def _update_overlaps(self, bristles, bodies) -> None:
        """Check the design for initial overlap; show what is found under the Body folder."""
        try:
            self.overlaps = uv.design_overlaps(self.scene, bristles, bodies) \
                if bristles is not None else []
        except Exception as exc:  # (a check that fails must not stop the design)
            print(f"studio: overlap check failed: {type(exc).__name__}: {exc}")
            self.overlaps = []
        lines = []
        for o in self.overlaps:
            refused = o.kind != "bristle-bristle"
            lines.append(f"<span style='color:{'#d00' if refused else '#b60'}'>"
                         f"{'⚠ ' if refused else ''}{_md_escape(str(o))}"
                         f"{' — Start would be refused' if refused else ''}</span>")
        text = "\n\n".join(lines)
        if getattr(self, "_overlap_md", None) != text:
            self._overlap_md = text
            self.md_overlap.content = text
            self.md_overlap.visible = bool(text)
            self._update_summary()

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
            self.hold_design(v.scene)
            if uv.n_design_segments(self.scene) <= uv.MAX_OVERLAP_CHECK_SEGMENTS:
                self.redraw_design()  # (the overlap check follows the body)
            else:
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
                self.hold_design(v.scene)
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
                self.hold_design(v.scene)
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
                self.hold_design(v.scene)
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
            self.hold_design(v.scene)
            self.sel.body = 0
            self.set_mode("design", redraw=False)
            self.redraw_design()
            self.refresh_fields()

    @staticmethod
    def _set_note(md, text: str) -> None:
        md.content = _md_escape(text)
        md.visible = bool(text)
