"""Studies: many simulations of one design, run on Dask distributed.

``runner`` runs independent simulations (one task and one HDF5 per run; restartable), whose
files and outcomes ``run_files`` writes and reads; ``cli`` adds ``brush-studio study <name>``
and ``study_command`` holds what every command shares. Each study builds its runs, collects
their small summaries and writes CSV, HDF5 and PNG plots into an output folder; a larger one
is a package split by its seams: ``wedge/`` (``cycle``: the run task and its curves;
``scenes``, ``protocol``, ``study``: the command and its outputs), ``spin/`` and ``rod/``
(``runs``: physics and run tasks; ``outputs``; ``study``), ``convergence/``, ``optimise/``
(the design search), ``fur/``, ``docking/``. ``registry`` lists every study with its options
model; ``options`` and ``api`` are what every study is made of. See docs/studies.md.
"""
