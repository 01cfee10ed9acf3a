"""The outputs of the spin study (seed 4.3) from its finished runs: ``spin_summary.csv``
(one row per run: rest time, contacts...), ``contacts.csv`` (one row per contact),
``omega.csv`` (omega(t) of every run), ``spin.h5`` (the same arrays), ``omega_<size>mm.png``,
``delta_omega_vs_duration.png``, ``randomness.png``, ``rest_times.png``."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from studio.studies.spin.runs import config_label, read_spin


def write_outputs(out_dir: Path, outcomes) -> dict:
    """CSVs, spin.h5 and PNGs from the finished runs; returns a summary dict."""
    import h5py

    out_dir = Path(out_dir)
    ok = [o for o in outcomes if o.ok]
    data = {o.run_id: read_spin(o.h5) for o in ok}
    rows, contact_rows = [], []
    for o in ok:
        s = o.summary
        rows.append({"run_id": o.run_id, "cube_mm": o.params["cube_mm"],
                     "config": o.params["config"], "tip_variance": o.params["tip_variance"],
                     "seed": o.params["seed"], "status": o.status, "omega0": s["omega0"],
                     "rest_time": s["rest_time"], "at_rest": s["at_rest"],
                     "n_contacts": s["n_contacts"], "delta_omega_spread": s["delta_omega_spread"],
                     "end_time": s["end_time"], "dt": s.get("dt"), "wall_s": o.wall_s})
        for k, c in enumerate(s["contacts"]):
            contact_rows.append(dict({"run_id": o.run_id, "cube_mm": o.params["cube_mm"],
                                      "config": o.params["config"],
                                      "seed": o.params["seed"], "contact": k}, **c))
    _write_csv(out_dir / "spin_summary.csv", rows)
    _write_csv(out_dir / "contacts.csv", contact_rows)
    with (out_dir / "omega.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run_id", "time", "omega", "contact_force"])
        for rid, d in data.items():
            mag = np.linalg.norm(d["force"], axis=1)
            w.writerows([rid, f"{t:.6g}", f"{om:.6g}", f"{f:.6g}"]
                        for t, om, f in zip(d["time"], d["omega"], mag))
    tmp = out_dir / ".spin.h5.tmp"
    with h5py.File(tmp, "w") as h:
        for o in ok:
            d = data[o.run_id]
            g = h.create_group(o.run_id)
            g.create_dataset("time", data=d["time"])
            g.create_dataset("omega", data=d["omega"])
            g.create_dataset("contact_force", data=d["force"])
            g.attrs["params"] = json.dumps(o.params)
            g.attrs["summary"] = json.dumps({k: v for k, v in o.summary.items()
                                             if k != "contacts"}, default=str)
            if o.summary["contacts"]:
                keys = list(o.summary["contacts"][0])
                g.create_dataset("contacts", data=np.array(
                    [[c[k] for k in keys] for c in o.summary["contacts"]], float))
                g["contacts"].attrs["columns"] = json.dumps(keys)
    tmp.replace(out_dir / "spin.h5")
    _plots(out_dir, ok, data)
    return {"runs": rows, "n_contacts": len(contact_rows)}


def _write_csv(path: Path, rows: list[dict]) -> None:
    with path.open("w", newline="") as fh:
        if not rows:
            fh.write("")
            return
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _plots(out_dir: Path, ok, data: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    perfect = [o for o in ok if o.params["tip_variance"] == 0]
    for cube in sorted({o.params["cube_mm"] for o in perfect}):
        fig, ax = plt.subplots(figsize=(9, 4.5))
        for o in sorted((o for o in perfect if o.params["cube_mm"] == cube),
                        key=lambda o: o.params["config"]):
            d = data[o.run_id]
            ax.plot(d["time"], d["omega"], lw=1, label=config_label(o.params["config"]))
        ax.set_xlabel("time [s]")
        ax.set_ylabel("ω [rad/s]")
        ax.set_title(f"{cube} mm cube: angular velocity (seed figs. 4.25-4.26)", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out_dir / f"omega_{cube}mm.png", dpi=120)
        plt.close(fig)
    # fig. 4.40: delta omega per contact against its duration
    fig, ax = plt.subplots(figsize=(7, 5))
    markers = {20: "o", 40: "s", 60: "^"}
    for o in perfect:
        cs = o.summary["contacts"]
        if cs:
            ax.scatter([c["duration"] * 1e3 for c in cs], [c["delta_omega"] for c in cs],
                       s=14, marker=markers.get(o.params["cube_mm"], "o"),
                       label=f"{o.params['cube_mm']} mm, cfg {o.params['config']}")
    ax.set_xlabel("contact duration [ms]")
    ax.set_ylabel("Δω per contact [rad/s]")
    ax.set_title("Change of angular velocity per contact (seed fig. 4.40)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(out_dir / "delta_omega_vs_duration.png", dpi=120)
    plt.close(fig)
    # fig. 4.41: randomness
    rand = [o for o in ok if o.params["tip_variance"] > 0]
    if rand:
        cube, cfg = rand[0].params["cube_mm"], rand[0].params["config"]
        fig, ax = plt.subplots(figsize=(9, 4.5))
        base = next((o for o in perfect if o.params["cube_mm"] == cube
                     and o.params["config"] == cfg), None)
        if base is not None:
            d = data[base.run_id]
            ax.plot(d["time"], d["omega"], "k-", lw=1.6, label="perfect brush")
        for o in rand:
            d = data[o.run_id]
            ax.plot(d["time"], d["omega"], lw=0.9,
                    label=f"tip variance {o.params['tip_variance']:g} m², seed {o.params['seed']}")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("ω [rad/s]")
        ax.set_title(f"Random bristle orientation (seed fig. 4.41): {cube} mm cube, "
                     f"configuration {cfg}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out_dir / "randomness.png", dpi=120)
        plt.close(fig)
    # rest times
    if perfect:
        cubes = sorted({o.params["cube_mm"] for o in perfect})
        cfgs = sorted({o.params["config"] for o in perfect})
        fig, ax = plt.subplots(figsize=(8, 4.5))
        width = 0.8 / max(len(cubes), 1)
        for j, cube in enumerate(cubes):
            vals = []
            for cfg in cfgs:
                o = next((o for o in perfect if o.params["cube_mm"] == cube
                          and o.params["config"] == cfg), None)
                r = o.summary["rest_time"] if o else None
                vals.append(r if r is not None else np.nan)
            ax.bar(np.arange(len(cfgs)) + j * width, vals, width, label=f"{cube} mm")
        ax.set_xticks(np.arange(len(cfgs)) + 0.4 - width / 2)
        ax.set_xticklabels([f"cfg {c}" for c in cfgs])
        ax.set_ylabel("time to rest [s]")
        ax.set_title("Spin-down time per configuration (missing bar: still turning at the "
                     "end)", fontsize=9)
        ax.grid(alpha=0.3, axis="y")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out_dir / "rest_times.png", dpi=120)
        plt.close(fig)
