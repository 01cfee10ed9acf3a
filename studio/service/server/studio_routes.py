"""The 3D studio's own HTTP routes, served beside the API on the studio's ``--api-port``:
``/studio`` (open the studio, on a preset), ``/studio/presets`` and ``/studio/state``.

(No ``from __future__ import annotations`` here: FastAPI reads the route functions'
annotations, which must be objects, not names of locally imported classes.)
"""
import threading
from typing import Optional

from studio.presets import load_preset_or_file, preset_names


def studio_router(studio, viser_port: int):
    """The routes of ``studio`` (a :class:`studio.web.app.Studio`), whose page is on
    ``viser_port``."""
    from fastapi import APIRouter, Header, HTTPException
    from fastapi.responses import RedirectResponse

    router = APIRouter(tags=["studio"])

    def open_studio(request_host: str, preset: Optional[str], design: Optional[str] = None,
                    change: bool = False):
        """Redirect to the studio page, whose websocket URL names the design the new tab's
        own session opens on (nobody else's design changes). A studio with one shared
        design changes it only for ``change`` (a POST, which the Origin check guards: a
        GET can be sent by an ``<img>`` on any page)."""
        host = request_host.split(":")[0] if request_host else "127.0.0.1"
        page = f"http://{host}:{viser_port}/"
        if design:
            if not design.isalnum():
                raise HTTPException(404, detail=f"no shared design {design!r}")
            return RedirectResponse(f"{page}?websocket=ws://{host}:{viser_port}/design/{design}",
                                    status_code=307)
        if preset:
            import engine

            if preset not in preset_names():  # names only: no file paths from a URL
                raise HTTPException(404, detail=f"no preset {preset!r}; presets: "
                                                f"{preset_names()}")
            try:
                load_preset_or_file(preset)
            except engine.SceneError as exc:
                raise HTTPException(422, detail=[str(p) for p in exc.problems])
            if not getattr(studio, "per_client", False):
                if not change:
                    raise HTTPException(405, detail="this studio has one design shared by "
                                                    "every tab: POST /studio?preset=NAME "
                                                    "changes it", headers={"Allow": "POST"})
                studio.load_preset(preset)  # (one design shared by every tab)
                return RedirectResponse(page, status_code=303)
            return RedirectResponse(f"{page}?websocket=ws://{host}:{viser_port}/preset/{preset}",
                                    status_code=307)
        return RedirectResponse(page, status_code=307)

    @router.get("/studio")
    def studio_landing(preset: Optional[str] = None, design: Optional[str] = None,
                       host: Optional[str] = Header(None)):
        """Open the studio in a new session on ``preset`` (a name from GET
        /studio/presets) or on a shared ``design`` id, if given."""
        return open_studio(host or "", preset, design)

    @router.post("/studio")
    def studio_change(preset: Optional[str] = None, design: Optional[str] = None,
                      host: Optional[str] = Header(None)):
        """As GET, and in a studio with one shared design, load ``preset`` into it (a POST:
        refused from pages of other origins by the request guard)."""
        return open_studio(host or "", preset, design, change=True)

    @router.get("/studio/presets")
    def studio_presets():
        return {"presets": preset_names()}

    @router.get("/studio/state")
    def studio_state(client: Optional[int] = None):
        """What a session shows: ``client``'s (ids in ``sessions``), else the newest tab's."""
        return studio.state(client)

    return router


def make_api_app(jobs, studio, viser_port: int, token: Optional[str] = None,
                 host: str = "127.0.0.1", extra_hosts=()):
    """The HTTP API app (:func:`studio.service.server.create_app`) plus the studio's own routes,
    with the headless service's Host and Origin rules for the bound address ``host``
    (``extra_hosts``: more names its Host may give)."""
    from studio.service.hosts import allowed_hosts
    from studio.service.server import create_app

    app = create_app(jobs, token=token, allowed_hosts=allowed_hosts(host, extra_hosts))
    app.include_router(studio_router(studio, viser_port))
    return app


def serve_in_thread(app, host: str, port: int):
    """Serve ``app`` with uvicorn in a daemon thread: ``(server, thread)``; stop it with
    ``server.should_exit = True``."""
    import uvicorn

    config = uvicorn.Config(app, host=host, port=port, log_level="warning")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="studio-api", daemon=True)
    thread.start()
    return server, thread
