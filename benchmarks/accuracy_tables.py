"""Measure the tables and plots of docs/accuracy.md: error against wall time for the
verification cases, with the convergence machinery of ``brush-studio convergence``
(``studio/studies/convergence/``).

    python benchmarks/accuracy_tables.py [--cases rod_frequencies,rod_static,...]
                                         [--out DIR] [--img docs/img]

Each case is a ladder of nodes per bristle run one level after another in this process
(``serial``: on a shared machine, parallel levels would disturb each other's wall times);
the runs stay in ``--out`` and a second call reuses them. For each case the script prints a
markdown table (quantity, relative error and wall time per level; observed order; the
cheapest level within 1 % and 5 %), writes ``--out/<case>/<quantity>/convergence.*`` and
the plot ``--img/accuracy_<case>.png`` (log-log |error| against wall time), and stores all
tables in ``--out/accuracy.json``.

Cases (scenes from ``static_presets/``, changed as stated):

* ``rod_frequencies``: rod_tip_impulse as shipped; first three bending frequencies
  (spectral_peak:1..3) against Euler-Bernoulli.
* ``rod_static``: the steel rod, a 1 mN tip load (linear) ramped in 0.1 s and settled by
  local damping 0.7, 2 s; tip deflection against P L^3 / 3 E I.
* ``rod_weight``: the steel rod under the seed's 20 g tip weight (0.1962 N) and its own
  weight (gravity on), ramped in 0.2 s, local damping 0.7, 1.5 s; tip deflection against the
  elastica with distributed weight (large deflection, about 27 % of L).
* ``cone_large``: one conical silicone bristle of the wedge brush (33 mm, 1.0 -> 0.5 mm,
  E 2.7 MPa) as a horizontal cantilever under a tip load of 1.5 E I_root / L^2, ramped in
  0.2 s, local damping 0.7, 1 s; tip deflection against the tapered elastica.
* ``wedge``: wedge_60 pressed 30 steps in (no unloading), the preset's 50 ms dwell;
  wedge_force@10mm, @20mm, @30mm against the Richardson estimate of the finest levels.
* ``rod_frequencies_linear``: the same with the impulse scaled by 1/25 (tip amplitude
  2.5 mm instead of 62 mm: the linear regime Euler-Bernoulli describes).
* ``cube``, ``cube_dt``: spin_cube_40 with the brush moved to the seed's second horizontal position
  (tips at a (1 + sqrt 2) / 4 from the axis: only the corners sweep into the brush, so
  contacts are distinct), 0.3 s, no stop condition; body_omega_after_first_contact, over
  nodes per bristle (``cube``) and over dt factors 1, 0.5, 0.25 at 6 nodes (``cube_dt``).
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import engine  # noqa: E402
from engine.analysis.beam_theory import circle_second_moment  # noqa: E402
from studio.studies import convergence as cv  # noqa: E402

PRESETS = ROOT / "static_presets"


def preset(name: str) -> dict:
    return json.loads((PRESETS / f"{name}.json").read_text())


def rod_static_scene(tip_force: float, gravity: bool, ramp: float, duration: float) -> dict:
    d = preset("rod_tip_impulse")
    d["name"] = "rod_static" if not gravity else "rod_weight"
    d["description"] = "steel rod (seed table 4.1) as a horizontal cantilever, static tip load"
    d["loads"] = [{"brush": "brush", "node": -1, "force": [0.0, 0.0, -tip_force],
                   "profile": {"times": [0.0, ramp], "values": [0.0, 1.0]}}]
    d["environment"] = {"gravity": [0.0, 0.0, -9.81 if gravity else 0.0],
                        "local_damping": 0.7}
    d["run"] = {"duration": duration, "record_interval": 0.01, "channels": ["nodes"]}
    return d


def cone_scene(load_parameter: float) -> dict:
    d = rod_static_scene(0.0, False, 0.2, 1.0)
    w = preset("wedge_60")
    brush = w["brushes"][0]
    silicone = w["materials"][brush["material"]]
    d["name"] = "cone_large"
    d["description"] = "one conical silicone bristle of the wedge brush, large tip load"
    d["materials"] = {"silicone": silicone}
    b = d["brushes"][0]
    b.update(material="silicone", bristle_length=brush["bristle_length"],
             root_radius=brush["root_radius"], tip_radius=brush["tip_radius"])
    ei_root = silicone["youngs_modulus"] * circle_second_moment(brush["root_radius"])
    d["loads"][0]["force"] = [0.0, 0.0, -load_parameter * ei_root / brush["bristle_length"] ** 2]
    return d


def wedge_scene(n_steps: int = 30) -> dict:
    d = preset("wedge_60")
    prof = d["bodies"][0]["motion"]["profile"]
    prof["n_steps"] = n_steps
    prof["unload"] = False
    t_step = math.sqrt(6 * prof["step"] / prof["max_acceleration"]) + prof["dwell"]
    d["run"]["duration"] = round(n_steps * t_step + 0.02, 4)
    d["run"]["channels"] = ["bodies", "root_force"]
    d["name"] = "wedge_60_loading"
    return d


def cube_scene() -> dict:
    d = preset("spin_cube_40")
    a = d["bodies"][0]["shape"]["size"][0]
    tips = a * (1 + math.sqrt(2)) / 4
    base = d["brushes"][0]["base"]["position"]
    length = d["brushes"][0]["bristle_length"]
    base[0] = tips + length + d["brushes"][0]["tip_radius"]
    d["run"]["duration"] = 0.3
    d["run"]["stop"] = None
    d["run"]["channels"] = ["bodies", "contacts"]
    d["name"] = "spin_cube_40_position2"
    return d


CASES = {
    "rod_frequencies": (lambda: preset("rod_tip_impulse"), [5, 9, 17, 33],
                        ["spectral_peak:1", "spectral_peak:2", "spectral_peak:3"]),
    "rod_static": (lambda: rod_static_scene(1e-3, False, 0.1, 2.0), [3, 5, 9, 17, 33],
                   ["tip_deflection"]),
    "rod_weight": (lambda: rod_static_scene(0.1962, True, 0.2, 1.5), [5, 9, 17, 33],
                   ["tip_deflection"]),
    "cone_large": (lambda: cone_scene(1.5), [3, 5, 9, 17, 33], ["tip_deflection"]),
    "wedge": (wedge_scene, [4, 6, 9],
              ["wedge_force@10mm", "wedge_force@20mm", "wedge_force@30mm"]),
    "cube": (cube_scene, [6, 8, 11, 16], ["body_omega_after_first_contact"]),
    "cube_dt": (cube_scene, [6], ["body_omega_after_first_contact"], [1.0, 0.5, 0.25]),
    "rod_frequencies_linear": (lambda: small_impulse(1 / 25), [5, 9, 17],
                               ["spectral_peak:1", "spectral_peak:2", "spectral_peak:3"]),
}


def small_impulse(scale: float) -> dict:
    """rod_tip_impulse with its impulse scaled: 1/25 gives a tip amplitude of 2.5 mm
    (0.6 % of L) instead of 62 mm (15 % of L), the linear regime of Euler-Bernoulli."""
    d = preset("rod_tip_impulse")
    d["loads"][0]["force"] = [c * scale for c in d["loads"][0]["force"]]
    d["name"] = "rod_tip_impulse_small"
    return d


def settle_drift(h5: str, index: int = 0) -> float:
    """How far the tip still moved over the last 20 % of a static run, relative to its
    final deflection."""
    with engine.open_result(h5) as res:
        t = np.asarray(res.time)
        first = np.asarray(res.static("bristles/first_node"))
        tip = np.asarray(res.series("nodes/positions")[:, first[index + 1] - 1, :])
    d = np.linalg.norm(tip - tip[0], axis=1)
    tail = t >= 0.8 * t[-1]
    return float(np.ptp(d[tail]) / max(d[-1], 1e-300))


def slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)


def markdown(case: str, tables: list, drifts: list | None) -> str:
    rows = tables[0].rows
    head = "| n_nodes | dt [s] | dt factor | " + " | ".join(
        f"{t.quantity} [{t.unit}] | error" for t in tables) + " | wall [s] |"
    if drifts is not None:
        head += " settled (drift) |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for i, r in enumerate(rows):
        cells = [str(r["n_nodes"]), "–" if r["dt"] is None else f"{r['dt']:.3g}",
                 "auto" if r["dt_factor"] is None else f"{r['dt_factor']:g}"]
        for t in tables:
            tr = t.rows[i]
            cells.append("failed" if tr["quantity"] is None else f"{tr['quantity']:.6g}")
            cells.append("–" if tr["error"] is None else f"{tr['error']:+.2e}")
        cells.append("–" if r["wall_s"] is None else f"{r['wall_s']:.2f}")
        if drifts is not None:
            cells.append("–" if drifts[i] is None else f"{drifts[i]:.0e}")
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    for t in tables:
        orders = ", ".join("–" if o is None else f"{o:.2f}" for o in t.observed_orders)
        fit = "–" if t.fitted_order is None else f"{t.fitted_order:.2f}"
        rich = ("–" if t.richardson is None else
                f"{t.richardson:.6g} {t.unit} (order {t.richardson_order:.2f})")
        cheap = []
        for tol, row in t.cheapest.items():
            cheap.append(f"within {100 * float(tol):g} %: " + (
                "none" if row is None else f"n_nodes {row['n_nodes']}"
                + ("" if row["dt_factor"] is None else f" dt×{row['dt_factor']:g}")
                + f", {row['wall_s']:.2f} s"))
        lines.append(f"- **{t.quantity}**: reference {t.reference:.6g} {t.unit} "
                     f"({t.reference_kind}); observed order between levels {orders} "
                     f"(fit {fit}); Richardson {rich}; cheapest {'; '.join(cheap)}.")
    return "\n".join(lines)


def plot(case: str, tables: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for t in tables:
        pts = [r for r in t.rows if r["error"] not in (None, 0) and r["wall_s"]]
        x = [r["wall_s"] for r in pts]
        y = [abs(r["error"]) for r in pts]
        line, = ax.loglog(x, y, "o-", label=f"{t.quantity} ({t.reference_kind})")
        for r, xi, yi in zip(pts, x, y):
            label = str(r["n_nodes"]) + ("" if r["dt_factor"] is None
                                         else f" dt×{r['dt_factor']:g}")
            ax.annotate(label, (xi, yi), textcoords="offset points",
                        xytext=(3, 3), fontsize=7, color=line.get_color())
    for tol, style in ((0.01, ":"), (0.05, "--")):
        ax.axhline(tol, color="grey", ls=style, lw=0.8)
    ax.set_xlabel("wall time of the run [s] (labels: nodes per bristle)")
    ax.set_ylabel("|relative error|")
    ax.set_title(f"{case}: {tables[0].scene_name}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", default=",".join(CASES), help="comma-separated, of: "
                   + ", ".join(CASES))
    p.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "brush-studio-accuracy"),
                   help="folder for the runs and tables (default: in the temporary folder)")
    p.add_argument("--img", default=str(ROOT / "docs" / "img"), help="folder for the plots")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    store = out / "accuracy.json"
    results = json.loads(store.read_text()) if store.exists() else {}
    for case in args.cases.split(","):
        if case not in CASES:
            p.error(f"unknown case {case!r}; cases: {', '.join(CASES)}")
        make, ladder, quantities, *factors = CASES[case]
        scene = engine.parse_scene(make())
        t0 = time.perf_counter()
        levels, records = cv.run_ladder(scene, out / case, n_nodes=ladder,
                                        dt_factors=factors[0] if factors else None,
                                        serial=True)
        total = time.perf_counter() - t0
        tables = []
        for q in quantities:
            table = cv.tabulate(scene, q, levels, records)
            cv.write_outputs(table, out / case / slug(q), scene_json=scene.to_json())
            tables.append(table)
        drifts = None
        if quantities == ["tip_deflection"]:
            drifts = [settle_drift(r["h5"]) if r["status"] == "completed" else None
                      for r in records]
        text = markdown(case, tables, drifts)
        failed = [f"n_nodes {lv.n_nodes}: {r['error']}" for lv, r in zip(levels, records)
                  if r["status"] not in ("completed", "stopped")]
        print(f"\n### {case} ({scene.name}; ladder {ladder}; {total:.0f} s for this call, "
              f"{sum(1 for r in records if r.get('skipped'))} level(s) reused)\n")
        print(text)
        for f in failed:
            print(f"- failed: {f}")
        plot(case, tables, Path(args.img) / f"accuracy_{case}.png")
        results[case] = {"tables": [t.to_dict() for t in tables], "markdown": text,
                         "failed": failed, "drifts": drifts,
                         "machine_note": "2 shared cores, serial levels",
                         "measured_at": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
        store.write_text(json.dumps(results, indent=1, allow_nan=False))
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
