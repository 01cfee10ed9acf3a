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

import json
import os
import sys
import threading
import time
from pathlib import Path
from typing import Optional

import numpy as np

from . import ui_scene as us
from . import ui_view as uv
from .console import print_scene_error
from .exit_codes import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK
from .panels.common import POLL_S, STREAM_HZ, STUDIES_POLL_S
from .panels.design import DesignPanel
from .panels.results import ResultFrames, ResultsPanel  # noqa: F401  (ResultFrames: public)
from .panels.run import RunPanel
from .panels.studies import StudiesPanel
from .presets import demo_scene, load_preset_or_file, preset_names  # noqa: F401  (demo_scene: the studio's public name)

DEFAULT_DATA_DIR = "brush-studio-data"


# =========================================================================== the studio
class Studio(DesignPanel, RunPanel, ResultsPanel, StudiesPanel):
    """The viser studio. ``server``: a ``viser.ViserServer``; ``jobs``: a
    ``studio.jobs.JobManager`` (or None: designing only). The panels (``studio.panels``)
    hold each tab's widgets and handlers; this class holds what they share and the poller."""

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
        self.overlaps: list = []    # initial overlaps of the design (engine.overlap)
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
        self.bg_view = gui.add_button_group("show", ("design", "run"))
        self.bg_view.on_click(lambda e: self.show_view(e.target.value))
        tabs = gui.add_tab_group()
        self.tab_design = tabs.add_tab("Design")
        self.tab_run = tabs.add_tab("Run")
        self.tab_results = tabs.add_tab("Results")
        self.tab_studies = tabs.add_tab("Studies")
        self._build_design_gui(gui)
        self._build_run_gui(gui)
        self._build_results_gui(gui)
        self._build_studies_gui(gui)

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
                "overlaps": [{"kind": o.kind, "body": o.body, "depth_m": o.depth,
                              "bristles": len(o.items), "message": str(o)}
                             for o in self.overlaps],
                "studies": self.studies.state() if self.studies is not None else None,
                "scene": self.scene,
            }

    def close(self) -> None:
        self._stop.set()
        self.poller.join(timeout=2.0)
        for r in (self.playback, self.live):
            if r is not None:
                r.close()


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
