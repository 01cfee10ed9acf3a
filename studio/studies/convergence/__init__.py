"""``brush-studio convergence``: error against run time for a ladder of resolutions.

    brush-studio convergence SCENE.json --quantity tip_deflection \\
        --ladder n_nodes=3,5,9,17,33 [--dt-factor 1,0.5,0.25] -o DIR

Each *level* of the ladder is the scene with every brush at ``n_nodes`` nodes per bristle and
(with ``--dt-factor``) ``run.dt`` = factor x the automatic time step of that level. The levels
run as independent simulations through the studies' Dask layer
(:func:`studio.studies.runner.run_many`), or one after another in this process with
``--serial`` (undisturbed wall times). From each level's result file the quantity of interest
is measured, and compared with a reference:

* **analytic** where one exists: the single-bristle rod cases (tip deflection against the
  elastica of a tapered, self-weighted cantilever, which is ``P L^3 / 3 E I`` for small
  loads; bending frequencies of a uniform rod against Euler-Bernoulli);
* otherwise the **Richardson extrapolation** of the three finest levels (with the observed
  order of convergence), or the **finest level** itself when the three finest levels do not
  converge monotonically.

Outputs in DIR: ``convergence.csv`` (``level,n_nodes,dt,quantity,error,wall_s``; ``error`` is
the relative error ``(q - reference) / |reference|``, ``wall_s`` the run's own wall time),
``convergence.h5`` (group ``/convergence``), ``convergence.json`` (everything, for
:func:`load_convergence`), ``convergence.png`` (log-log |error| against wall time) and the
runs themselves under ``DIR/runs/``. Running again into the same DIR reuses finished runs, so
another ``--quantity`` of the same ladder costs only the measurement.
"""
from __future__ import annotations

from .quantities import (  # noqa: F401
    CONTACT_GAP_S, CSV_COLUMNS, ConvergenceError, FORMAT, GRAZE_CHANGE, KINDS,
    QUANTITY_HELP, Quantity, ROOTED_WITHIN, TOLERANCES, _body_channel, _bristle_tip,
    _free_after, _omega_after_first_contact, _parse_int, _parse_length, _peak_plate_force,
    _spinning_body, _stepped_body, _transverse, _wedge_force, check_measurable,
    contact_episodes, first_contact_end, measure, parse_quantity, spectral_peaks)
from .references import (  # noqa: F401
    Reference, _amplitude, analytic_reference, tapered_elastica_tip)
from .ladder import (  # noqa: F401
    Level, level_resolution, make_levels, parse_factors, parse_ladder)
from .table import (  # noqa: F401
    ConvergenceTable, analyse, fitted_order, observed_orders, richardson)
from .outputs import (  # noqa: F401
    _num, load_convergence, plot_convergence, write_outputs)
from .running import (  # noqa: F401
    _run_dask, _run_serial, run_convergence, run_ladder, run_level, tabulate)
from .command import (  # noqa: F401
    Options, _err, _run_study, register, run)
