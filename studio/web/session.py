"""One design session: the studio as one browser tab sees it.

Each connected client gets its own :class:`Session` (issue 14, defect 3): its own design,
selection, field errors, playback and live view, drawn with the client's own GUI and scene
handles (``client.gui``, ``client.scene``), so an edit, a preset load or a scrub in one tab
changes nothing in another. What is shared lives in :class:`studio.web.app.Studio`: the job pool
(runs and studies, listed in every session's Runs and Studies tabs), the poller, the grid.

A session is the four panels of ``studio.web.panels`` (design, run, results, studies) mixed into
one object over one ``target``: a viser ``ClientHandle`` (one tab), or the ``ViserServer``
itself (every tab: the studio's tests and scripts that drive one shared session).
"""
from __future__ import annotations

import threading
from pathlib import Path
from typing import Optional

import numpy as np

from studio.web import guides as ug
from studio.web import scene as us
from studio.web import view as uv
from studio.web.panels.common import POLL_S, STUDIES_POLL_S
from studio.web.panels.compare import ComparePanel
from studio.web.panels.design import DesignPanel
from studio.plots.result_frames import ResultFrames
from studio.web.panels.results import ResultsPanel
from studio.web.panels.run import RunPanel
from studio.web.panels.studies import StudiesPanel


class Session(DesignPanel, RunPanel, ResultsPanel, ComparePanel, StudiesPanel):
    """One tab's studio. ``target``: a viser ClientHandle (or the ViserServer: shared by every
    tab); ``jobs``: the shared ``studio.service.jobs.JobManager`` (or None: designing only);
    ``scene``: the design it opens on."""

    def __init__(self, target, jobs, scene, data_dir: Optional[Path] = None,
                 client_id: Optional[int] = None, note: str = "", share=None,
                 link_host: Optional[str] = None):
        self.server = target          # (named so for the panels: where this session draws)
        self.share = share            # design JSON -> stored design id (Studio.share_design)
        self.link_host = link_host    # host:port the tab reached the studio at (for links)
        self.shared_design_id: Optional[str] = None
        self.client_id = client_id
        self.jobs = jobs
        self.data_dir = Path(data_dir) if data_dir is not None else None
        self.lock = threading.RLock()
        self.design = scene           # the design: a validated engine.Scene, parsed once per edit
        self.scene: dict = us.scene_dict(scene)         # its dict: the fields' working copy
        self.loaded_scene: dict = us.scene_dict(scene)  # what has_edits compares with
        self.sel = us.Selection()
        self.errors: dict[str, list[str]] = {}
        self.loads = 0                # designs loaded over this one (set_design): for scripts
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
        self.overlaps: list = []    # initial overlaps of the design (engine.assembly.overlap)
        self._runs_md = ""
        self._last_poll = self._last_studies = 0.0
        self.view = uv.View(target)
        self.guides = ug.Guides(target.scene)
        self.design_extent = (np.full(3, -25.0), np.full(3, 25.0))   # mm, redraw_design
        self._build_gui()
        self.gizmo = None
        self.redraw_design()
        self.refresh_fields()
        if note:
            self._set_note(self.md_preset, note)

    def hold_design(self, scene) -> None:
        """Hold ``scene``, the engine.Scene an edit's validation just parsed, as the design
        (the cost line and the saved JSON use it: no second parse) and its dict as the
        fields' working copy."""
        self.design = scene
        self.scene = us.scene_dict(scene)

    def _clients(self) -> list:
        """The clients this session draws for (one, or every tab for a shared session)."""
        if hasattr(self.server, "get_clients"):
            return list(self.server.get_clients().values())
        return [self.server]

    def _camera(self) -> Optional[dict]:
        """The tab's camera as the browser last reported it (None: a shared session)."""
        camera = getattr(self.server, "camera", None)
        if camera is None:
            return None
        try:
            return {"position": [float(c) for c in camera.position],
                    "look_at": [float(c) for c in camera.look_at],
                    "far": float(camera.far)}
        except Exception:  # (no camera state received yet)
            return None

    # ----------------------------------------------------------------- GUI
    def _build_gui(self) -> None:
        gui = self.server.gui
        # The control panel docked at the left edge: the 3D view is inset beside it (and
        # beside the plots docked at the right) instead of lying under a floating panel
        # that covered its middle once the plots docked (issue 29, item 4).
        main_panel = getattr(gui, "main_panel", None)
        if main_panel is not None:
            main_panel.dock_left()
        who = f" · session {self.client_id}" if self.client_id is not None else ""
        self.md_title = gui.add_markdown(f"**Brush Studio**{who}")
        self.md_summary = gui.add_markdown("")
        self.bg_view = gui.add_button_group("show", ("design", "run"))
        self.bg_view.on_click(lambda e: self.show_view(e.target.value))
        self.bt_fit = gui.add_button("Fit view", hint="aim the camera at the whole design")
        self.bt_fit.on_click(self._on_fit_view)
        self.cb_guides = gui.add_checkbox("axes and scale bar", True)
        self.cb_guides.on_update(lambda e: self.guides.set_visible(e.target.value))
        tabs = gui.add_tab_group()
        self.tab_design = tabs.add_tab("Design")
        self.tab_run = tabs.add_tab("Run")
        self.tab_results = tabs.add_tab("Results")
        self.tab_studies = tabs.add_tab("Studies")
        self._build_design_gui(gui)
        self._build_run_gui(gui)
        self._build_results_gui(gui)
        self._build_studies_gui(gui)

    # ----------------------------------------------------------------- polling
    def poll(self, now: float) -> None:
        """One tick of the shared poller for this session: its runs, its studies tab, its
        live stream and its playback clock."""
        if now - self._last_poll >= POLL_S:
            self._last_poll = now
            self._poll_jobs()
        if self.studies is not None and now - self._last_studies >= STUDIES_POLL_S:
            self._last_studies = now
            self.studies.poll()
        self._stream_live()
        self._advance_play(now)

    # ----------------------------------------------------------------- state
    def state(self) -> dict:
        """What the studio shows (for scripts and tests)."""
        with self.lock:
            bodies = {}
            for name, h in self.view.bodies.items():
                bodies[name] = {"position_mm": [float(c) for c in h.position],
                                "wxyz": [float(c) for c in h.wxyz]}
            return {
                "client": self.client_id,
                "mode": self.mode,
                "scene_name": self.scene.get("name"),
                "n_segments": int(self.view.n_instances if self.view.n_instances > 0 else 0),
                "segments_mean_mm": self.view.mean_segment_position(),
                "n_bristles": sum(int(b["rows"]) * int(b["columns"])
                                  for b in self.scene.get("brushes") or []),
                "bodies": bodies,
                "camera": self._camera(),
                "guides": {"visible": self.guides.visible, "axes_mm": self.guides.axes_mm,
                           "scale_bar_mm": self.guides.bar_mm,
                           "extent_mm": [[float(c) for c in e] for e in self.design_extent]},
                "frame": int(self.frame_index),
                "n_frames": int(self.playback.n_frames) if self.playback else 0,
                "playback_job": self.playback_job,
                "plots": list(self.figures) if self.playback is not None else [],
                "plot_traces": {title: [d.name for d in fig.data]
                                for title, fig in self.figures.items()}
                if self.playback is not None else {},
                "time_s": self.playback_time(),
                "slider": {"label": self.sl_time.label, "value": float(self.sl_time.value),
                           "min": float(self.sl_time.min), "max": float(self.sl_time.max)},
                "legend": self.legend,
                "plots_window": self.plots_place if self.plots_panel is not None and
                self.plots_panel.visible else None,
                "active_job": self.active_job,
                "errors": {k: list(v) for k, v in self.errors.items()},
                "edited": self.has_edits(),
                "loads": self.loads,
                "brush": int(self.sel.brush),
                "body": int(self.sel.body),
                "warnings": {k: list(v) for k, v in self.warnings.items()},
                "overlaps": [{"kind": o.kind, "body": o.body, "depth_m": o.depth,
                              "bristles": len(o.items), "message": str(o)}
                             for o in self.overlaps],
                "studies": self.studies.state() if self.studies is not None else None,
                "compare": self.compare_state(),
                "scene": self.scene,
            }

    def close(self) -> None:
        with self.lock:
            for r in (self.playback, self.live):
                if r is not None:
                    r.close()
            self.playback = self.live = None
