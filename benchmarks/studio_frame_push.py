"""Server-side cost of pushing one frame of bristles into the studio's 3D view.

    python benchmarks/studio_frame_push.py                # 1,000 and 10,000 bristles
    python benchmarks/studio_frame_push.py --bristles 1000 10000 40000 --nodes 8
    python benchmarks/studio_frame_push.py --client       # with a headless chromium connected

For each brush size it builds the rest geometry of a square brush (``n_nodes`` nodes per
bristle, so ``n_nodes - 1`` instanced cylinders per bristle), draws it once in a real
``viser.ViserServer`` (the studio's ``studio.web.view.View``), then times ``repeats`` frames, each
with every node moved (as a recorded frame from a result file would be):

* **compute**: node positions -> per-segment centres, orientations and scales
  (``studio.web.view.segment_instances``) and bending-moment colours (``studio.web.view.colormap``);
* **push**: assigning them to the batched-mesh handle inside ``server.atomic()`` (what the
  studio does for every streamed or scrubbed frame): viser serialises the arrays into its
  message buffer here;
* **total** = compute + push, the server's time per frame, and the frame rate it allows;
* **payload**: bytes of instance data per frame (float32 positions, quaternions, scales and
  uint8 colours: 43 bytes per segment).

``--client`` connects a headless chromium (Debian's /usr/bin/chromium through Playwright)
first, so that the messages are also sent over a websocket; the figures stay server-side.
Results depend on the machine and its load; nothing here is an assertion.
"""
from __future__ import annotations

import argparse
import math
import socket
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studio.web import view as uv  # noqa: E402


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def square_brush(n_bristles: int, n_nodes: int) -> dict:
    side = int(math.ceil(math.sqrt(n_bristles)))
    rows = int(math.ceil(n_bristles / side))
    return {"brushes": [{"name": "brush", "material": "silicone", "rows": rows,
                         "columns": side, "pitch": [0.003, 0.003], "bristle_length": 0.033,
                         "root_radius": 0.001, "tip_radius": 0.0005, "n_nodes": n_nodes,
                         "tip_variance": 4e-10, "seed": 1}], "bodies": []}


def measure(server, n_bristles: int, n_nodes: int, repeats: int) -> dict:
    view = uv.View(server, root=f"/bench{n_bristles}")
    b = uv.design_bristles(square_brush(n_bristles, n_nodes))
    view.set_bristle_nodes(b)  # first draw: creates the batched node
    rng = np.random.default_rng(0)
    compute, push = [], []
    for _ in range(repeats):
        x = b.positions + rng.normal(0.0, 1e-4, b.positions.shape)  # a "recorded frame"
        moments = rng.random(len(b.bonds))
        t0 = time.perf_counter()
        centres, wxyz, scales = uv.segment_instances(x, b.radius, b.bonds)
        colors = uv.colormap(moments, 1.0)
        t1 = time.perf_counter()
        view.set_bristles(centres, wxyz, scales, colors)
        t2 = time.perf_counter()
        compute.append(t1 - t0)
        push.append(t2 - t1)
    view.clear()
    n_seg = len(b.bonds)
    c, p = statistics.median(compute), statistics.median(push)
    return {"bristles": b.n_bristles, "segments": n_seg, "compute_ms": 1e3 * c,
            "push_ms": 1e3 * p, "total_ms": 1e3 * (c + p), "fps": 1.0 / (c + p),
            "payload_mb": n_seg * 43 / 1e6}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bristles", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--nodes", type=int, default=8, help="nodes per bristle (default 8)")
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--client", action="store_true",
                    help="connect a headless chromium to the server first")
    args = ap.parse_args(argv)

    import viser

    port = _free_port()
    server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    browser = pw = None
    try:
        if args.client:
            from playwright.sync_api import sync_playwright

            pw = sync_playwright().start()
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium",
                                         args=["--no-sandbox", "--use-angle=swiftshader",
                                               "--enable-unsafe-swiftshader"])
            page = browser.new_page(viewport={"width": 800, "height": 600})
            page.goto(f"http://127.0.0.1:{port}/")
            deadline = time.monotonic() + 60
            while not server.get_clients() and time.monotonic() < deadline:
                time.sleep(0.2)
            print(f"client connected: {bool(server.get_clients())}")
        print(f"{'bristles':>9} {'segments':>9} {'compute':>9} {'push':>9} {'total':>9} "
              f"{'frames/s':>9} {'payload':>9}")
        for n in args.bristles:
            r = measure(server, n, args.nodes, args.repeats)
            print(f"{r['bristles']:>9,} {r['segments']:>9,} {r['compute_ms']:>7.1f}ms "
                  f"{r['push_ms']:>7.1f}ms {r['total_ms']:>7.1f}ms {r['fps']:>9.1f} "
                  f"{r['payload_mb']:>7.2f}MB")
    finally:
        if browser is not None:
            browser.close()
        if pw is not None:
            pw.stop()
        server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
