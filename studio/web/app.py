"""Brush Studio in the browser: the viser app (``brush-studio studio``).

    brush-studio studio [--host 127.0.0.1] [--port 8080] [--preset NAME_OR_PATH]
                        [--data DIR] [--workers N] [--api-port PORT]

One design session per browser tab (``studio.web.session.Session``: the panels of
``studio.web.panels`` over the tab's own GUI and scene handles): the panels on the left edit that
tab's scene (millimetres and degrees, SI inside), the 3D view follows every change at once,
Start queues the design as a job in the shared background worker pool
(``studio.service.jobs.JobManager``: the worker process runs the engine and writes HDF5; this process
only reads result files with ``engine.open_result``), the latest frames of a running job
stream into the view, and a finished run can be scrubbed, played and plotted. Runs and
studies are shared: every tab lists every job. The Studies tab (``studio.web.panels.studies_tab``)
starts a study as a job of the same pool. Beside viser, the same JobManager is served as the
HTTP API (``studio.service.server``) on ``--api-port`` (default port + 1), plus the studio routes:

* ``GET /studio?preset=NAME`` (or ``?design=ID``, a design shared with the Share button)
  redirects to the viser page with a websocket URL naming the design
  (``/?websocket=ws://HOST:PORT/preset/NAME``): the new tab's own session opens on it, and
  the page's URL is a link to it; nobody else's design changes;
* ``GET /studio/state[?client=ID]``: what a session shows (mode, instanced segments, bodies'
  poses, timeline frame, field errors, initial overlaps) as JSON, for scripts and the
  browser tests; ``sessions`` lists the open ones.

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

from studio.console import print_scene_error
from studio.exit_codes import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK
from studio.web.panels.common import STREAM_HZ
from studio.plots.result_frames import ResultFrames  # noqa: F401  (the studio's public name)
from studio.web.page_script import send_page_script
from studio.web.panels.design_history import draft_path, new_draft_id
from studio.web.session import Session
from studio.presets import demo_scene, load_preset_or_file, preset_names  # noqa: F401  (demo_scene: the studio's public name)

DEFAULT_DATA_DIR = "brush-studio-data"


# =========================================================================== the studio
class Studio:
    """The viser studio: what every tab shares. ``server``: a ``viser.ViserServer``;
    ``jobs``: a ``studio.service.jobs.JobManager`` (or None: designing only); ``scene``: the design a
    new session opens on.

    ``per_client=True`` (``brush-studio studio``): each tab that connects gets its own
    :class:`studio.web.session.Session` (design, playback, selection), opened on the design its
    URL names (``/?websocket=ws://HOST:PORT/preset/NAME`` or ``.../design/ID``, which
    ``GET /studio?preset=NAME`` redirects to) or else on ``scene``. ``per_client=False``: one
    session drawn for every tab, whose attributes this object forwards (scripts, tests)."""

    def __init__(self, server, jobs, scene, data_dir: Optional[Path] = None,
                 per_client: bool = False):
        self.server = server
        self.jobs = jobs
        self.data_dir = Path(data_dir) if data_dir is not None else None
        self.default_scene = scene
        self.per_client = per_client
        self.sessions: dict[int, Session] = {}
        self.sessions_lock = threading.RLock()
        self._stop = threading.Event()
        try:
            server.gui.configure_theme(control_width="large", show_share_button=False)
        except TypeError:
            server.gui.configure_theme(control_width="large")
        server.scene.set_up_direction("+z")
        server.scene.add_grid("/grid", width=200.0, height=200.0, cell_size=10.0,
                              section_size=50.0, plane="xy", position=(0.0, 0.0, 0.0))
        self.shared: Optional[Session] = None
        if not per_client:
            self.shared = Session(server, jobs, scene, data_dir=self.data_dir,
                                  share=self.share_design)
        server.on_client_connect(self._on_connect)
        server.on_client_disconnect(self._on_disconnect)
        self.poller = threading.Thread(target=self._poll_loop, name="studio-poll", daemon=True)
        self.poller.start()

    def __getattr__(self, name):
        # (a shared session's attributes and methods, as before sessions: app.edit(...))
        shared = self.__dict__.get("shared")
        if shared is None:
            raise AttributeError(name)
        return getattr(shared, name)

    # ----------------------------------------------------------------- sessions
    def _on_connect(self, client) -> None:
        if self.shared is not None:
            self.shared._on_connect(client)
            return
        path, host = client_request(self.server, client.client_id)
        scene, note = self.design_for(path)
        session = Session(client, self.jobs, scene, data_dir=self.data_dir,
                          client_id=client.client_id, note=note, share=self.share_design,
                          link_host=host)
        preset = (path or "").split("?")[0].strip("/").split("/")
        if len(preset) == 2 and preset[0] == "preset" and preset[1] in session.dd_preset.options:
            session.dd_preset.value = preset[1]
        draft = self.draft_for(path)
        with self.sessions_lock:
            # a reloaded tab takes its draft back; a second tab opened on the same address
            # (a copied link) gets a copy under a new id, so two tabs never share one draft
            taken = {getattr(x, "draft_id", None) for x in self.sessions.values()}
            draft_id = draft[0] if draft is not None and draft[0] not in taken \
                else new_draft_id()
            self.sessions[client.client_id] = session
        if draft is not None:
            session.restore_draft(draft[1])
        if self.data_dir is not None:
            session.attach_draft(draft_id)
        send_page_script(client)
        session._on_connect(client)

    def _on_disconnect(self, client) -> None:
        with self.sessions_lock:
            session = self.sessions.pop(client.client_id, None)
        if session is not None:
            session.close()

    def design_for(self, path: Optional[str]):
        """The design a tab opened at websocket path ``path`` starts on, and a note:
        ``/preset/NAME`` (a shipped preset), ``/design/ID`` (a design shared with
        :meth:`share_design`), else the studio's default."""
        import engine

        parts = [p for p in (path or "").split("?")[0].split("/") if p]
        try:
            draft = self.draft_for(path)
            if draft is not None:
                return (engine.parse_scene(draft[1]["scene"]),
                        "the design as this tab left it (reloaded)")
            if len(parts) == 2 and parts[0] == "preset" and parts[1] in preset_names():
                return load_preset_or_file(parts[1]), f"opened on preset {parts[1]!r} (link)"
            if len(parts) == 2 and parts[0] == "design":
                stored = self.design_path(parts[1])
                if stored is not None and stored.exists():
                    return (engine.parse_scene(stored.read_text()),
                            f"opened on shared design {parts[1]!r} (link)")
                return self.default_scene, f"no shared design {parts[1]!r}: the default"
        except engine.SceneError as exc:
            return self.default_scene, f"link refused: {exc}"
        return self.default_scene, ""

    def draft_for(self, path: Optional[str]) -> Optional[tuple[str, dict]]:
        """(id, saved draft) a tab reconnecting at ``/draft/ID`` (a reload) reopens; None
        when the path names no draft or it is not there (a studio restarted with another
        data folder)."""
        parts = [p for p in (path or "").split("?")[0].split("/") if p]
        if len(parts) != 2 or parts[0] != "draft":
            return None
        stored = draft_path(self.data_dir, parts[1])
        if stored is None or not stored.exists():
            return None
        try:
            return parts[1], json.loads(stored.read_text())
        except (OSError, ValueError):
            return None

    def design_path(self, design_id: str) -> Optional[Path]:
        if self.data_dir is None or not design_id.isalnum():
            return None
        return self.data_dir / "designs" / f"{design_id}.json"

    def share_design(self, text: str) -> Optional[str]:
        """Store a design (scene JSON) under a content id; returns the id (None without a
        data folder)."""
        import hashlib

        design_id = hashlib.sha256(text.encode()).hexdigest()[:12]
        path = self.design_path(design_id)
        if path is None:
            return None
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        return design_id

    def session(self, client: Optional[int] = None) -> Optional[Session]:
        """The session of ``client`` (None: the shared one, else the newest tab's)."""
        if self.shared is not None:
            return self.shared
        with self.sessions_lock:
            if client is not None:
                return self.sessions.get(int(client))
            return self.sessions[max(self.sessions)] if self.sessions else None

    # ----------------------------------------------------------------- polling
    def _poll_loop(self) -> None:
        while not self._stop.wait(1.0 / STREAM_HZ):
            now = time.monotonic()
            with self.sessions_lock:
                sessions = [self.shared] if self.shared is not None else \
                    list(self.sessions.values())
            for s in sessions:
                try:
                    s.poll(now)
                except Exception as exc:  # never let the poller die
                    print(f"studio: poll error: {type(exc).__name__}: {exc}")

    # ----------------------------------------------------------------- state
    def state(self, client: Optional[int] = None) -> dict:
        """What a session shows (for scripts and tests): ``client``'s, or the newest tab's;
        ``sessions`` lists every open one."""
        s = self.session(client)
        out = s.state() if s is not None else {"mode": None, "scene_name": None,
                                               "client": None}
        with self.sessions_lock:
            out["sessions"] = [{"client": c, "scene_name": x.scene.get("name"),
                                "mode": x.mode} for c, x in sorted(self.sessions.items())]
        return out

    def load_preset(self, name: str) -> None:
        s = self.session()
        if s is not None:
            s.load_preset(name)

    def close(self) -> None:
        self._stop.set()
        self.poller.join(timeout=2.0)
        for s in ([self.shared] if self.shared else []) + list(self.sessions.values()):
            s.close()


def client_request(server, client_id: int) -> tuple[Optional[str], Optional[str]]:
    """The path (``/preset/NAME``...) and Host header of the websocket request a client
    connected with. viser 1.1 has no public API for them: read from its websocket server's
    live connections ((None, None) when that changes: every tab then opens on the default)."""
    try:
        request = server._websock_server._live_connections[client_id].request
        return request.path, request.headers.get("Host")
    except Exception:
        return None, None


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

    try:
        scene = load_preset_or_file(preset or "demo")
    except engine.SceneError as exc:
        print_scene_error(exc, f"cannot open preset {preset!r}")
        return EXIT_BAD_INPUT
    from studio.service.jobs import JobManager
    from studio.service.hosts import is_loopback

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
    from studio.service.hosts import allowed_hosts
    from studio.service.server.ws_guard import guarded_viser_server

    # the page and its WebSocket with the API's Host and Origin rules (DNS rebinding, pages
    # of other sites)
    server = guarded_viser_server(host, port, allowed_hosts(host), verbose=False)
    studio = Studio(server, jobs, scene, data_dir=Path(data_dir), per_client=True)
    api = None
    if api_port is None:
        api_port = port + 1
    if api_port > 0:
        try:
            from studio.service.server.studio_routes import make_api_app, serve_in_thread

            app = make_api_app(jobs, studio, viser_port=port, token=token, host=host)
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
