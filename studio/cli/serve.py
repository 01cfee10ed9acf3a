"""``brush-studio serve --headless``: the HTTP job service (``studio.service.server``) under uvicorn.

    brush-studio serve --headless [--host 127.0.0.1] [--port 8000] [--workers N]
                       [--data DIR] [--token TOKEN] [--cors ORIGIN ...]
                       [--scheduler tcp://HOST:PORT]   (where study jobs run their runs)

Binds 127.0.0.1 unless told otherwise; binding another address without a token prints a
warning. The token may also come from the environment (``BRUSH_STUDIO_TOKEN``) so that it
does not show in the process list. Jobs, results and uploaded meshes live under ``--data``
(default ``$BRUSH_STUDIO_DATA`` or ``./brush-studio-data``); a restarted server lists them.
"""
from __future__ import annotations

import os
import signal
import sys

from studio.exit_codes import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK
from studio.service.hosts import allowed_hosts, is_loopback

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8000
DEFAULT_DATA = "brush-studio-data"
# after SIGTERM/SIGINT the pool is closed (running jobs cancelled, files closed); if anything
# still holds the process this long (a request thread stuck in a library call), it exits
SHUTDOWN_DEADLINE_S = 45.0


def _exit_after(seconds: float, code: int) -> None:
    """End the process with ``code`` in ``seconds`` unless it has ended by then (a daemon
    timer: it keeps running while the interpreter waits for other threads at exit)."""
    import threading

    def end():
        print(f"brush-studio serve: still running {seconds:g} s after the stop signal; "
              f"exiting now", file=sys.stderr, flush=True)
        os._exit(code)

    timer = threading.Timer(seconds, end)
    timer.daemon = True
    timer.start()


def register(subparsers) -> None:
    s = subparsers.add_parser(
        "serve", help="serve the engine as an HTTP job service (--headless)",
        description="Serve Brush Studio's HTTP API (docs/api.md, 'HTTP API'; OpenAPI at "
                    "/docs): submit scenes as jobs, follow their progress, download results. "
                    "Jobs run in a pool of worker processes; their state and files persist "
                    "under --data. The 3D studio with the same API is `brush-studio studio`.")
    s.add_argument("--headless", action="store_true",
                   help="serve the HTTP API only, without the 3D studio (required for now: "
                        "the studio is `brush-studio studio`)")
    s.add_argument("--host", default=DEFAULT_HOST,
                   help=f"address to bind (default {DEFAULT_HOST}: this machine only)")
    s.add_argument("--port", type=int, default=DEFAULT_PORT,
                   help=f"port (default {DEFAULT_PORT})")
    s.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes running jobs at once (default: one per core)")
    s.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="Dask scheduler that study jobs run their simulations on (default: "
                        "each study job starts one local Dask worker)")
    s.add_argument("--data", default=None, metavar="DIR",
                   help=f"folder for the job database, results and meshes (default "
                        f"$BRUSH_STUDIO_DATA or ./{DEFAULT_DATA})")
    s.add_argument("--token", default=None,
                   help="require 'Authorization: Bearer TOKEN' on the API (default "
                        "$BRUSH_STUDIO_TOKEN; none: no authentication)")
    s.add_argument("--cors", nargs="*", default=[], metavar="ORIGIN",
                   help="browser origins allowed to call the API (default: none, CORS off)")
    s.add_argument("--allow-host", nargs="*", default=[], metavar="NAME",
                   help="names a request's Host header may give besides the bound address "
                        "and, on loopback, localhost/127.0.0.1/::1 (against DNS rebinding; "
                        "binding 0.0.0.0 without it leaves Host unchecked)")
    s.add_argument("--max-body-mb", type=float, default=8.0,
                   help="largest request body (a scene), MiB (default 8)")
    s.add_argument("--max-upload-mb", type=float, default=64.0,
                   help="largest mesh upload, MiB (default 64)")
    s.add_argument("--max-triangles", type=int, default=200_000,
                   help="most triangles in an uploaded mesh (default 200000)")
    from studio.service.jobs import Limits

    d = Limits()
    lim = s.add_argument_group("limits", "what one job may cost, checked at submit from the "
                               "scene's estimate before anything is built (413/422 naming "
                               "the limit), and how many jobs may wait (429); 0: no limit")
    lim.add_argument("--max-nodes", type=int, default=d.max_nodes,
                     help=f"bristle nodes in one scene (default {d.max_nodes})")
    lim.add_argument("--max-steps", type=float, default=d.max_steps,
                     help=f"steps to a scene's duration (default {d.max_steps:.0e})")
    lim.add_argument("--max-node-steps", type=float, default=d.max_node_steps,
                     help=f"nodes x steps, a run's work (default {d.max_node_steps:.0e})")
    lim.add_argument("--max-frames", type=float, default=d.max_frames,
                     help=f"recorded frames (default {d.max_frames:.0e})")
    lim.add_argument("--max-memory-mb", type=float, default=d.max_memory_bytes / 2**20,
                     help=f"estimated memory of one run, MiB (default "
                          f"{d.max_memory_bytes / 2**20:.0f})")
    lim.add_argument("--max-result-mb", type=float, default=d.max_result_bytes / 2**20,
                     help=f"estimated result file of one run, MiB (default "
                          f"{d.max_result_bytes / 2**20:.0f})")
    lim.add_argument("--max-job-seconds", type=float, default=d.max_job_seconds,
                     help=f"wall time of one job: then it is stopped and fails (default "
                          f"{d.max_job_seconds:.0f})")
    lim.add_argument("--max-queued", type=int, default=d.max_queued,
                     help=f"jobs waiting at once; more are refused with 429 (default "
                          f"{d.max_queued})")
    lim.add_argument("--max-study-runs", type=int, default=d.max_study_runs,
                     help=f"runs one study may plan (default {d.max_study_runs})")
    lim.add_argument("--keep-days", type=float, default=0.0,
                     help="delete finished jobs and their files this many days after they "
                          "finished (default 0: keep everything; DELETE "
                          "/api/runs/{id}?purge=true deletes one)")
    lim.add_argument("--max-storage-gb", type=float, default=0.0,
                     help="most GiB of job files and meshes in the data folder; a submit "
                          "that would go over it (by its estimated result) is refused with "
                          "507 and health says degraded (default 0: no quota)")
    lim.add_argument("--min-free-mb", type=float, default=16.0,
                     help="free space the data folder must keep; below it submits are "
                          "refused with 507 and health says degraded (default 16)")
    s.add_argument("--log-level", default="info",
                   choices=["critical", "error", "warning", "info", "debug"])
    s.set_defaults(func=_cmd_serve)


def limits_from_args(args):
    """The :class:`studio.service.jobs.Limits` of the command's options (0: no limit); ValueError
    for a negative one."""
    from studio.service.jobs import Limits

    values = {}
    for name, scale in (("max_nodes", 1), ("max_steps", 1), ("max_node_steps", 1),
                        ("max_frames", 1), ("max_memory_mb", 2**20),
                        ("max_result_mb", 2**20), ("max_job_seconds", 1), ("max_queued", 1),
                        ("max_study_runs", 1), ("keep_days", 1),
                        ("max_storage_gb", 2**30)):
        v = getattr(args, name)
        if not v >= 0:
            raise ValueError(f"--{name.replace('_', '-')} = {v}: must be >= 0 (0: no limit)")
        field = name.replace("_mb", "_bytes").replace("_gb", "_bytes")
        values[field] = None if v == 0 else v * scale
    if args.min_free_mb < 0:
        raise ValueError(f"--min-free-mb = {args.min_free_mb}: must be >= 0")
    return Limits(**values)


def _cmd_serve(args) -> int:

    err = lambda m: print(m, file=sys.stderr)  # noqa: E731
    if not args.headless:
        err("brush-studio serve: the 3D studio is served by `brush-studio studio`; "
            "add --headless to serve the HTTP API alone")
        return EXIT_BAD_INPUT
    if not 0 < args.port < 65536:
        err(f"--port = {args.port}: must be 1..65535")
        return EXIT_BAD_INPUT
    if args.workers is not None and args.workers < 1:
        err(f"--workers = {args.workers}: must be >= 1")
        return EXIT_BAD_INPUT
    for name in ("max_body_mb", "max_upload_mb"):
        if not getattr(args, name) > 0:
            err(f"--{name.replace('_', '-')} must be > 0")
            return EXIT_BAD_INPUT
    if args.scheduler is not None and "://" not in args.scheduler:
        err(f"--scheduler = {args.scheduler!r}: expected an address like tcp://HOST:PORT")
        return EXIT_BAD_INPUT
    if args.max_triangles < 1:
        err("--max-triangles must be >= 1")
        return EXIT_BAD_INPUT
    try:
        limits = limits_from_args(args)
    except ValueError as exc:
        err(str(exc))
        return EXIT_BAD_INPUT
    token = args.token or os.environ.get("BRUSH_STUDIO_TOKEN") or None
    if not is_loopback(args.host) and token is None:
        err(f"WARNING: binding {args.host} without --token: anyone who can reach this "
            f"port can run jobs and read results. Pass --token (or set BRUSH_STUDIO_TOKEN).")
    data = args.data or os.environ.get("BRUSH_STUDIO_DATA") or DEFAULT_DATA

    import uvicorn

    from studio.service.jobs import JobManager
    from studio.service.server import create_app

    try:
        jobs = JobManager(data, workers=args.workers, max_triangles=args.max_triangles,
                          scheduler=args.scheduler, limits=limits,
                          min_free_bytes=int(args.min_free_mb * 2**20))
    except (RuntimeError, OSError, ValueError) as exc:
        err(f"error: {exc}")
        return EXIT_FAILED
    try:
        app = create_app(jobs, token=token, cors_origins=args.cors,
                         allowed_hosts=allowed_hosts(args.host, args.allow_host),
                         max_body_bytes=int(args.max_body_mb * 1024 * 1024),
                         max_upload_bytes=int(args.max_upload_mb * 1024 * 1024))
        print(f"Brush Studio API on http://{args.host}:{args.port}/api (OpenAPI: "
              f"http://{args.host}:{args.port}/docs); data in {jobs.data_dir}; "
              f"{jobs.n_workers} worker(s) x {jobs.threads_per_worker} thread(s)"
              f"{'; bearer token required' if token else ''}", flush=True)
        config = uvicorn.Config(app, host=args.host, port=args.port,
                                log_level=args.log_level, timeout_graceful_shutdown=5)
        server = uvicorn.Server(config)
        # uvicorn shuts down gracefully on SIGINT/SIGTERM and then re-raises the signal to
        # the handler that was there before it: ours only notes it, so that the job pool
        # below is closed too (running jobs cancelled, their files closed, workers ended).
        received: list[int] = []
        previous = {sig: signal.signal(sig, lambda s, f: received.append(s))
                    for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            server.run()
        except SystemExit as exc:  # uvicorn exits when it cannot bind
            if exc.code not in (None, 0):
                err(f"error: could not serve on {args.host}:{args.port} (in use, or not an "
                    f"address of this machine)")
                return EXIT_FAILED
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            if received:  # stopped by a signal: whatever hangs below, the process ends
                _exit_after(SHUTDOWN_DEADLINE_S, 128 + received[0])
        if not server.started:
            err(f"error: could not serve on {args.host}:{args.port}")
            return EXIT_FAILED
    finally:
        jobs.close()
    return EXIT_OK
