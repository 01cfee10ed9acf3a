"""A small wedge study on a local Dask cluster
=============================================

The wedge study of seed 4.2 (``brush-studio study wedge``) through its typed Python API:
the study registry's ``Options`` in (``get("wedge").options``), ``StudyResult`` out. Two wedges, 45 and 60 degrees (the
presets ``wedge_45`` and ``wedge_60``), each pressed 2 mm into the brush at 3 nodes per
bristle, one run per wedge. ``workers=2`` runs them at once on a local Dask cluster of two
single-threaded worker processes (``scheduler="tcp://HOST:PORT"`` would use an existing
cluster instead; ``workers=1`` runs them one after the other in this process). Each step is
held until the brush is in equilibrium, then the force is recorded (docs/studies.md).

The study prints its own report; the example then reads the table the study wrote,
``force_depth.csv``, and prints the force at every depth for each wedge.

Run it from the repository root, with the package installed (``pip install -e .``)::

    python examples/03_study_on_dask.py [OUT_DIR]

It writes the study's files (``force_depth.csv``, ``force_depth.png``, ``study.json``,
``runs/*.h5``...) into OUT_DIR (default ``./example_output/03_study_on_dask``). Running it
again in the same folder skips the runs already complete.
"""
import csv
import sys
from pathlib import Path

from studio.studies.registry import get


def main():
    out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "example_output/03_study_on_dask")

    wedge = get("wedge")   # any study by its command name: .options (a pydantic model), .run
    options = wedge.options(
        angles=[45, 60],     # the presets wedge_45 and wedge_60
        depth_mm=2,          # full depth, in 1 mm steps
        nodes=3,             # nodes per bristle
        no_unload=True,      # loading only
        workers=2,           # a local Dask cluster of two worker processes
        no_progress=True,    # no progress bar on the terminal
    )
    result = wedge.run(options, out_dir)
    print(f"study {result.status} (exit code {result.exit_code}) in {result.wall_s:.1f} s")
    if not result.ok:
        sys.exit(result.exit_code)

    # The study's table: one row per recorded depth and wedge.
    with open(out_dir / "force_depth.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    print()
    print(f"{'angle [deg]':>11} {'depth [mm]':>10} {'force [mN]':>10}")
    for row in rows:
        print(f"{float(row['angle_deg']):>11g} {float(row['depth_m']) * 1e3:>10.3g} "
              f"{float(row['force_N']) * 1e3:>10.4f}")
    print(f"\nfiles: {', '.join(result.files)}")


# The guard is needed: Dask starts its worker processes by running this file again
# (multiprocessing's "spawn"), and they must not start a study of their own.
if __name__ == "__main__":
    main()
