"""The Results panel: a finished (or stopped) run opened for playback: the time slider, play
and speed, colour-by and its legend, the plots with their cursor, the HDF5 download. The
run is read by :class:`~studio.plots.result_frames.ResultFrames`, its plots drawn by
:mod:`studio.plots.result_plots`. A mixin of :class:`studio.web.app.Studio`."""
from __future__ import annotations

import time
from typing import Any, Optional

import numpy as np

from studio.web import view as uv
from studio.plots.result_plots import CURSOR_COLOR, result_figures
from studio.web.panels.common import (COLOR_MODES, PLOT_ASPECT, PLOT_CURSOR_S, SPEEDS, _md_escape,
                     _safe_name)
from studio.plots.result_frames import ResultFrames, color_note

PLOT_PLACES = ("docked", "pop out", "minimise")
# px: a plot 460 px wide; the 3D view gets what the control panel (384 px, docked left)
# and the plots leave between them
PLOTS_DOCKED_WIDTH = 480
PLOTS_FLOAT_SIZE = (900, 700)  # px


class ResultsPanel:
    """Results tab of the studio (mixin)."""

    def _build_results_gui(self, gui) -> None:
        with self.tab_results:
            self.md_result = gui.add_markdown("No run loaded. Finished runs load here.")
            self.sl_time = gui.add_slider("time [s]", min=0.0, max=1.0, step=0.01,
                                          initial_value=0.0, disabled=True)
            self.sl_time.on_update(self._on_slider)
            self.md_time = gui.add_markdown("")
            self.cb_play = gui.add_checkbox("play", False, disabled=True)
            self.cb_play.on_update(self._on_play)
            self.dd_speed = gui.add_dropdown("speed (simulated s per s)", SPEEDS,
                                             initial_value="0.25x")
            self.dd_color = gui.add_dropdown("colour bristles by", COLOR_MODES,
                                             initial_value="bending moment")
            self.dd_color.on_update(lambda e: self._show_frame(self.frame_index))
            self.html_legend = gui.add_html("", visible=False)
            self.md_color = gui.add_markdown("", visible=False)
            self.bg_plots = gui.add_button_group("plots window", PLOT_PLACES)
            self.bg_plots.on_click(lambda e: self._place_plots(e.target.value))
            self.bt_download_h5 = gui.add_button("Download result HDF5", disabled=True)
            self.bt_download_h5.on_click(self._on_download_h5)
            self.bt_export = gui.add_button(
                "Export…", disabled=True,
                hint="the run for ParaView and Python tools, the plotted series as CSV")
            self.bt_export.on_click(self._on_export_dialog)
            self.bt_design = gui.add_button("Back to the design view")
            self.bt_design.on_click(lambda e: self.set_mode("design"))
            self._build_compare_gui(gui)
            self.plots: dict[str, Any] = {}
            self.figures: dict[str, Any] = {}
            self.legend: Optional[dict] = None
            self.plots_place = "docked"
        self._new_plots_window(gui)

    def _new_plots_window(self, gui) -> None:
        """The plots get a window of their own beside the 3D view (issue 14, item 9: the
        side panel's 380 px are too narrow to read them); with a viser before panels, the
        Results tab."""
        self.plots_panel = gui.add_panel(visible=False) if hasattr(gui, "add_panel") \
            else None
        self.plots_tab = self.plots_panel.add_tab("Plots") if self.plots_panel is not None \
            else self.tab_results

    def _place_plots(self, where: str) -> None:
        """Dock the plots window at the right, float it large over the view, or minimise
        it."""
        panel = self.plots_panel
        if panel is None or where not in PLOT_PLACES:
            return
        if where == "docked" and self.plots_place == "pop out":
            # viser 1.1's page docks a window that floated at its floating width, whatever
            # width it is then given: a new window docks at the width asked for
            with self.lock:
                panel.remove()
                self.plots.clear()
                self._new_plots_window(self.server.gui)
                panel = self.plots_panel
                self.plots_place = where
                if self.playback is not None:
                    self._make_plots()  # (shows and places the new window)
                    self._move_cursor(float(self.playback.time[max(self.frame_index, 0)]))
                return
        self.plots_place = where
        if where == "docked":
            panel.dock_right()
            panel.set_width(PLOTS_DOCKED_WIDTH)
            panel.expand()
        elif where == "pop out":
            panel.float(x=20, y=20, width=PLOTS_FLOAT_SIZE[0], height=PLOTS_FLOAT_SIZE[1])
            panel.expand()
        else:
            panel.minimize()

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
            self._set_time_slider(np.asarray(frames.time, float))
            self.cb_play.disabled = n < 2
            self.bt_download_h5.disabled = False
            self.bt_export.disabled = False
            self.bt_compare_add.disabled = False
            info = self.jobs.get(job_id)
            t_end = float(frames.time[-1]) if n else 0.0
            self.md_result.content = (
                f"Run `{job_id}` ({_md_escape(info.name)}): **{frames.res.status}**, {n} frames,"
                f" t = 0 … {t_end:.4g} s" +
                (f". {_md_escape(info.error)}" if info.error else ""))
            self._make_plots()
            self.frame_index = -1
            self.sl_time.value = self.sl_time.min
            self._show_frame(0)
        return True

    def _set_time_slider(self, t: np.ndarray) -> None:
        """The timeline over the run's recorded times, in seconds: one step per record
        interval, as many decimals as the step needs."""
        n = len(t)
        t0, t1 = (float(t[0]), float(t[-1])) if n else (0.0, 0.0)
        step = float(np.median(np.diff(t))) if n > 1 else 1.0
        if not step > 0:
            step = (t1 - t0) / max(n - 1, 1) or 1.0
        digits = int(min(max(np.ceil(-np.log10(step)) + 1, 1), 9))
        # the ends rounded to the digits shown (the slider's tooltip shows them as they
        # are: 0.9999582512234378 for a run that stopped at 1 s); a time picks the nearest
        # frame, so the last frame stays at the end
        lo, hi = round(t0, digits), round(t1, digits)
        self.sl_time.min, self.sl_time.max = lo, (hi if hi > lo else lo + step)
        self.sl_time.step = step
        self.sl_time.precision = digits
        self.sl_time.disabled = n < 2

    def frame_at(self, t: float) -> int:
        """The recorded frame nearest to time ``t`` [s] of the loaded run."""
        times = np.asarray(self.playback.time, float) if self.playback is not None else []
        if len(times) == 0:
            return 0
        i = int(np.searchsorted(times, t))
        if i >= len(times):
            return len(times) - 1
        if i > 0 and t - times[i - 1] <= times[i] - t:
            return i - 1
        return i

    def playback_time(self) -> Optional[float]:
        """The simulated time [s] of the frame the loaded run shows (None: none loaded)."""
        res = self.playback
        if res is None or res.n_frames == 0 or self.frame_index < 0:
            return None
        return float(res.time[min(self.frame_index, res.n_frames - 1)])

    def _on_slider(self, event) -> None:
        """Scrubbing shows the loaded run: after a design edit (which shows the design) the
        first touch of the slider switches the view back to the run."""
        if self.mode != "playback" and event.client is not None and self.playback is not None:
            self.set_mode("playback")
        if self.mode == "playback":
            self._show_frame(self.frame_at(float(event.target.value)))

    def _on_play(self, event) -> None:
        if event.client is not None and self.cb_play.value and self.playback is not None:
            self.set_mode("playback")
            self._show_frame(self.frame_at(float(self.sl_time.value)))

    def show_view(self, which: str) -> bool:
        """Show the design or the run (the loaded playback, else the running job live).
        Returns False when there is no run to show."""
        with self.lock:
            if which == "design":
                self.set_mode("design")
                return True
            if self.playback is not None:
                self.set_mode("playback")
                self._show_frame(self.frame_at(float(self.sl_time.value)))
                return True
            if self.active_job is not None:
                self.set_mode("live")
                return True
            return False

    def _show_frame(self, i: int, source: Optional[ResultFrames] = None) -> None:
        """Draw frame ``i`` of the playback (or live) result."""
        with self.lock:
            res = source or self.playback
            if res is None or res.n_frames == 0:
                return
            i = int(min(max(i, 0), res.n_frames - 1))
            note = color_note(res, self.dd_color.value)
            if note != getattr(self, "_color_note", ""):
                self._color_note = note
                self.md_color.content = f"<span style='color:#b60'>⚠ {note}</span>" \
                    if note else ""
                self.md_color.visible = bool(note)
            x = res.nodes(i)
            scale = None
            if x is not None and len(res.bonds):
                colors = res.colors(self.dd_color.value, i, x)
                scale = res.colour_scale(self.dd_color.value) if colors is not None else None
                centres, wxyz, scales = uv.segment_instances(x, res.radius, res.bonds)
                self.view.set_bristles(centres, wxyz, scales, colors)
                self.n_segments_drawn = len(centres)
            self._show_legend(scale)
            meshes = []
            for name, (verts, tris) in res.bodies.items():
                pose = res.body_pose(name, i)
                if pose is not None:
                    meshes.append(uv.BodyMesh(name, verts, tris, pose[0], pose[1]))
            self.view.set_bodies(meshes)
            if source is None:
                self.frame_index = i
                t = res.time
                p = self.sl_time.precision
                self.md_time.content = (f"**t = {float(t[i]):.{p}f} s** of "
                                        f"{float(t[0]):.{p}f} … {float(t[-1]):.{p}f} s")
                now = time.monotonic()
                if not self.cb_play.value or now - self.last_cursor > PLOT_CURSOR_S:
                    self.last_cursor = now
                    self._move_cursor(float(res.time[i]))

    def _show_legend(self, scale: Optional[tuple[str, str, float]]) -> None:
        """The colour bar under *colour bristles by*: the quantity, its unit and the values
        at both ends and the middle (hidden when the bristles are not coloured)."""
        legend = None if scale is None else \
            {"quantity": scale[0], "unit": scale[1], "max": float(scale[2])}
        if legend == self.legend:
            return
        self.legend = legend
        if legend is None:
            self.html_legend.visible = False
            return
        top = legend["max"]
        ticks = "".join(f"<span>{v:.3g}</span>" for v in (0.0, top / 2, top))
        self.html_legend.content = (
            f"<div style='font-size:0.8em;padding:0 0.75em 0.4em'>"
            f"<div>colour: {legend['quantity']} [{legend['unit']}]</div>"
            f"<div style='height:12px;border:1px solid #888;"
            f"background:{uv.colormap_css()}'></div>"
            f"<div style='display:flex;justify-content:space-between'>{ticks}</div></div>")
        self.html_legend.visible = True

    # ----------------------------------------------------------------- plots
    def _make_plots(self) -> None:
        res = self.playback
        figs, self.cursor_x = result_figures(res)
        t = res.time
        gui = self.server.gui
        for title, fig in figs.items():
            x0 = self.cursor_x[title][0] if title in self.cursor_x and len(t) else \
                (float(t[0]) if len(t) else 0.0)
            fig.add_vline(x=float(x0), line_color=CURSOR_COLOR, line_width=1)
            self.figures[title] = fig
            if title in self.plots:
                self.plots[title].figure = fig
                self.plots[title].visible = True
            else:
                with self.plots_tab:
                    self.plots[title] = gui.add_plotly(fig, aspect=PLOT_ASPECT)
        for title in list(self.figures):  # a plot the previous run had and this one lacks
            if title not in figs:
                del self.figures[title]
                self.plots[title].visible = False
        if self.plots_panel is not None and not self.plots_panel.visible:
            self.plots_panel.visible = True
            self._place_plots(self.plots_place)

    def _move_cursor(self, t: float) -> None:
        times = self.playback.time if self.playback is not None else None
        for title, fig in list(self.figures.items()):
            x = t
            xs = getattr(self, "cursor_x", {}).get(title)
            if xs is not None and times is not None and len(times):
                x = float(np.interp(t, times, xs))
            fig.layout.shapes = ()
            fig.add_vline(x=x, line_color=CURSOR_COLOR, line_width=1)
            self.plots[title].figure = fig

    def _on_download_h5(self, event) -> None:
        if event.client is None or self.playback_job is None:
            return
        path = self.jobs.result_path(self.playback_job)
        event.client.send_file_download(f"{self._export_name()}.h5", path.read_bytes(),
                                        save_immediately=True)

    def _export_name(self) -> str:
        """The stem every download of the loaded run shares: ``NAME-JOB``."""
        return f"{_safe_name(self.jobs.get(self.playback_job).name)}-{self.playback_job}"

    def _on_export_dialog(self, event) -> None:
        """The export dialog: the run as a ParaView series, the plotted series as CSV, the
        HDF5 file, each a download named after the run."""
        if event.client is None or self.playback_job is None:
            return
        gui = event.client.gui
        stem = self._export_name()
        n = self.playback.n_frames if self.playback is not None else 0
        with gui.add_modal(f"Export run {self.playback_job}") as modal:
            gui.add_markdown(
                f"**{_md_escape(stem)}**, {n} frames.\n\n"
                f"* **ParaView / Python** (`{_md_escape(stem)}.zip`): `{_md_escape(stem)}.pvd` "
                f"and one VTK `.vtu` per frame: open the `.pvd` in ParaView (a time series), "
                f"read a `.vtu` with VTK, meshio or PyVista. Bristles as lines, bodies as "
                f"triangles in the world frame, metres; point data `radius`, `part`.\n"
                f"* **Plotted series** (`{_md_escape(stem)}-plots.csv`): every curve of the "
                f"plots, one row per point (plot, series, x, y with their units).\n"
                f"* **HDF5** (`{_md_escape(stem)}.h5`): everything recorded "
                f"(docs/results.md).\n\n"
                f"The same from a shell: `brush-studio export {_md_escape(stem)}.h5 -o "
                f"{_md_escape(stem)}`.")
            every = gui.add_number("every N-th frame (ParaView)", 1, min=1, step=1)
            b_vtk = gui.add_button("Download ParaView series (.zip)")
            b_csv = gui.add_button("Download plotted series (.csv)")
            b_h5 = gui.add_button("Download HDF5 (.h5)")
            b_close = gui.add_button("Close", color="gray")
            status = gui.add_markdown("")

            def _vtk(_e) -> None:
                from engine.io.vtk_export import export_vtk_zip

                status.content = "writing the series…"
                try:
                    data = export_vtk_zip(self.jobs.result_path(self.playback_job), stem,
                                          every=max(int(every.value), 1))
                except Exception as exc:
                    status.content = f"<span style='color:#d00'>export failed: " \
                                     f"{_md_escape(str(exc))}</span>"
                    return
                event.client.send_file_download(f"{stem}.zip", data, save_immediately=True)
                status.content = f"sent {stem}.zip ({len(data) / 1e6:.2f} MB)"

            def _csv(_e) -> None:
                from studio.web.export import figures_csv

                data = figures_csv(self.figures).encode()
                event.client.send_file_download(f"{stem}-plots.csv", data,
                                                save_immediately=True)
                status.content = f"sent {stem}-plots.csv"

            b_vtk.on_click(_vtk)
            b_csv.on_click(_csv)
            b_h5.on_click(self._on_download_h5)
            b_close.on_click(lambda _e: modal.close())

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
            self.sl_time.value = float(t[i])  # triggers _show_frame through the callback
